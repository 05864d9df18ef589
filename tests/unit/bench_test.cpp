// Tests for src/bench/: the Pareto front on hand-made points, the SVG chart, timing summaries,
// CSV contents, spec validation, and end-to-end runs of a tiny graph (in process and through
// `posthaste bench`).

#include "bench/bench.h"

#include <OpenImageIO/imageio.h>
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

#include "bench/chart.h"
#include "bench/stability_chart.h"
#include "core/error.h"
#include "io/image_file.h"
#include "scratch_folder_test.h"

namespace posthaste::bench {
namespace {

namespace fs = std::filesystem;

std::size_t count_of(const std::string &text, const std::string &what)
{
    std::size_t n = 0;
    for (std::size_t i = text.find(what); i != std::string::npos; i = text.find(what, i + 1)) {
        ++n;
    }
    return n;
}

// --- Pareto front and chart ----------------------------------------------------------------

TEST(BenchPareto, HandMadePointsGiveTheFrontInTimeOrder)
{
    //  error
    //   8 | a
    //   6 |    b        e
    //   4 |       c  f
    //   2 |             d
    //     +--------------- time
    const std::vector<ChartPoint> points = {
        {"a", 1, 1, 1, 8},
        {"b", 2, 2, 2, 6},
        {"c", 3, 3, 3, 4},
        {"d", 5, 5, 5, 2},
        {"e", 5, 5, 5, 6},
        {"f", 4, 4, 4, 4},
    };
    EXPECT_EQ(pareto_front(points), (std::vector<std::size_t>{0, 1, 2, 3}));
    // PSNR-like: higher y is better, so the front flips.
    EXPECT_EQ(pareto_front(points, true), (std::vector<std::size_t>{0}));
    const std::vector<ChartPoint> up = {{"slow good", 9, 9, 9, 40},
                                        {"fast bad", 1, 1, 1, 20},
                                        {"mid", 5, 5, 5, 30},
                                        {"mid worse", 6, 6, 6, 25}};
    EXPECT_EQ(pareto_front(up, true), (std::vector<std::size_t>{1, 2, 0}));
}

TEST(BenchPareto, TiesNonFiniteAndEmpty)
{
    const double nan = std::nan("");
    const double inf = std::numeric_limits<double>::infinity();
    const std::vector<ChartPoint> points = {
        {"twin1", 2, 2, 2, 3},
        {"twin2", 2, 2, 2, 3},              // identical: both stay
        {"same time worse", 2, 2, 2, 4},    // dominated by the twins
        {"nan error", 0.5, 0.5, 0.5, nan},  // never on the front, dominates nothing
        {"inf time", inf, inf, inf, 0},
        {"zero error slow", 10, 10, 10, 0},
    };
    EXPECT_EQ(pareto_front(points), (std::vector<std::size_t>{0, 1, 5}));
    EXPECT_TRUE(pareto_front({}).empty());
    EXPECT_EQ(pareto_front({{"only", 1, 1, 1, 1}}), (std::vector<std::size_t>{0}));
}

TEST(BenchChart, SvgMarksAndConnectsTheFront)
{
    const std::vector<ChartPoint> points = {
        {"a<1>", 1, 0.8, 1.3, 8},
        {"b", 2, 2, 2, 6},
        {"c", 3, 3, 3, 4},
        {"e", 5, 5, 5, 6},
        {"n", 1, 1, 1, std::nan("")},
    };
    ChartOptions o;
    o.title = "t & t";
    o.log_y = true;
    const std::string svg = svg_chart(points, o);
    EXPECT_EQ(svg.rfind("<svg", 0), 0u);
    EXPECT_NE(svg.find("</svg>"), std::string::npos);
    EXPECT_EQ(count_of(svg, "<circle"), 4u);  // the NaN point is listed, not drawn
    EXPECT_EQ(count_of(svg, "class=\"point pareto\""), 3u);
    EXPECT_EQ(count_of(svg, "<polyline class=\"pareto\""), 1u);
    // The polyline joins three points, in time order.
    std::smatch m;
    ASSERT_TRUE(std::regex_search(svg, m, std::regex("polyline[^>]*points=\"([^\"]*)\"")));
    std::istringstream pts(m[1].str());
    std::vector<double> xs;
    std::string pair;
    while (pts >> pair) {
        xs.push_back(std::stod(pair.substr(0, pair.find(','))));
    }
    ASSERT_EQ(xs.size(), 3u);
    EXPECT_LT(xs[0], xs[1]);
    EXPECT_LT(xs[1], xs[2]);
    EXPECT_NE(svg.find("a&lt;1&gt;"), std::string::npos);  // labels escaped
    EXPECT_NE(svg.find("t &amp; t"), std::string::npos);
    EXPECT_NE(svg.find("not drawn (non-finite): n"), std::string::npos);
    EXPECT_NE(svg.find("(log scale)"), std::string::npos);
    // Degenerate input still gives a document.
    EXPECT_NE(svg_chart({}, o).find("</svg>"), std::string::npos);
    EXPECT_NE(svg_chart({{"one", 2, 2, 2, 0}}, o).find("<circle"), std::string::npos);
}

TEST(BenchTiming, MedianPercentilesMinMax)
{
    const Timing odd = summarize({5, 1, 3, 2, 4});
    EXPECT_EQ(odd.median_ms, 3);
    EXPECT_EQ(odd.min_ms, 1);
    EXPECT_EQ(odd.max_ms, 5);
    EXPECT_EQ(odd.p10_ms, 1);
    EXPECT_EQ(odd.p90_ms, 5);
    EXPECT_EQ(odd.runs_ms, (std::vector<double>{5, 1, 3, 2, 4}));  // run order kept
    const Timing even = summarize({4, 1, 3, 2});
    EXPECT_EQ(even.median_ms, 2.5);
    EXPECT_TRUE(std::isnan(summarize({}).median_ms));
    std::vector<double> many;
    for (int i = 1; i <= 20; ++i) {
        many.push_back(i);
    }
    EXPECT_EQ(summarize(many).p10_ms, 2);
    EXPECT_EQ(summarize(many).p90_ms, 18);
}

// --- CSV -----------------------------------------------------------------------------------

TEST(BenchCsv, OneLinePerSettingWithRatiosAndFlags)
{
    BenchResult r;
    r.spec.node = "blur";
    r.spec.baseline = "ref";
    r.frames = {1, 2, 3};
    r.threads = 2;
    SettingResult a;
    a.setting = {"ref", {"blur.samples=64"}};
    a.node = summarize({10, 12, 11});
    a.graph = summarize({20, 22, 21});
    a.speed_ratio = 1.0;
    a.rmse = 0.01;
    a.psnr = 40;
    a.pareto = true;
    SettingResult b;
    b.setting = {"fast, \"cheap\"", {"blur.samples=8", "blur.mode=fast"}};
    b.node = summarize({2, 3, 2.5});
    b.graph = summarize({12, 13, 12.5});
    b.speed_ratio = 11.0 / 2.5;
    b.rmse = 0.05;
    b.psnr = std::numeric_limits<double>::infinity();
    r.settings = {a, b};
    const std::string csv = results_csv(r);
    std::istringstream in(csv);
    std::string header, l1, l2, extra;
    std::getline(in, header);
    std::getline(in, l1);
    std::getline(in, l2);
    EXPECT_FALSE(std::getline(in, extra));
    EXPECT_EQ(header,
              "setting,node_median_ms,node_p10_ms,node_p90_ms,node_min_ms,node_max_ms,"
              "graph_median_ms,graph_min_ms,graph_max_ms,speed_ratio,rmse,psnr,flip,pareto,runs,"
              "threads,frames,overrides");
    EXPECT_EQ(l1, "ref,11,10,12,10,12,21,20,22,1,0.01,40,,1,3,2,3,blur.samples=64");
    EXPECT_EQ(l2,
              "\"fast, \"\"cheap\"\"\",2.5,2,3,2,3,12.5,12,13,4.4,0.05,inf,,0,3,2,3,"
              "blur.samples=8 blur.mode=fast");
}

// --- Spec ----------------------------------------------------------------------------------

TEST(BenchSpecFile, ParsesResolvesAndDefaults)
{
    const BenchSpec s = parse_spec(
        R"({"graph": "g.json", "node": "n", "truth": {"pattern": "t/####.exr"},
            "settings": [{"name": "a", "set": ["n.x=1"]}, {"name": "b"}], "baseline": "b",
            "metrics": ["rmse", "flip"], "runs": 3, "frames": "1-4"})",
        "spec.json",
        "/base");
    EXPECT_EQ(s.graph, "/base/g.json");
    EXPECT_EQ(s.truth_pattern, "/base/t/####.exr");
    ASSERT_EQ(s.settings.size(), 2u);
    EXPECT_EQ(s.settings[0].overrides, (std::vector<std::string>{"n.x=1"}));
    EXPECT_TRUE(s.flip);
    EXPECT_EQ(s.runs, 3);
    EXPECT_EQ(s.warmup, 1);
    EXPECT_EQ(s.pass, "color");
    const BenchSpec d = parse_spec(R"({"graph": "/g.json", "node": "n",
                                       "truth": {"graph": "t.json", "node": "m"}})",
                                   "s",
                                   "/x");
    EXPECT_EQ(d.graph, "/g.json");
    EXPECT_EQ(d.truth_graph, "/x/t.json");
    ASSERT_EQ(d.settings.size(), 1u);
    EXPECT_EQ(d.settings[0].name, "default");
}

TEST(BenchSpecFile, ErrorsNameThePlace)
{
    auto message = [](const std::string &text) {
        try {
            parse_spec(text, "s.json", "");
        } catch (const Error &e) {
            EXPECT_EQ(e.exit_code(), 2);
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const std::string ok_head = R"("graph": "g", "node": "n", )";
    EXPECT_NE(message("{" + ok_head + R"("truth": {"pattern": "p"}, "runz": 3})")
                  .find("s.json:/: unknown key \"runz\" (did you mean \"runs\"?)"),
              std::string::npos);
    EXPECT_NE(message(R"({"graph": "g", "node": "n"})").find("missing key \"truth\""),
              std::string::npos);
    EXPECT_NE(
        message("{" + ok_head + R"("truth": {"pattern": "p", "graph": "g"}})").find("exactly one"),
        std::string::npos);
    EXPECT_NE(message("{" + ok_head +
                      R"("truth": {"pattern": "p"}, "settings": [{"name": "a"}], "baseline": "b"})")
                  .find("s.json:/baseline: no setting \"b\""),
              std::string::npos);
    EXPECT_NE(message("{" + ok_head + R"("truth": {"pattern": "p"}, "settings": [{"name": "a",
                      "set": [1]}]})")
                  .find("s.json:/settings/0/set/0: expected a string"),
              std::string::npos);
    EXPECT_NE(message("{" + ok_head + R"("truth": {"pattern": "p"}, "runs": 0})").find("runs"),
              std::string::npos);
    EXPECT_NE(message("{" + ok_head + R"("truth": {"pattern": "p"}, "metrics": ["ssim"]})")
                  .find("unknown metric \"ssim\""),
              std::string::npos);
}

// --- End to end ----------------------------------------------------------------------------

void write_exr(const std::string &path, int w, int h, float base)
{
    std::vector<float> px(std::size_t(w * h * 4));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            float *p = &px[std::size_t((y * w + x) * 4)];
            p[0] = base + 0.01f * float(x);
            p[1] = base * 0.5f + 0.02f * float(y);
            p[2] = 0.3f;
            p[3] = (x + y) % 3 == 0 ? 0.0f : 1.0f;
        }
    }
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path, OIIO::ImageSpec(w, h, 4, OIIO::TypeDesc::FLOAT)));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, px.data()));
    ASSERT_TRUE(out->close());
}

class BenchEndToEnd : public test::ScratchFolderTest {
   protected:
    BenchEndToEnd() : ScratchFolderTest("posthaste_bench_") {}
    void SetUp() override
    {
        ScratchFolderTest::SetUp();
        for (int f = 1; f <= 2; ++f) {
            write_exr(path("fg.000" + std::to_string(f) + ".exr"), 24, 16, 0.2f * float(f));
            write_exr(path("bg.000" + std::to_string(f) + ".exr"), 24, 16, 0.6f);
            write_exr(path("truth.000" + std::to_string(f) + ".exr"), 24, 16, 0.4f);
        }
        std::ofstream(path("g.json")) << R"({"frames": "1-2", "nodes": [
            {"id": "fg", "type": "read", "params": {"path": ")"
                                      << path("fg.####.exr") << R"("}},
            {"id": "bg", "type": "read", "params": {"path": ")"
                                      << path("bg.####.exr") << R"("}},
            {"id": "m", "type": "merge", "inputs": {"a": "fg", "b": "bg"}},
            {"id": "w", "type": "write", "inputs": {"image": "m"},
             "params": {"path": ")" << path("out/w.####.exr")
                                      << R"("}}]})";
    }
};

TEST_F(BenchEndToEnd, TwoSettingsTwoRunsAgainstATruthGraph)
{
    std::ofstream(path("spec.json")) << R"({"graph": "g.json", "node": "m",
        "truth": {"graph": "g.json", "node": "m", "set": ["m.operation=over"]},
        "settings": [{"name": "over", "set": ["m.operation=over"]},
                     {"name": "half", "set": ["m.mix=0.5"]}],
        "baseline": "over", "metrics": ["rmse", "psnr", "flip"], "warmup": 0, "runs": 2,
        "threads": 1})";
    const BenchResult r = run_bench(load_spec(path("spec.json")));
    EXPECT_EQ(r.frames, (std::vector<int>{1, 2}));
    EXPECT_EQ(r.threads, 1);
    ASSERT_EQ(r.settings.size(), 2u);
    for (const SettingResult &s : r.settings) {
        SCOPED_TRACE(s.setting.name);
        EXPECT_EQ(s.node.runs_ms.size(), 2u);
        EXPECT_TRUE(std::isfinite(s.node.median_ms));
        EXPECT_GT(s.node.median_ms, 0.0);
        EXPECT_GE(s.graph.median_ms, s.node.median_ms);
        EXPECT_TRUE(std::isfinite(s.speed_ratio));
        EXPECT_TRUE(std::isfinite(s.rmse));
        EXPECT_TRUE(std::isfinite(s.flip));
        EXPECT_EQ(s.thumbnail.width(), 24);
        EXPECT_EQ(s.difference.channels(), 3);
    }
    EXPECT_EQ(r.settings[0].rmse, 0.0);  // the truth is the same graph and setting
    EXPECT_TRUE(std::isinf(r.settings[0].psnr));
    EXPECT_EQ(r.settings[0].speed_ratio, 1.0);
    EXPECT_GT(r.settings[1].rmse, 0.0);
    EXPECT_TRUE(std::isfinite(r.settings[1].psnr));
    EXPECT_TRUE(r.settings[0].pareto);

    write_results(r, path("res"));
    for (const char *f : {"results.csv",
                          "chart.svg",
                          "index.html",
                          "results.json",
                          "thumbs/0.png",
                          "thumbs/0_diff.png",
                          "thumbs/1.png",
                          "thumbs/1_diff.png"}) {
        EXPECT_TRUE(fs::exists(path("res/") + f)) << f;
    }
    auto png = OIIO::ImageInput::open(path("res/thumbs/1_diff.png"));
    ASSERT_TRUE(png);
    EXPECT_EQ(png->spec().width, 24);
    std::ifstream html(path("res/index.html"));
    std::stringstream ss;
    ss << html.rdbuf();
    EXPECT_NE(ss.str().find("<svg"), std::string::npos);
    EXPECT_NE(ss.str().find("thumbs/1_diff.png"), std::string::npos);
}

TEST_F(BenchEndToEnd, CommandLineWithTruthFiles)
{
    std::ofstream(path("spec.json")) << R"({"graph": "g.json", "node": "m",
        "truth": {"pattern": "truth.####.exr"},
        "settings": [{"name": "add", "set": ["m.operation=add"]},
                     {"name": "max", "set": ["m.operation=max"]}],
        "warmup": 1, "runs": 5})";
    const std::string cmd = std::string(POSTHASTE_BINARY) +
                            " bench -q --runs 2 --threads 1 --out " + path("cli") + " " +
                            path("spec.json") + " 2>&1";
    FILE *pipe = popen(cmd.c_str(), "r");
    ASSERT_TRUE(pipe);
    std::string output;
    char buf[512];
    while (std::fgets(buf, sizeof(buf), pipe)) {
        output += buf;
    }
    const int status = pclose(pipe);
    ASSERT_TRUE(WIFEXITED(status));
    ASSERT_EQ(WEXITSTATUS(status), 0) << output;
    std::ifstream csv(path("cli/results.csv"));
    std::string header, line;
    std::getline(csv, header);
    int rows = 0;
    while (std::getline(csv, line)) {
        ++rows;
        std::vector<std::string> cells;
        std::stringstream ls(line);
        for (std::string cell; std::getline(ls, cell, ',');) {
            cells.push_back(cell);
        }
        ASSERT_GE(cells.size(), 17u) << line;
        for (std::size_t i : {1u, 6u, 10u, 11u}) {  // node median, graph median, rmse, psnr
            EXPECT_TRUE(std::isfinite(std::stod(cells[i]))) << header << "\n" << line;
        }
        EXPECT_EQ(cells[14], "2");  // runs, from --runs
        EXPECT_EQ(cells[15], "1");  // threads
    }
    EXPECT_EQ(rows, 2);
    EXPECT_TRUE(fs::exists(path("cli/chart.svg")));
    EXPECT_TRUE(fs::exists(path("cli/thumbs/1_diff.png")));
}

// The ready specs under graphs/bench/ run (one quick run of their first frame each, from the
// repository root, where their graphs' relative paths point).
/// Run every ready spec under graphs/bench/ (the graphs they use live in graphs/bench/graphs/)
/// whose graph renders (`heavy`) or does not; one quick run each, from the repository root.
void run_ready_specs(bool heavy)
{
    const fs::path out = fs::temp_directory_path() /
                         ("posthaste_ready_" + std::to_string(::getpid()) + (heavy ? "_h" : ""));
    int ran = 0;
    for (const auto &entry :
         fs::directory_iterator(fs::path(POSTHASTE_SOURCE_DIR) / "graphs/bench")) {
        const std::string name = entry.path().filename().string();
        if (!entry.is_regular_file() || entry.path().extension() != ".json") {
            continue;
        }
        std::ifstream in(entry.path());
        const std::string text((std::istreambuf_iterator<char>(in)),
                               std::istreambuf_iterator<char>());
        // Specs whose graphs render ground truth, or exact 1080p references (bloom's FFT), take
        // minutes (far more under the sanitizers): they run in the Slow suite.
        const bool renders = text.find("graphs/truth_") != std::string::npos ||
                             text.find("fog_graph") != std::string::npos ||
                             text.find("bloom_graph") != std::string::npos;
        if (renders != heavy) {
            continue;
        }
        ++ran;
        SCOPED_TRACE(name);
        // A spec's first frame only: the check is that it runs, and its truth is the slow part.
        const std::string frames = bench::load_spec(entry.path().string()).frames;
        const std::string first = frames.substr(0, frames.find_first_of(",-"));
        const std::string cmd = std::string("cd ") + POSTHASTE_SOURCE_DIR + " && " +
                                POSTHASTE_BINARY + " bench -q --runs 1 --warmup 0 " +
                                (first.empty() ? "" : "--frames " + first + " ") + "--out " +
                                (out / name).string() + " graphs/bench/" + name + " 2>&1";
        FILE *pipe = popen(cmd.c_str(), "r");
        ASSERT_TRUE(pipe);
        std::string output;
        char buf[512];
        while (std::fgets(buf, sizeof(buf), pipe)) {
            output += buf;
        }
        const int status = pclose(pipe);
        EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << output;
        EXPECT_TRUE(fs::exists(out / name / "index.html"));
        EXPECT_TRUE(fs::exists(out / name / "results.csv"));
    }
    EXPECT_GE(ran, 2);
    fs::remove_all(out);
}

// A renderer's AO pass against the ao node: the truth's pass named apart (Cycles' grey RGB
// "ViewLayer.AO"), one channel of it, and the sky left out (Cycles writes 0 there, the node 1).
TEST_F(BenchEndToEnd, TruthPassChannelAndSkyExcluded)
{
    Frame f;
    f.set_size(8, 4);
    Image ao(8, 4, 1), depth(8, 4, 1), truth(8, 4, 3);
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 8; ++x) {
            const bool sky = x >= 4;
            ao.at(x, y, 0) = sky ? 1.0f : 0.1f * float(x + y);
            depth.at(x, y, 0) = sky ? std::numeric_limits<float>::infinity() : 2.0f;
            truth.at(x, y, 0) = sky ? 0.0f : ao.at(x, y, 0);
            truth.at(x, y, 1) = 7.0f;  // other channels: not compared
            truth.at(x, y, 2) = -3.0f;
        }
    }
    f.set("ao", std::move(ao), {"Y"});
    f.set("depth", std::move(depth));
    write_exr(f, path("ao.0001.exr"), {});
    Frame t;
    t.set_size(8, 4);
    t.set("t", std::move(truth), {"R", "G", "B"});
    write_exr(t, path("t.0001.exr"), {});
    std::ofstream(path("ao.json")) << R"({"nodes": [
        {"id": "r", "type": "read", "params": {"path": ")"
                                   << path("ao.####.exr") << R"("}},
        {"id": "w", "type": "write", "inputs": {"image": "r"},
         "params": {"path": ")" << path("out/o.####.exr")
                                   << R"(", "passes": "ao"}}]})";
    auto spec = [&](const std::string &exclude) {
        std::ofstream(path("s.json")) << R"({"graph": "ao.json", "node": "r", "pass": "ao",
            "frames": "1", "truth": {"pattern": "t.####.exr", "pass": "t", "channel": 0},)"
                                      << exclude << R"( "warmup": 0, "runs": 1})";
        return run_bench(load_spec(path("s.json")));
    };
    EXPECT_EQ(spec(R"("exclude": "sky",)").settings.at(0).rmse, 0.0);
    // With the sky: half the pixels differ by 1, RMSE sqrt(1/2).
    EXPECT_NEAR(spec("").settings.at(0).rmse, std::sqrt(0.5), 1e-6);
    // Bad values name the key.
    std::ofstream(path("bad.json")) << R"({"graph": "ao.json", "node": "r",
        "truth": {"pattern": "t.####.exr", "channel": -1}})";
    try {
        load_spec(path("bad.json"));
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("/truth/channel"), std::string::npos) << e.what();
    }
    // A pass the node or the truth file does not have is the spec's mistake: exit 2, naming the
    // key, before any timing.
    auto usage_error = [&](const std::string &pass, const std::string &truth_pass) {
        std::ofstream(path("s.json")) << R"({"graph": "ao.json", "node": "r", "pass": ")" << pass
                                      << R"(", "frames": "1", "truth": {"pattern": "t.####.exr",
            "pass": ")" << truth_pass << R"(", "channel": 0}, "warmup": 0, "runs": 1})";
        try {
            run_bench(load_spec(path("s.json")));
        } catch (const Error &e) {
            EXPECT_EQ(e.exit_code(), 2) << e.what();
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(usage_error("aoo", "t").find("/pass: node \"r\" gives no pass \"aoo\" (have: ao, "),
              std::string::npos);
    EXPECT_NE(usage_error("ao", "tt")
                  .find("/truth/pass: " + path("t.0001.exr") + " has no pass \"tt\" (have: t)"),
              std::string::npos);
    std::ofstream(path("bad.json")) << R"({"graph": "ao.json", "node": "r",
        "truth": {"pattern": "t.####.exr"}, "exclude": "clouds"})";
    try {
        load_spec(path("bad.json"));
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("/exclude"), std::string::npos) << e.what();
    }
}

TEST(BenchReadySpecs, RunFromTheRepositoryRoot)
{
    run_ready_specs(false);
}

TEST(BenchReadySpecsSlow, NodeSpecsAgainstRenderedTruthRun)
{
    run_ready_specs(true);
}

}  // namespace
}  // namespace posthaste::bench

namespace posthaste::bench {
namespace {

TEST(BenchStabilityChart, GridHasOneCellPerCaseColoredByStatus)
{
    const std::string record = R"({"cases": [
        {"node": "merge", "params": "defaults", "frame": "plain", "status": "ok", "message": ""},
        {"node": "merge", "params": "defaults", "frame": "nan<>", "status": "unstable",
         "message": "3 non-finite", "spread": 3, "max_abs": 1.0, "ms": 0.1},
        {"node": "ocio", "params": "to_linear", "frame": "plain", "status": "known_failure",
         "message": "why"}]})";
    const std::string svg = stability_svg(record, "s.json");
    EXPECT_EQ(count_of(svg, "<rect class="), 3u);
    EXPECT_EQ(count_of(svg, "class=\"unstable\""), 1u);
    EXPECT_NE(svg.find("nan&lt;&gt;"), std::string::npos);
    EXPECT_NE(svg.find("merge / defaults"), std::string::npos);
    const std::string html = stability_html(record, "s.json");
    EXPECT_NE(html.find("3 case(s): 1 known_failure; 1 ok; 1 unstable;"), std::string::npos);
    EXPECT_THROW(stability_svg("[1]", "s.json"), Error);
}

}  // namespace
}  // namespace posthaste::bench
