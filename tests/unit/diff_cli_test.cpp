// Tests for `posthaste diff` (src/cli/cmd_diff.cpp), run as a process: exit codes agree with
// OpenImageIO's idiff for several threshold sets, JSON numbers equal metrics::compare, frame
// sequences with a missing frame, size mismatch, unreadable files, and the images it writes.

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "core/hash.h"
#include "metrics/metrics.h"
#include "scratch_folder_test.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;

struct Process {
    int exit_code = -1;
    std::string output;  ///< stdout and stderr together
};

Process run_process(const std::string &command)
{
    Process p;
    FILE *pipe = popen((command + " 2>&1").c_str(), "r");
    if (!pipe) {
        return p;
    }
    char buf[1024];
    while (std::fgets(buf, sizeof(buf), pipe)) {
        p.output += buf;
    }
    const int status = pclose(pipe);
    p.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return p;
}

std::string find_on_path(const std::string &name)
{
    const char *path = std::getenv("PATH");
    std::stringstream ss(path ? path : "");
    std::string dir;
    while (std::getline(ss, dir, ':')) {
        const fs::path p = fs::path(dir) / name;
        if (!dir.empty() && fs::exists(p)) {
            return p.string();
        }
    }
    return {};
}

Image noise(int w, int h, int c, std::uint32_t seed, float lo = 0.1f, float range = 0.8f)
{
    Image img(w, h, c);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int k = 0; k < c; ++k) {
                img.at(x, y, k) = lo + range * hash_unit(x, y, k, seed);
            }
        }
    }
    return img;
}

/// b = a + amplitude * (hash in [-1, 1]) on every value.
Image perturbed(const Image &a, float amplitude, std::uint32_t seed)
{
    Image b = a;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int k = 0; k < a.channels(); ++k) {
                b.at(x, y, k) += amplitude * (2.0f * hash_unit(x, y, k, seed) - 1.0f);
            }
        }
    }
    return b;
}

/// A file of one part per spec (float), each holding the same `pixels`.
void write_parts(const std::string &path,
                 const std::vector<OIIO::ImageSpec> &specs,
                 const float *pixels)
{
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << OIIO::geterror();
    ASSERT_TRUE(out->open(path, int(specs.size()), specs.data())) << out->geterror();
    for (std::size_t p = 0; p < specs.size(); ++p) {
        if (p > 0) {
            ASSERT_TRUE(out->open(path, specs[p], OIIO::ImageOutput::AppendSubimage))
                << out->geterror();
        }
        ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, pixels)) << out->geterror();
    }
    ASSERT_TRUE(out->close()) << out->geterror();
}

void write_float_exr(const std::string &path, const Image &img)
{
    write_parts(path,
                {OIIO::ImageSpec(img.width(), img.height(), img.channels(), OIIO::TypeDesc::FLOAT)},
                img.data());
}

/// idiff's single-dash options ("-fail 0.1") as ours ("--fail 0.1").
std::string double_dashed(const std::string &args)
{
    std::istringstream in(args);
    std::string word, out;
    while (in >> word) {
        if (!out.empty()) {
            out += ' ';
        }
        if (word.size() > 1 && word[0] == '-' && std::isalpha(word[1])) {
            out += '-';
        }
        out += word;
    }
    return out;
}

nlohmann::json read_json(const fs::path &path)
{
    std::ifstream in(path);
    return nlohmann::json::parse(in);
}

class DiffCli : public test::ScratchFolderTest {
   protected:
    DiffCli() : ScratchFolderTest("posthaste_diff_cli_") {}

    Process diff(const std::string &args) const
    {
        return run_process(std::string(POSTHASTE_BINARY) + " diff --flip off " + args);
    }
};

// --- Agreement with idiff ----------------------------------------------------------------

/// Its own suite (one ctest entry) because it starts ~50 processes.
class DiffCliIdiff : public DiffCli {};

TEST_F(DiffCliIdiff, ExitCodesAndJsonMatchCompare)
{
    const std::string idiff = find_on_path("idiff");
    if (idiff.empty()) {
        GTEST_SKIP() << "idiff (openimageio-tools) is not on PATH";
    }
    struct Pair {
        std::string name;
        Image a, b;
    };
    const Image base = noise(23, 17, 4, 1);
    Image spike = base;
    spike.at(5, 9, 2) += 0.5f;
    spike.at(20, 1, 0) -= 0.02f;
    std::vector<Pair> pairs = {
        {"same", base, base},
        {"small", base, perturbed(base, 0.002f, 7)},
        {"large", base, perturbed(base, 0.05f, 9)},
        {"spike", base, spike},
        {"rgb",
         noise(9, 31, 3, 4, 0.0f, 4.0f),
         perturbed(noise(9, 31, 3, 4, 0.0f, 4.0f), 0.01f, 5)},
    };
    struct Set {
        std::string args;
        metrics::Thresholds t;
    };
    std::vector<Set> sets;
    sets.push_back({"", {}});
    metrics::Thresholds loose;
    loose.fail = 0.004f;
    loose.fail_percent = 0.02f;
    loose.hard_fail = 0.012f;
    loose.warn = 0.001f;
    sets.push_back({"-fail 0.004 -failpercent 0.02 -hardfail 0.012 -warn 0.001", loose});
    metrics::Thresholds percent;
    percent.fail = 0.01f;
    percent.fail_percent = 30.0f;
    percent.warn = 0.001f;
    percent.warn_percent = 5.0f;
    sets.push_back({"-fail 0.01 -failpercent 30 -warn 0.001 -warnpercent 5", percent});
    metrics::Thresholds allow;
    allow.fail = 0.1f;
    allow.allow_failures = 1;
    allow.warn = 0.01f;
    allow.hard_warn = 0.3f;
    sets.push_back({"-fail 0.1 -allowfailures 1 -warn 0.01 -hardwarn 0.3", allow});

    metrics::Thresholds warn;
    warn.fail = 0.04f;
    warn.fail_percent = 70.0f;
    warn.warn = 0.01f;
    sets.push_back({"-fail 0.04 -failpercent 70 -warn 0.01", warn});

    std::set<int> codes_seen;
    for (const Pair &p : pairs) {
        const std::string pa = path(p.name + "_a.exr");
        const std::string pb = path(p.name + "_b.exr");
        write_float_exr(pa, p.a);
        write_float_exr(pb, p.b);
        for (const Set &s : sets) {
            SCOPED_TRACE(p.name + " [" + s.args + "]");
            const Process ref = run_process(idiff + " " + s.args + " " + pa + " " + pb);
            const std::string ours_args = double_dashed(s.args);
            const std::string json = path("report.json");
            const Process ours = diff(ours_args + " --json " + json + " " + pa + " " + pb);
            EXPECT_EQ(ours.exit_code, ref.exit_code) << ours.output << "\nidiff:\n" << ref.output;
            codes_seen.insert(ours.exit_code);

            const metrics::CompareStats stats = metrics::compare(p.a, p.b, s.t);
            const nlohmann::json j = read_json(json);
            ASSERT_EQ(j["frames"].size(), 1u);
            const nlohmann::json &pass = j["frames"][0]["passes"][0];
            EXPECT_EQ(pass["name"], "color");
            const nlohmann::json &st = pass["stats"];
            EXPECT_DOUBLE_EQ(st["mean_error"].get<double>(), stats.all.mean_error);
            EXPECT_DOUBLE_EQ(st["rms_error"].get<double>(), stats.all.rms_error);
            if (std::isfinite(stats.all.psnr)) {
                EXPECT_DOUBLE_EQ(st["psnr"].get<double>(), stats.all.psnr);
            } else {
                EXPECT_EQ(st["psnr"], "inf");
            }
            EXPECT_DOUBLE_EQ(st["max_error"].get<double>(), stats.all.max_error);
            EXPECT_EQ(st["fail_pixels"].get<std::uint64_t>(), stats.all.fail_count);
            EXPECT_EQ(st["warn_pixels"].get<std::uint64_t>(), stats.all.warn_count);
            EXPECT_EQ(j["exit_code"].get<int>(), ours.exit_code);
        }
    }
    // The pairs and threshold sets reach every idiff verdict but the size/file ones.
    EXPECT_EQ(codes_seen, (std::set<int>{0, 1, 2}));
}

TEST_F(DiffCli, SizeMismatchIsThree)
{
    write_float_exr(path("a.exr"), noise(8, 8, 4, 1));
    write_float_exr(path("b.exr"), noise(8, 9, 4, 1));
    write_float_exr(path("rgb.exr"), noise(8, 8, 3, 1));
    // Departure from idiff 2.4.7, which compares different sizes over the union of the two
    // windows and missing channels as 0, and so reports a failure (2): we refuse to compare
    // and exit 3 (idiff's ErrDifferentSize), so CI can tell "wrong shape" from "wrong pixels".
    const Process ours = diff(path("a.exr") + " " + path("b.exr"));
    EXPECT_EQ(ours.exit_code, 3) << ours.output;
    EXPECT_NE(ours.output.find("SIZE MISMATCH"), std::string::npos) << ours.output;
    // Different channel counts (the reader's A = 1 fill for RGB files is not compared).
    const Process rgb = diff(path("a.exr") + " " + path("rgb.exr"));
    EXPECT_EQ(rgb.exit_code, 3) << rgb.output;
    const std::string idiff = find_on_path("idiff");
    if (!idiff.empty()) {
        for (const std::string other : {"b.exr", "rgb.exr"}) {
            EXPECT_EQ(run_process(idiff + " " + path("a.exr") + " " + path(other)).exit_code, 2)
                << "idiff's behaviour changed; revisit the departure in docs/DIFF.md";
        }
    }
}

// A luminance file's one Y channel is what it stores: against an RGB file of the same gray the
// channel counts differ (the reader's R = G = B = Y had passed, exit 0; idiff fails it).
TEST_F(DiffCli, LuminanceAgainstRgbIsASizeMismatch)
{
    Image gray(6, 4, 3);
    gray.fill(0.5f);
    write_float_exr(path("gray_rgb.exr"), gray);
    {
        OIIO::ImageSpec spec(6, 4, 1, OIIO::TypeDesc::FLOAT);
        spec.channelnames = {"Y"};
        const std::vector<float> y(24, 0.5f);
        write_parts(path("gray_y.exr"), {spec}, y.data());
    }
    const Process p = diff(path("gray_rgb.exr") + " " + path("gray_y.exr"));
    EXPECT_EQ(p.exit_code, 3) << p.output;
    EXPECT_NE(p.output.find("3 channels (R, G, B) vs 1 channels (Y)"), std::string::npos)
        << p.output;
    EXPECT_EQ(diff(path("gray_y.exr") + " " + path("gray_y.exr")).exit_code, 0);
}

// Thresholds are numbers of at least 0 (percentages at most 100), never NaN (a NaN
// --failpercent turned a FAILURE into a WARNING); --ppd at most 1000 (1e9 hung in FLIP's
// filter, 1e30 and inf crashed it); --diff-image writes EXR, so it needs an .exr name.
TEST_F(DiffCli, ThresholdsAndPpdAreBounded)
{
    write_float_exr(path("a.exr"), noise(7, 5, 3, 1));
    write_float_exr(path("b.exr"), noise(7, 5, 3, 2));
    const std::string ab = str_cat(" ", path("a.exr"), " ", path("b.exr"));
    for (const std::string bad : {"--failpercent nan",
                                  "--fail -1",
                                  "--hardfail -3",
                                  "--failrelative -1",
                                  "--warn nan",
                                  "--warnpercent 101",
                                  "--ppd 1e9",
                                  "--ppd inf",
                                  "--ppd 1e30"}) {
        const Process p = diff(bad + ab);
        EXPECT_EQ(p.exit_code, 2) << bad << ": " << p.output;
        EXPECT_NE(p.output.find("must be a number"), std::string::npos) << bad << ": " << p.output;
    }
    EXPECT_EQ(diff("--hardfail inf --ppd 1000" + ab).exit_code, 2);  // a FAILURE, computed
    const Process png = diff("--diff-image " + path("d.png") + ab);
    EXPECT_EQ(png.exit_code, 2) << png.output;
    EXPECT_NE(png.output.find("give a name ending in .exr"), std::string::npos) << png.output;
    EXPECT_FALSE(std::filesystem::exists(path("d.png")));
}

// --- File errors ---------------------------------------------------------------------------

TEST_F(DiffCli, MissingFileIsFileErrorNamingIt)
{
    write_float_exr(path("a.exr"), noise(8, 8, 4, 1));
    const Process p = diff(path("a.exr") + " " + path("nope.exr"));
    EXPECT_EQ(p.exit_code, 4) << p.output;
    EXPECT_NE(p.output.find("nope.exr"), std::string::npos) << p.output;
    EXPECT_EQ(std::count(p.output.begin(), p.output.end(), '\n'), 1) << p.output;
}

TEST_F(DiffCli, NonExrAndTruncatedFilesAreFileErrors)
{
    write_float_exr(path("a.exr"), noise(32, 32, 4, 1));
    std::ofstream(path("text.exr")) << "this is not an image\n";
    const auto size = fs::file_size(path("a.exr"));
    fs::copy_file(path("a.exr"), path("cut.exr"));
    fs::resize_file(path("cut.exr"), size / 2);
    for (const std::string name : {"text.exr", "cut.exr"}) {
        SCOPED_TRACE(name);
        const Process p = diff(path("a.exr") + " " + path(name));
        EXPECT_EQ(p.exit_code, 4) << p.output;
        EXPECT_NE(p.output.find(name), std::string::npos) << p.output;
        const Process q = diff(path(name) + " " + path("a.exr"));
        EXPECT_EQ(q.exit_code, 4) << q.output;
    }
}

TEST_F(DiffCli, MissingPassIsFileError)
{
    write_float_exr(path("a.exr"), noise(8, 8, 4, 1));
    const Process p = diff("--pass depth " + path("a.exr") + " " + path("a.exr"));
    EXPECT_EQ(p.exit_code, 4) << p.output;
    EXPECT_NE(p.output.find("depth"), std::string::npos) << p.output;
}

// Outputs that cannot be written are idiff's file error (4), never 1 (a WARNING) over images
// that fail; a device is written in place, not replaced by a file; absurd patterns and options
// that cannot apply are usage errors at once.
TEST_F(DiffCli, OutputsPatternsAndOptionsThatCannotApply)
{
    write_float_exr(path("a.exr"), noise(8, 8, 4, 1));
    write_float_exr(path("b.exr"), noise(8, 8, 4, 2));
    const std::string ab = path("a.exr") + " " + path("b.exr");
    std::ofstream(path("afile")) << "x";
    Process p = diff(ab + " --report " + path("afile"));
    EXPECT_EQ(p.exit_code, 4) << p.output;
    EXPECT_NE(p.output.find("Not a directory"), std::string::npos) << p.output;
    if (fs::is_character_file("/dev/full")) {
        p = diff(ab + " --json /dev/full");
        EXPECT_EQ(p.exit_code, 4) << p.output;
        EXPECT_NE(p.output.find("/dev/full: cannot write: No space left on device"),
                  std::string::npos)
            << p.output;
        EXPECT_TRUE(fs::is_character_file("/dev/full"));  // not renamed over
    }
    p = diff(path("s.%2147483647d.exr") + " " + path("b.####.exr") + " --frames 1");
    EXPECT_EQ(p.exit_code, 2) << p.output.substr(0, 300);
    EXPECT_NE(p.output.find("padded to 2147483647 digits"), std::string::npos)
        << p.output.substr(0, 300);
    EXPECT_LT(p.output.size(), 400u);
    p = diff(ab + " --frames 1-3");
    EXPECT_EQ(p.exit_code, 2) << p.output;
    EXPECT_NE(p.output.find("has a frame placeholder"), std::string::npos) << p.output;
    p = diff(ab + " --flip-map " + path("f.png"));  // the fixture's --flip off
    EXPECT_EQ(p.exit_code, 2) << p.output;
    EXPECT_FALSE(fs::exists(path("f.png")));
}

// The same pixels in another display window (a crop or an overscan lost) warn: they passed.
TEST_F(DiffCli, ADisplayWindowThatDiffersWarns)
{
    const Image img = noise(8, 8, 3, 1);
    write_float_exr(path("a.exr"), img);
    OIIO::ImageSpec spec(8, 8, 3, OIIO::TypeDesc::FLOAT);
    spec.full_width = spec.full_height = 16;
    write_parts(path("b.exr"), {spec}, img.data());
    const Process p = diff(path("a.exr") + " " + path("b.exr"));
    EXPECT_EQ(p.exit_code, 1) << p.output;
    EXPECT_NE(p.output.find("display window 8x8 at (0, 0) vs 16x16 at (0, 0)"), std::string::npos)
        << p.output;
}

// info: a header's escape sequence is printed escaped; one camera matrix alone is named as
// such; the files after a bad one are still described, and the exit code is the bad one's.
TEST_F(DiffCli, InfoEscapesSaysWhichMatrixAndGoesOnPastABadFile)
{
    const std::string odd = path("odd.exr");
    const std::vector<float> pixels(4 * 4 * 3, 0.5f);
    {
        OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::FLOAT);
        spec.attribute("weird", "red\x1b[31mtext");
        const float m[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
        spec.attribute("worldToCamera", OIIO::TypeMatrix44, m);
        write_parts(odd, {spec}, pixels.data());
    }
    // A second part with an attribute of its own: listed under that part (it was not shown).
    const std::string two = path("two.exr");
    {
        std::vector<OIIO::ImageSpec> specs(2, OIIO::ImageSpec(4, 4, 3, OIIO::TypeDesc::FLOAT));
        specs[0].attribute("name", "left");
        specs[1].attribute("name", "right");
        specs[1].attribute("onlyInPart1", "hello");
        write_parts(two, specs, pixels.data());
    }
    const Process parts = run_process(std::string(POSTHASTE_BINARY) + " info " + two);
    EXPECT_EQ(parts.exit_code, 0) << parts.output;
    EXPECT_NE(parts.output.find("    attribute onlyInPart1        string = hello"),
              std::string::npos)
        << parts.output;
    std::ofstream(path("text.exr")) << "not an image";
    const Process p =
        run_process(std::string(POSTHASTE_BINARY) + " info " + path("text.exr") + " " + odd);
    EXPECT_EQ(p.exit_code, 1) << p.output;
    EXPECT_NE(p.output.find("text.exr"), std::string::npos) << p.output;
    EXPECT_NE(p.output.find("weird              string = red\\x1b[31mtext"), std::string::npos)
        << p.output;
    EXPECT_EQ(p.output.find('\x1b'), std::string::npos) << p.output;
    EXPECT_NE(p.output.find("none: the header has worldToCamera but no worldToNDC"),
              std::string::npos)
        << p.output;
}

// --- Sequences -----------------------------------------------------------------------------

TEST_F(DiffCli, SequenceWithMissingFrameReportsItAndExitsWorst)
{
    const Image base = noise(8, 6, 4, 3);
    for (int f = 1; f <= 3; ++f) {
        char name[32];
        std::snprintf(name, sizeof(name), "a.%04d.exr", f);
        write_float_exr(path(name), base);
        if (f != 2) {
            std::snprintf(name, sizeof(name), "b.%04d.exr", f);
            write_float_exr(path(name), f == 3 ? perturbed(base, 0.01f, 1) : base);
        }
    }
    const std::string json = path("seq.json");
    const Process p = diff("--json " + json + " " + path("a.####.exr") + " " + path("b.%04d.exr"));
    EXPECT_EQ(p.exit_code, 4) << p.output;
    EXPECT_NE(p.output.find("b.0002.exr"), std::string::npos) << p.output;
    EXPECT_NE(p.output.find("frame 1: PASS"), std::string::npos) << p.output;
    EXPECT_NE(p.output.find("frame 3: FAILURE"), std::string::npos) << p.output;
    const nlohmann::json j = read_json(json);
    ASSERT_EQ(j["frames"].size(), 3u);
    EXPECT_EQ(j["frames"][0]["verdict"], "PASS");
    EXPECT_EQ(j["frames"][1]["verdict"], "FILE ERROR");
    EXPECT_EQ(j["frames"][2]["verdict"], "FAILURE");
    EXPECT_EQ(j["exit_code"], 4);

    // Only the good frames: the worst is the failure.
    EXPECT_EQ(diff("--frames 1,3 " + path("a.####.exr") + " " + path("b.####.exr")).exit_code, 2);
    EXPECT_EQ(diff("--frames 1 " + path("a.####.exr") + " " + path("b.####.exr")).exit_code, 0);
    // A frame missing from A (frames given explicitly) is a file error too.
    EXPECT_EQ(diff("--frames 1-4 " + path("a.####.exr") + " " + path("a.####.exr")).exit_code, 4);
    // No files at all for A's pattern.
    const Process none = diff(path("zzz.####.exr") + " " + path("b.####.exr"));
    EXPECT_EQ(none.exit_code, 4) << none.output;
    EXPECT_NE(none.output.find("zzz.####.exr"), std::string::npos) << none.output;
}

// --- Outputs -------------------------------------------------------------------------------

TEST_F(DiffCli, WritesValidDifferenceImagesFlipMapsAndJson)
{
    const Image a = noise(16, 12, 4, 5);
    const Image b = perturbed(a, 0.05f, 6);
    for (int f = 1; f <= 2; ++f) {
        write_float_exr(path("a." + std::to_string(f) + ".exr"), a);
        write_float_exr(path("b." + std::to_string(f) + ".exr"), b);
    }
    const std::string args = " --diff-image " + path("out/d.####.exr") + " --diff-scale 16" +
                             " --flip-map " + path("out/f.####.png") + " --json " +
                             path("out/r.json") + " --fail 1 --warn 1 " + path("a.%d.exr") + " " +
                             path("b.%d.exr");
    const Process p = run_process(std::string(POSTHASTE_BINARY) + " diff --flip hdr" + args);
    EXPECT_EQ(p.exit_code, 0) << p.output;
    for (int f = 1; f <= 2; ++f) {
        const std::string d = path("out/d.000" + std::to_string(f) + ".exr");
        auto in = OIIO::ImageInput::open(d);
        ASSERT_TRUE(in) << d << ": " << OIIO::geterror();
        const OIIO::ImageSpec &spec = in->spec();
        EXPECT_EQ(spec.width, 16);
        EXPECT_EQ(spec.height, 12);
        EXPECT_EQ(spec.nchannels, 4);
        std::vector<float> px(std::size_t(16 * 12 * 4));
        ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::FLOAT, px.data()));
        EXPECT_NEAR(px[0], 16.0f * std::fabs(a.data()[0] - b.data()[0]), 1e-5f);

        const std::string fm = path("out/f.000" + std::to_string(f) + ".png");
        auto png = OIIO::ImageInput::open(fm);
        ASSERT_TRUE(png) << fm << ": " << OIIO::geterror();
        EXPECT_EQ(png->spec().width, 16);
        EXPECT_EQ(png->spec().nchannels, 3);
    }
    const nlohmann::json j = read_json(path("out/r.json"));
    ASSERT_EQ(j["frames"].size(), 2u);
    EXPECT_GT(j["frames"][0]["flip"]["mean"].get<double>(), 0.0);
    // No temporary files left behind.
    for (const auto &e : fs::directory_iterator(path("out"))) {
        EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
    }
    // Several frames into one file name is refused before any work.
    const Process clash =
        diff("--diff-image " + path("one.exr") + " " + path("a.%d.exr") + " " + path("b.%d.exr"));
    EXPECT_EQ(clash.exit_code, 2) << clash.output;
    EXPECT_NE(clash.output.find("placeholder"), std::string::npos) << clash.output;
}

}  // namespace
}  // namespace posthaste
