// Tests for src/metrics/metrics.h: hand-computed compare statistics, idiff's verdict rules,
// thread-count independence, and agreement with the idiff binary and ImageBufAlgo::compare.

#include "metrics/metrics.h"

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <regex>
#include <sstream>
#include <string>

#include "core/error.h"
#include "core/hash.h"
#include "core/parallel.h"

namespace posthaste::metrics {
namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

Image make_image(int w, int h, int c, std::initializer_list<float> values)
{
    Image img(w, h, c);
    EXPECT_EQ(values.size(), img.value_count());
    std::copy(values.begin(), values.end(), img.data());
    return img;
}

// a = 0 everywhere; b differs by 0.1, 0.5 (x2, a tie), 0.2 (x2). 3x2 pixels, 2 channels.
Image tiny_b()
{
    return make_image(3,
                      2,
                      2,
                      {0.1f,
                       0.0f,
                       0.0f,
                       0.0f,
                       0.0f,
                       -0.5f,  //
                       0.5f,
                       0.0f,
                       0.2f,
                       0.2f,
                       0.0f,
                       0.0f});
}

TEST(Metrics, HandComputedSmallImage)
{
    const Image a(3, 2, 2);
    const Image b = tiny_b();
    Thresholds t;
    t.warn = 0.15f;
    t.fail = 0.3f;
    const CompareStats s = compare(a, b, t);
    // Errors 0.1 + 0.5 + 0.5 + 0.2 + 0.2 = 1.5 over 12 values; squares sum to 0.59.
    EXPECT_NEAR(s.all.mean_error, 1.5 / 12.0, 1e-8);
    EXPECT_NEAR(s.all.rms_error, std::sqrt(0.59 / 12.0), 1e-8);
    EXPECT_NEAR(s.all.rms_error, 0.2217355, 1e-6);
    EXPECT_NEAR(s.all.psnr, 13.08329, 1e-4);  // 20 log10(1 / 0.2217355), peak 1
    EXPECT_EQ(s.all.peak, 1.0);
    // Tie at 0.5 between (2, 0, ch 1) and (0, 1, ch 0): the first in scan order wins.
    EXPECT_EQ(s.all.max_error, 0.5);
    EXPECT_EQ(s.all.max_x, 2);
    EXPECT_EQ(s.all.max_y, 0);
    EXPECT_EQ(s.all.max_channel, 1);
    // Over 0.15: pixels (2,0), (0,1), (1,1) (the last once, though both channels are over).
    EXPECT_EQ(s.all.warn_count, 3u);
    EXPECT_EQ(s.all.fail_count, 2u);
    EXPECT_EQ(s.pixel_count, 6u);
    EXPECT_NEAR(s.warn_percent(), 50.0, 1e-12);
    EXPECT_NEAR(s.fail_percent(), 100.0 / 3.0, 1e-12);

    ASSERT_EQ(s.channels.size(), 2u);
    EXPECT_NEAR(s.channels[0].mean_error, 0.8 / 6.0, 1e-8);
    EXPECT_NEAR(s.channels[0].rms_error, std::sqrt(0.30 / 6.0), 1e-8);
    EXPECT_EQ(s.channels[0].max_error, 0.5);
    EXPECT_EQ(s.channels[0].max_x, 0);
    EXPECT_EQ(s.channels[0].max_y, 1);
    EXPECT_EQ(s.channels[0].warn_count, 2u);
    EXPECT_EQ(s.channels[0].fail_count, 1u);
    EXPECT_NEAR(s.channels[1].mean_error, 0.7 / 6.0, 1e-8);
    EXPECT_EQ(s.channels[1].max_x, 2);
    EXPECT_EQ(s.channels[1].max_y, 0);
    EXPECT_EQ(s.channels[1].fail_count, 1u);
}

TEST(Metrics, IdenticalImagesAndPeak)
{
    const Image a = make_image(2, 1, 1, {-5.0f, 2.0f});
    CompareStats s = compare(a, a);
    EXPECT_EQ(s.all.mean_error, 0.0);
    EXPECT_EQ(s.all.rms_error, 0.0);
    EXPECT_TRUE(std::isinf(s.all.psnr));
    EXPECT_EQ(s.all.max_error, 0.0);
    EXPECT_EQ(verdict(s, {}), Verdict::Pass);

    // Peak is the largest |value| (5 here), not 1: psnr = 20 log10(5 / rms).
    const Image b = make_image(2, 1, 1, {-4.0f, 2.0f});
    s = compare(a, b);
    EXPECT_EQ(s.all.peak, 5.0);
    EXPECT_NEAR(s.all.rms_error, std::sqrt(0.5), 1e-12);
    EXPECT_NEAR(s.all.psnr, 20.0 * std::log10(5.0 / std::sqrt(0.5)), 1e-9);
}

TEST(Metrics, NonFiniteMismatchesFail)
{
    // NaN vs NaN and +inf vs +inf match; NaN vs a number, and +inf vs -inf, are errors of +inf
    // that fail (idiff counted none of them but the first's max: a frame of NaNs passed). The
    // mean and RMS become +inf; the max is the first mismatch in scan order.
    const Image a = make_image(3, 2, 1, {kNaN, 1.0f, kInf, kInf, 0.0f, 2.0f});
    const Image b = make_image(3, 2, 1, {kNaN, kNaN, kInf, -kInf, 0.25f, 2.0f});
    const CompareStats s = compare(a, b);
    EXPECT_TRUE(std::isinf(s.all.max_error));
    EXPECT_EQ(s.all.max_x, 1);
    EXPECT_EQ(s.all.max_y, 0);
    EXPECT_EQ(s.all.fail_count, 3u);  // (1, 0), (0, 1), (1, 1)
    EXPECT_EQ(s.all.warn_count, 3u);
    EXPECT_TRUE(std::isinf(s.all.mean_error) && std::isinf(s.all.rms_error));
    EXPECT_EQ(verdict(s, {}), Verdict::Failure);
    // One NaN pixel in a large frame fails the golden tests' thresholds too (its error is over
    // any hard limit), and its place does not depend on the tiles' order.
    Image big(300, 200, 4), other(300, 200, 4);
    big.fill(0.5f);
    other.fill(0.5f);
    other.at(250, 150, 2) = kNaN;
    other.at(290, 190, 0) = kNaN;
    Thresholds golden;
    golden.fail = 0.004f;
    golden.fail_percent = 0.02f;
    golden.hard_fail = 0.012f;
    const CompareStats g = compare(big, other, golden);
    EXPECT_EQ(g.all.fail_count, 2u);
    EXPECT_EQ(g.all.max_x, 250);
    EXPECT_EQ(g.all.max_y, 150);
    EXPECT_EQ(g.all.max_channel, 2);
    EXPECT_EQ(verdict(g, golden), Verdict::Failure);
    // Matching NaNs and infinities alone pass.
    Image same = big;
    same.at(3, 3, 0) = kNaN;
    same.at(4, 4, 1) = -kInf;
    EXPECT_EQ(verdict(compare(same, same), {}), Verdict::Pass);
}

TEST(Metrics, VerdictRulesMatchIdiffOptions)
{
    const CompareStats s = compare(Image(3, 2, 2), tiny_b(), [] {
        Thresholds t;
        t.warn = 0.15f;
        t.fail = 0.3f;
        return t;
    }());
    // 2 of 6 pixels fail, 3 warn, max error 0.5 (each case checked against idiff 2.4.7).
    Thresholds t;
    EXPECT_EQ(verdict(s, t), Verdict::Failure);
    t.fail_percent = 50.0f;  // 2 <= 3 allowed: not a failure, but 3 > 0 warnings
    EXPECT_EQ(verdict(s, t), Verdict::Warning);
    t.warn_percent = 50.0f;  // 3 <= 3 allowed
    EXPECT_EQ(verdict(s, t), Verdict::Pass);
    t.hard_warn = 0.5f;  // max error 0.5 is not above 0.5
    EXPECT_EQ(verdict(s, t), Verdict::Pass);
    t.hard_warn = 0.49f;
    EXPECT_EQ(verdict(s, t), Verdict::Warning);
    t.hard_fail = 0.49f;
    EXPECT_EQ(verdict(s, t), Verdict::Failure);
    t.allow_failures = 2;  // at most 2 failing pixels: pass outright
    EXPECT_EQ(verdict(s, t), Verdict::Pass);
    t.allow_failures = 1;
    EXPECT_EQ(verdict(s, t), Verdict::Failure);
    EXPECT_EQ(exit_code(Verdict::SizeMismatch), 3);
    EXPECT_EQ(worse(Verdict::Warning, Verdict::Failure), Verdict::Failure);
    EXPECT_STREQ(verdict_name(Verdict::Warning), "WARNING");
}

TEST(Metrics, RelativeThresholds)
{
    // |a-b| = 0.1 against mean |a|,|b| of 10.05 (1%) and 0.15 (67%).
    const Image a = make_image(2, 1, 1, {10.0f, 0.1f});
    const Image b = make_image(2, 1, 1, {10.1f, 0.2f});
    Thresholds t;
    t.fail = 0.05f;
    t.fail_relative = 0.1f;
    EXPECT_EQ(compare(a, b, t).all.fail_count, 1u);
}

TEST(Metrics, ShapeMismatchThrows)
{
    EXPECT_THROW(compare(Image(3, 2, 1), Image(2, 3, 1)), Error);
    EXPECT_THROW(compare(Image(3, 2, 1), Image(3, 2, 2)), Error);
}

// compare_surface over the pixels with a finite depth; none left is an error (a zeroed pixel
// stood in for none, scoring RMSE 0).
TEST(Metrics, SurfaceComparisonLeavesTheSkyOutAndNeedsAPixel)
{
    Image a(2, 1, 1), b(2, 1, 1), depth(2, 1, 1);
    a.at(0, 0, 0) = 1.0f;
    b.at(0, 0, 0) = 0.5f;
    a.at(1, 0, 0) = 9.0f;  // under the sky: left out
    depth.at(0, 0, 0) = 2.0f;
    depth.at(1, 0, 0) = std::numeric_limits<float>::infinity();
    EXPECT_DOUBLE_EQ(metrics::compare_surface(a, b, depth).all.rms_error, 0.5);
    depth.at(0, 0, 0) = std::numeric_limits<float>::infinity();
    EXPECT_THROW(metrics::compare_surface(a, b, depth), Error);
}

TEST(Metrics, TiesAcrossTilesPickScanOrderAndThreadsAgree)
{
    // (100, 0) lies in tile 1, (5, 10) in tile 0; scan order puts (100, 0) first.
    Image a(130, 70, 3), b(130, 70, 3);
    for (int y = 0; y < 70; ++y) {
        for (int x = 0; x < 130; ++x) {
            for (int c = 0; c < 3; ++c) {
                a.at(x, y, c) = hash_unit(x, y, c, 1);
                b.at(x, y, c) = a.at(x, y, c) + 0.01f * (hash_unit(x, y, c, 2) - 0.5f);
            }
        }
    }
    b.at(5, 10, 2) = a.at(5, 10, 2) + 0.75f;
    b.at(100, 0, 1) = a.at(100, 0, 1) + 0.75f;
    a.at(5, 10, 2) = a.at(100, 0, 1) = 0.125f;  // make the two errors bit-identical
    b.at(5, 10, 2) = b.at(100, 0, 1) = 0.875f;

    set_thread_count(1);
    const CompareStats one = compare(a, b);
    set_thread_count(2);
    const CompareStats two = compare(a, b);
    set_thread_count(0);
    EXPECT_EQ(one.all.max_x, 100);
    EXPECT_EQ(one.all.max_y, 0);
    EXPECT_EQ(one.all.max_channel, 1);
    EXPECT_EQ(one.all.mean_error, two.all.mean_error);  // bit-identical
    EXPECT_EQ(one.all.rms_error, two.all.rms_error);
    EXPECT_EQ(one.all.max_x, two.all.max_x);
    EXPECT_EQ(one.channels[2].max_x, 5);
    EXPECT_EQ(one.channels[2].max_y, 10);
}

TEST(Metrics, DifferenceImageScales)
{
    const Image d = difference_image(Image(3, 2, 2), tiny_b(), 16.0f);
    EXPECT_FLOAT_EQ(d.at(2, 0, 1), 8.0f);
    EXPECT_FLOAT_EQ(d.at(0, 0, 0), 1.6f);
    EXPECT_EQ(d.at(1, 0, 0), 0.0f);
    // Non-finite values as compare counts them: NaN against NaN and inf against inf are 0,
    // anything else against a NaN or an infinity is infinite; a zero difference stays 0 under
    // an infinite scale.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    Image a(5, 1, 1), b(5, 1, 1);
    const float va[] = {nan, inf, nan, inf, 2.0f}, vb[] = {nan, inf, 1.0f, -inf, 2.0f};
    for (int x = 0; x < 5; ++x) {
        a.at(x, 0, 0) = va[x];
        b.at(x, 0, 0) = vb[x];
    }
    const Image e = difference_image(a, b, 1.0f);
    const float want[] = {0.0f, 0.0f, inf, inf, 0.0f};
    for (int x = 0; x < 5; ++x) {
        EXPECT_EQ(e.at(x, 0, 0), want[x]) << x;
    }
    EXPECT_EQ(difference_image(a, b, inf).at(4, 0, 0), 0.0f);
    EXPECT_EQ(difference_image(a, b, 0.0f).at(2, 0, 0), 0.0f);
}

// --- Agreement with OpenImageIO's idiff and ImageBufAlgo::compare ---------------------------

std::string find_on_path(const std::string &name)
{
    const char *path = std::getenv("PATH");
    std::stringstream ss(path ? path : "");
    std::string dir;
    while (std::getline(ss, dir, ':')) {
        const std::filesystem::path p = std::filesystem::path(dir) / name;
        if (!dir.empty() && std::filesystem::exists(p)) {
            return p.string();
        }
    }
    return {};
}

void write_exr(const std::string &path, const Image &img)
{
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out) << OIIO::geterror();
    const OIIO::ImageSpec spec(img.width(), img.height(), img.channels(), OIIO::TypeDesc::FLOAT);
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, img.data())) << out->geterror();
    ASSERT_TRUE(out->close()) << out->geterror();
}

struct IdiffRun {
    int exit_code = -1;
    std::string output;
};

IdiffRun run_idiff(const std::string &idiff, const std::string &args)
{
    IdiffRun run;
    FILE *pipe = popen((idiff + " -v " + args + " 2>&1").c_str(), "r");
    if (!pipe) {
        return run;
    }
    char buf[512];
    while (std::fgets(buf, sizeof(buf), pipe)) {
        run.output += buf;
    }
    const int status = pclose(pipe);
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return run;
}

/// A value as idiff prints it (ostream defaults: 6 significant digits; "nan", "inf").
std::string printed(double v)
{
    if (std::isnan(v)) {
        return "nan";
    }
    if (std::isinf(v)) {
        return "inf";
    }
    std::ostringstream os;
    os << v;
    return os.str();
}

std::string match1(const std::string &text, const std::string &pattern)
{
    std::smatch m;
    const std::regex re(pattern);
    return std::regex_search(text, m, re) ? m[1].str() : std::string("<missing>");
}

class DiffIdiffAgreement : public ::testing::Test {
   protected:
    void SetUp() override
    {
        idiff_ = find_on_path("idiff");
        if (idiff_.empty()) {
            GTEST_SKIP() << "idiff (openimageio-tools) is not on PATH";
        }
        dir_ = std::filesystem::temp_directory_path() /
               ("posthaste_idiff_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir_);
    }
    void TearDown() override
    {
        if (!dir_.empty()) {
            std::filesystem::remove_all(dir_);
        }
    }

    /// Write a and b, run idiff and ImageBufAlgo::compare, and check ours against both.
    void check_pair(const std::string &name,
                    const Image &a,
                    const Image &b,
                    const Thresholds &t,
                    const std::string &options)
    {
        SCOPED_TRACE(name + " " + options);
        const std::string pa = (dir_ / (name + "_a.exr")).string();
        const std::string pb = (dir_ / (name + "_b.exr")).string();
        write_exr(pa, a);
        write_exr(pb, b);
        const CompareStats s = compare(a, b, t);
        const IdiffRun run = run_idiff(idiff_, options + " " + pa + " " + pb);
        ASSERT_NE(run.exit_code, -1) << run.output;

        // idiff prints 6 significant digits (below the 1e-6 relative asked for), so its text
        // is matched exactly; full precision is checked against ImageBufAlgo::compare below.
        EXPECT_EQ(match1(run.output, R"(Mean error = (\S+))"), printed(s.all.mean_error));
        EXPECT_EQ(match1(run.output, R"(RMS error = (\S+))"), printed(s.all.rms_error));
        EXPECT_EQ(match1(run.output, R"(Peak SNR = (\S+))"), printed(s.all.psnr));
        EXPECT_EQ(match1(run.output, R"(Max error  = (\S+))"), printed(s.all.max_error));
        if (s.all.max_error != 0.0) {
            EXPECT_EQ(match1(run.output, R"(@ \((\d+, \d+))"),
                      std::to_string(s.all.max_x) + ", " + std::to_string(s.all.max_y));
            const char *names[] = {"R", "G", "B", "A"};
            EXPECT_EQ(match1(run.output, R"(@ \(\d+, \d+, (\w+)\))"), names[s.all.max_channel]);
        }
        EXPECT_EQ(match1(run.output, R"((\d+) pixels \([^)]*\) over \S+\n)"),
                  std::to_string(s.all.warn_count));
        EXPECT_EQ(match1(run.output, R"(\d+ pixels \([^)]*\) over \S+\n\s+(\d+) pixels)"),
                  std::to_string(s.all.fail_count));
        EXPECT_EQ(run.exit_code, exit_code(verdict(s, t))) << run.output;

        OIIO::ImageBuf ia(pa), ib(pb);
        const auto cr =
            OIIO::ImageBufAlgo::compare(ia, ib, t.fail, t.warn, t.fail_relative, t.warn_relative);
        expect_rel(s.all.mean_error, cr.meanerror);
        expect_rel(s.all.rms_error, cr.rms_error);
        expect_rel(s.all.psnr, cr.PSNR);
        expect_rel(s.all.max_error, cr.maxerror);
        EXPECT_EQ(s.all.max_x, cr.maxx);
        EXPECT_EQ(s.all.max_y, cr.maxy);
        EXPECT_EQ(s.all.max_channel, cr.maxc);
        EXPECT_EQ(s.all.warn_count, cr.nwarn);
        EXPECT_EQ(s.all.fail_count, cr.nfail);
    }

    static void expect_rel(double ours, double theirs)
    {
        if (!std::isfinite(ours) || !std::isfinite(theirs)) {
            EXPECT_EQ(printed(ours), printed(theirs));
            return;
        }
        EXPECT_LE(std::abs(ours - theirs), 1e-6 * std::abs(theirs) + 1e-300)
            << ours << " vs " << theirs;
    }

    std::string idiff_;
    std::filesystem::path dir_;
};

Image noise_image(int w, int h, int c, std::uint32_t seed, float lo, float hi)
{
    Image img(w, h, c);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int k = 0; k < c; ++k) {
                img.at(x, y, k) = lo + (hi - lo) * hash_unit(x, y, k, seed);
            }
        }
    }
    return img;
}

TEST_F(DiffIdiffAgreement, SmallPerturbationLdr)
{
    const Image a = noise_image(17, 11, 3, 7, 0.0f, 1.0f);
    Image b = a;
    for (int y = 0; y < 11; ++y) {
        for (int x = 0; x < 17; ++x) {
            b.at(x, y, (x + y) % 3) += 0.02f * (hash_unit(x, y, 0, 9) - 0.5f);
        }
    }
    b.at(3, 9, 1) += 0.3f;
    check_pair("ldr", a, b, {}, "");
    Thresholds t;
    t.fail = 0.05f;
    t.warn = 0.005f;
    t.fail_percent = 1.0f;
    check_pair("ldr", a, b, t, "-fail 0.05 -warn 0.005 -failpercent 1");
    t.warn_percent = 90.0f;
    check_pair("ldr", a, b, t, "-fail 0.05 -warn 0.005 -failpercent 1 -warnpercent 90");
    t.hard_fail = 0.2f;
    check_pair(
        "ldr", a, b, t, "-fail 0.05 -warn 0.005 -failpercent 1 -warnpercent 90 -hardfail 0.2");
}

TEST_F(DiffIdiffAgreement, HdrWithNegativesAndAlpha)
{
    const Image a = noise_image(8, 6, 4, 11, -3.0f, 40.0f);
    Image b = noise_image(8, 6, 4, 12, -3.0f, 40.0f);
    b.at(2, 2, 3) = a.at(2, 2, 3);  // some exact matches
    Thresholds t;
    t.fail = 10.0f;
    t.warn = 1.0f;
    t.fail_relative = 0.5f;
    check_pair("hdr", a, b, t, "-fail 10 -warn 1 -failrelative 0.5");
    check_pair("hdr", a, b, {}, "");
}

TEST_F(DiffIdiffAgreement, ManyTilesWithTiedMaxima)
{
    // 150x90 spans six 64-pixel tiles; equal maxima in tiles 0 and 1 test the merge order.
    const Image a = noise_image(150, 90, 3, 31, 0.0f, 1.0f);
    Image b = a;
    for (int y = 0; y < 90; ++y) {
        for (int x = 0; x < 150; ++x) {
            b.at(x, y, 1) += 0.001f * float((x * 7 + y * 3) % 11);
        }
    }
    Image a2 = a;
    a2.at(5, 10, 2) = a2.at(100, 0, 0) = 0.25f;
    b.at(5, 10, 2) = b.at(100, 0, 0) = 0.75f;
    Thresholds t;
    t.fail = 0.008f;
    t.warn = 0.004f;
    t.fail_percent = 10.0f;
    check_pair("tiles", a2, b, t, "-fail 0.008 -warn 0.004 -failpercent 10");
}

// Non-finite values are where diff departs from idiff (Metrics.NonFiniteMismatchesFail): a
// matching NaN still agrees with idiff bit for bit.
TEST_F(DiffIdiffAgreement, MatchingNaNs)
{
    Image a = noise_image(5, 4, 3, 21, 0.0f, 2.0f);
    Image b = a;
    a.at(0, 0, 0) = b.at(0, 0, 0) = kNaN;
    a.at(1, 0, 1) = b.at(1, 0, 1) = kInf;
    b.at(3, 2, 2) += 0.5f;
    check_pair("nonfinite_matching", a, b, {}, "");
}

}  // namespace
}  // namespace posthaste::metrics
