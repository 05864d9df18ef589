// Tests for the bench's checks and edge cases (src/bench/): excluding the sky from every metric,
// PSNR's +inf and RMSE's 0 on the chart, the same untimed first evaluation for every setting,
// outputs that are all written or none, and the spec's range checks and messages.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>

#include "bench/bench.h"
#include "bench/bench_metrics.h"
#include "bench/chart.h"
#include "bench/stability_chart.h"
#include "core/error.h"
#include "core/frame.h"
#include "io/image_file.h"
#include "scratch_folder_test.h"

namespace posthaste::bench {
namespace {

namespace fs = std::filesystem;

constexpr float kInf = std::numeric_limits<float>::infinity();

/// The message of the Error `f` throws ("no error" when none), with its exit code.
template <typename F>
std::pair<std::string, int> error_of(F &&f)
{
    try {
        f();
    } catch (const Error &e) {
        return {e.what(), e.exit_code()};
    }
    return {"no error", 0};
}

class BenchChecks : public test::ScratchFolderTest {
   protected:
    BenchChecks() : ScratchFolderTest("posthaste_benchchk_") {}

    /// An 8x4 frame file: color RGB, depth (infinite in the columns x >= sky_from) and a grey
    /// 1-channel ao; the truth file's color equals it on the surface and differs on the sky.
    /// A graph reads it (node "r") and a spec measures "r"'s `pass` against the truth.
    void make_scene(int sky_from)
    {
        Frame f, t;
        f.set_size(8, 4);
        t.set_size(8, 4);
        Image color(8, 4, 3), depth(8, 4, 1), ao(8, 4, 1), truth(8, 4, 3);
        for (int y = 0; y < 4; ++y) {
            for (int x = 0; x < 8; ++x) {
                const bool sky = x >= sky_from;
                for (int c = 0; c < 3; ++c) {
                    color.at(x, y, c) = 0.1f * float(x + c) + 0.05f * float(y);
                    truth.at(x, y, c) = sky ? 5.0f : color.at(x, y, c);
                }
                depth.at(x, y, 0) = sky ? kInf : 2.0f;
                ao.at(x, y, 0) = 0.5f;
            }
        }
        f.set("color", std::move(color), {"R", "G", "B"});
        f.set("depth", std::move(depth));
        f.set("ao", std::move(ao), {"Y"});
        t.set("color", std::move(truth), {"R", "G", "B"});
        write_exr(f, path("in.0001.exr"), {});
        write_exr(t, path("t.0001.exr"), {});
        std::ofstream(path("g.json")) << R"({"nodes": [
            {"id": "r", "type": "read", "params": {"path": ")"
                                      << path("in.####.exr") << R"("}},
            {"id": "w", "type": "write", "inputs": {"image": "r"},
             "params": {"path": ")" << path("out/o.####.exr")
                                      << R"(", "passes": "*"}}]})";
    }
    BenchResult run_spec(const std::string &extra)
    {
        std::ofstream(path("s.json")) << R"({"graph": "g.json", "node": "r", "frames": "1",
            "truth": {"pattern": "t.####.exr"}, "warmup": 0, "runs": 1)"
                                      << (extra.empty() ? "" : ", ") << extra << "}";
        return run_bench(load_spec(path("s.json")));
    }
};

// 1. The sky is left out of FLIP as of RMSE; a frame that is all sky is an error, not "exact".
TEST_F(BenchChecks, ExcludeSkyAppliesToFlipAndNeedsPixels)
{
    make_scene(4);
    const BenchResult kept = run_spec(R"("exclude": "sky", "metrics": ["rmse", "flip"])");
    EXPECT_EQ(kept.settings.at(0).rmse, 0.0);
    EXPECT_EQ(kept.settings.at(0).flip, 0.0);  // the sky differs, the surface does not
    const BenchResult all = run_spec(R"("metrics": ["rmse", "flip"])");
    EXPECT_GT(all.settings.at(0).flip, 0.0);

    make_scene(0);  // all sky
    const auto [msg, code] = error_of([&] { run_spec(R"("exclude": "sky")"); });
    EXPECT_NE(msg.find("/exclude"), std::string::npos) << msg;
    EXPECT_NE(msg.find("no pixels left after exclude sky"), std::string::npos) << msg;
    EXPECT_NE(msg.find("frame 1"), std::string::npos) << msg;
    EXPECT_NE(msg.find("setting \"default\""), std::string::npos) << msg;
    EXPECT_EQ(code, 2);
}

// 6. FLIP of a one-channel pass is refused, naming the pass, rather than left empty.
TEST_F(BenchChecks, FlipOfAOneChannelPassIsASpecError)
{
    make_scene(8);
    const auto [msg, code] = error_of([&] {
        std::ofstream(path("s.json")) << R"({"graph": "g.json", "node": "r", "frames": "1",
            "pass": "ao", "truth": {"graph": "g.json", "node": "r"}, "metrics": ["flip"],
            "warmup": 0, "runs": 1})";
        run_bench(load_spec(path("s.json")));
    });
    EXPECT_NE(msg.find(":/metrics: flip needs RGB"), std::string::npos) << msg;
    EXPECT_NE(msg.find("\"ao\""), std::string::npos) << msg;
    EXPECT_EQ(code, 2);
    // With one channel of the truth, FLIP cannot apply: refused when the spec is read.
    std::ofstream(path("s.json")) << R"({"graph": "g.json", "node": "r",
        "truth": {"pattern": "t.####.exr", "channel": 0}, "metrics": ["flip"]})";
    EXPECT_NE(error_of([&] { load_spec(path("s.json")); }).first.find("/metrics"),
              std::string::npos);
}

// 8. A pass missing from a truth graph, from one setting's output, or a depth `exclude` needs:
// usage errors naming the spec and its key, before any timing.
TEST_F(BenchChecks, MissingPassesAreSpecErrorsBeforeTiming)
{
    make_scene(8);
    std::ofstream(path("s.json")) << R"({"graph": "g.json", "node": "r", "frames": "1",
        "pass": "nosuch", "truth": {"graph": "g.json", "node": "r"}, "runs": 1000})";
    auto [msg, code] = error_of([&] { run_bench(load_spec(path("s.json"))); });
    EXPECT_EQ(msg.rfind(path("s.json") + ":/pass: truth node \"r\" gives no pass \"nosuch\"", 0),
              0u)
        << msg;
    EXPECT_EQ(code, 2);

    // The second setting's graph drops the depth: found before 1000 timed runs.
    std::ofstream(path("g2.json")) << R"({"nodes": [
        {"id": "r", "type": "read", "params": {"path": ")"
                                   << path("in.####.exr") << R"("}},
        {"id": "c", "type": "channels", "inputs": {"image": "r"}},
        {"id": "w", "type": "write", "inputs": {"image": "c"},
         "params": {"path": ")" << path("out/o.####.exr")
                                   << R"(", "passes": "*"}}]})";
    std::ofstream(path("s.json")) << R"({"graph": "g2.json", "node": "c", "frames": "1",
        "exclude": "sky", "truth": {"pattern": "t.####.exr"}, "warmup": 1000, "runs": 100000,
        "settings": [{"name": "keep"}, {"name": "drop", "set": ["c.remove=depth"]}]})";
    std::tie(msg, code) = error_of([&] { run_bench(load_spec(path("s.json"))); });
    EXPECT_NE(msg.find(path("s.json") + ":/exclude: node \"c\" gives no pass \"depth\""),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("setting \"drop\""), std::string::npos) << msg;
    EXPECT_EQ(code, 2);
    std::ofstream(path("s.json")) << R"({"graph": "g2.json", "node": "c", "frames": "1",
        "truth": {"pattern": "t.####.exr"}, "warmup": 1000, "runs": 100000,
        "settings": [{"name": "keep"}, {"name": "drop", "set": ["c.remove=color"]}]})";
    std::tie(msg, code) = error_of([&] { run_bench(load_spec(path("s.json"))); });
    EXPECT_NE(msg.find(":/pass: node \"c\" gives no pass \"color\""), std::string::npos) << msg;
    EXPECT_NE(msg.find("setting \"drop\""), std::string::npos) << msg;
    EXPECT_EQ(code, 2);
}

// 2. PSNR +inf (exact) is the best value: on the front, dominating, and drawn at the top.
TEST(BenchChartEdges, PsnrInfinityIsOnTheFrontAndDrawn)
{
    const double inf = std::numeric_limits<double>::infinity();
    const std::vector<ChartPoint> points = {
        {"exact", 1, 1, 1, inf}, {"slow worse", 3, 3, 3, 30}, {"fast", 0.5, 0.5, 0.5, 20}};
    EXPECT_EQ(pareto_front(points, true), (std::vector<std::size_t>{2, 0}));
    // For an error, +inf is the worst: never on the front.
    EXPECT_EQ(pareto_front(points, false), (std::vector<std::size_t>{2}));
    ChartOptions o;
    o.higher_y_is_better = true;
    const std::string svg = svg_chart(points, o);
    EXPECT_EQ(svg.find("non-finite"), std::string::npos) << svg;
    EXPECT_NE(svg.find("exact (inf)"), std::string::npos);
    std::smatch m;
    ASSERT_TRUE(std::regex_search(
        svg, m, std::regex("<circle class=\"point pareto\" cx=\"[^\"]*\" cy=\"([^\"]*)\"")));
    EXPECT_EQ(std::stod(m[1].str()), 40.0);  // the top edge, labelled inf
    EXPECT_NE(svg.find(">inf</text>"), std::string::npos);
    ASSERT_TRUE(
        std::regex_search(svg, m, std::regex("cx=\"[^\"]*\" cy=\"([^\"]*)\"[^>]*><title>slow")));
    EXPECT_GT(std::stod(m[1].str()), 60.0);  // the finite maximum stands apart from it
}

// 7. On a log scale, an error of exactly 0 gets its own row, labelled 0, below the lowest decade.
TEST(BenchChartEdges, LogScaleDrawsZeroApart)
{
    ChartOptions o;
    o.log_y = true;
    const std::string svg =
        svg_chart({{"zero", 1, 1, 1, 0.0}, {"small", 2, 2, 2, 0.01}, {"big", 3, 3, 3, 0.5}}, o);
    EXPECT_NE(svg.find(">0</text>"), std::string::npos) << svg;
    EXPECT_NE(svg.find("zero (0)"), std::string::npos);
    EXPECT_NE(svg.find("<title>zero: 1 ms, 0</title>"), std::string::npos);
    const std::regex cy_re("cy=\"([^\"]*)\"");
    std::vector<double> cy;
    for (auto it = std::sregex_iterator(svg.begin(), svg.end(), cy_re);
         it != std::sregex_iterator();
         ++it) {
        cy.push_back(std::stod((*it)[1].str()));
    }
    ASSERT_EQ(cy.size(), 3u);
    EXPECT_GT(cy[0], cy[1] + 20.0);  // not on the 0.01 tick
}

// 4. A failing write leaves no partial set; bytes that are not UTF-8 become U+FFFD.
TEST_F(BenchChecks, OutputsAreAllWrittenOrNoneAndValidUtf8)
{
    make_scene(8);
    BenchResult r = run_spec(R"("description": "bad \u00e9")");
    fs::create_directories(path("res"));
    std::ofstream(path("res/thumbs")) << "a file";
    EXPECT_THROW(write_results(r, path("res")), Error);
    for (const char *f : {"results.csv", "chart.svg", "index.html", "results.json"}) {
        EXPECT_FALSE(fs::exists(path("res/") + f)) << f;
    }
    EXPECT_EQ(std::distance(fs::directory_iterator(path("res")), fs::directory_iterator()), 1);

    r.spec.origin = path("bad\xff name.json");
    r.settings[0].setting.name = "n\xc3";
    write_results(r, path("ok"), {{"extra.txt", "x\xfe"}});
    for (const char *f : {"results.csv", "chart.svg", "index.html", "results.json", "extra.txt"}) {
        std::ifstream in(path("ok/") + f, std::ios::binary);
        std::stringstream ss;
        ss << in.rdbuf();
        EXPECT_EQ(valid_utf8(ss.str()), ss.str()) << f;
        EXPECT_NE(ss.str().find("\xEF\xBF\xBD"), std::string::npos) << f;
    }
    EXPECT_EQ(valid_utf8("a\xe2\x82\xac\xff\xed\xa0\x80z"),
              "a\xe2\x82\xac\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBD\xEF\xBF\xBDz");
}

// 5, 8, 9. Integers out of range name their key rather than wrap; a folder is not "bad JSON".
TEST_F(BenchChecks, SpecRangesAndFolders)
{
    const std::string head = R"({"graph": "g.json", "node": "n", )";
    auto msg = [&](const std::string &text) {
        return error_of([&] { parse_spec(text, "s.json", ""); }).first;
    };
    EXPECT_NE(msg(head + R"("truth": {"pattern": "p"}, "frames": 4294967297})").find("/frames"),
              std::string::npos);
    EXPECT_NE(
        msg(head + R"("truth": {"pattern": "p", "channel": 4294967296}})").find("/truth/channel"),
        std::string::npos);
    EXPECT_NE(msg(head + R"("truth": {"pattern": "p", "channel": 18446744073709551615}})")
                  .find("/truth/channel"),
              std::string::npos);
    EXPECT_NE(msg(head + R"("truth": {"pattern": "p"}, "runs": 4294967297})").find("/runs"),
              std::string::npos);
    EXPECT_NE(msg(head + R"("truth": {"pattern": "p"}, "diff_scale": 1e39})").find("/diff_scale"),
              std::string::npos);
    EXPECT_EQ(parse_spec(head + R"("truth": {"pattern": "p"}, "frames": -3})", "s.json", "").frames,
              "-3");
    const auto [dir_msg, code] = error_of([&] { load_spec(dir_.string()); });
    EXPECT_NE(dir_msg.find("is a directory"), std::string::npos) << dir_msg;
    EXPECT_EQ(code, 2);
    // A stability record's field of another type names the file and the case.
    const std::string st =
        error_of([] { stability_svg(R"({"cases": [{"node": 5}]})", "st.json"); }).first;
    EXPECT_NE(st.find("st.json:/cases/0/node"), std::string::npos) << st;
}

/// `posthaste ARGS` with its exit code and output.
std::pair<int, std::string> posthaste(const std::string &args)
{
    FILE *pipe = popen((std::string(POSTHASTE_BINARY) + " " + args + " 2>&1").c_str(), "r");
    std::string output;
    char buf[512];
    while (pipe && std::fgets(buf, sizeof(buf), pipe)) {
        output += buf;
    }
    const int status = pipe ? pclose(pipe) : -1;
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

// 4, 8. The command line checks --stability and --frames before running anything.
TEST_F(BenchChecks, CommandLineChecksItsOptionsFirst)
{
    make_scene(8);
    run_spec("");  // writes s.json
    auto [code, out] = posthaste("bench -q --stability " + path("nonexist.json") + " --out " +
                                 path("res") + " " + path("s.json"));
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(out.find("nonexist.json"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(path("res/results.csv")));
    std::tie(code, out) =
        posthaste("bench -q --frames abc --out " + path("res") + " " + path("s.json"));
    EXPECT_EQ(code, 2) << out;
    EXPECT_NE(out.find("--frames"), std::string::npos) << out;
    EXPECT_EQ(out.find("/frames"), std::string::npos) << out;
    std::tie(code, out) =
        posthaste("bench -q --frames \"\" --out " + path("res") + " " + path("s.json"));
    EXPECT_EQ(code, 2) << out;
    EXPECT_FALSE(fs::exists(path("res/results.csv")));
}

}  // namespace
}  // namespace posthaste::bench

namespace posthaste::bench {
namespace {

// 9. An integer parameter's range is printed exactly, not as %g.
TEST(BenchNodesListing, IntegerRangesArePrintedExactly)
{
    const auto [code, out] = posthaste("nodes render");
    EXPECT_EQ(code, 0) << out;
    EXPECT_NE(out.find("range 0..2147483647"), std::string::npos) << out;
    EXPECT_EQ(out.find("e+09"), std::string::npos) << out;
}

}  // namespace
}  // namespace posthaste::bench
