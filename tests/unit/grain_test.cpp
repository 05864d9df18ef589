// Film grain: the statistics of the grain on uniform frames (zero mean, the requested standard
// deviation in stops, the Gaussian autocorrelation of its size, white below 0.3 px, the midtone
// response), one field for mono and independent fields for color, determinism per frame, seed
// and thread count, grain fixed to file coordinates across data windows, non-finite values kept.

#include "filter/grain.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/parallel.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame grey_frame(int w, int h, float value)
{
    Image img(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float v[4] = {value, value, value, 1.0f};
            std::copy(v, v + 4, img.pixel(x, y));
        }
    }
    Frame f;
    f.number = 1;
    f.set_size(w, h);
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    return f;
}

/// The grain in stops: log2((out + offset) / (in + offset)) per pixel, channel c.
std::vector<double> stops(const Image &out, float in, int c, double offset = 1.0 / 256.0)
{
    std::vector<double> s;
    for (int y = 0; y < out.height(); ++y) {
        for (int x = 0; x < out.width(); ++x) {
            s.push_back(std::log2((out.at(x, y, c) + offset) / (in + offset)));
        }
    }
    return s;
}

double mean(const std::vector<double> &v)
{
    double s = 0.0;
    for (double x : v) {
        s += x;
    }
    return s / double(v.size());
}

double stddev(const std::vector<double> &v)
{
    const double m = mean(v);
    double s = 0.0;
    for (double x : v) {
        s += (x - m) * (x - m);
    }
    return std::sqrt(s / double(v.size()));
}

/// Correlation of a and b (same length).
double correlation(const std::vector<double> &a, const std::vector<double> &b)
{
    const double ma = mean(a), mb = mean(b);
    double ab = 0.0, aa = 0.0, bb = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        ab += (a[i] - ma) * (b[i] - mb);
        aa += (a[i] - ma) * (a[i] - ma);
        bb += (b[i] - mb) * (b[i] - mb);
    }
    return ab / std::sqrt(aa * bb);
}

/// Horizontal autocorrelation at lag d of a w-wide image stored row by row.
double autocorrelation(const std::vector<double> &v, int w, int d)
{
    std::vector<double> a, b;
    for (std::size_t i = 0; i + std::size_t(d) < v.size(); ++i) {
        if (int(i % std::size_t(w)) + d < w) {
            a.push_back(v[i]);
            b.push_back(v[i + std::size_t(d)]);
        }
    }
    return correlation(a, b);
}

TEST(Grain, StatisticsOnMiddleGrey)
{
    // At L = 0.18 the midtone weight is exactly 1: the grain is intensity stops of a unit field.
    const Frame out =
        test::run_node("grain", grey_frame(384, 384, 0.18f), R"({"intensity": 0.2, "size": 1.5})");
    const std::vector<double> g = stops(out.image("color"), 0.18f, 1);
    EXPECT_NEAR(mean(g), 0.0, 0.01);
    EXPECT_NEAR(stddev(g), 0.2, 0.2 * 0.04);
    // A unit field blurred by a Gaussian of sigma s correlates as exp(-d^2 / (4 s^2)).
    for (int d : {1, 2, 3}) {
        EXPECT_NEAR(autocorrelation(g, 384, d), std::exp(-d * d / (4.0 * 1.5 * 1.5)), 0.03)
            << "lag " << d;
    }
    const Frame white =
        test::run_node("grain", grey_frame(256, 256, 0.18f), R"({"intensity": 0.2, "size": 0})");
    EXPECT_NEAR(autocorrelation(stops(white.image("color"), 0.18f, 0), 256, 1), 0.0, 0.02);
    EXPECT_NEAR(stddev(stops(white.image("color"), 0.18f, 0)), 0.2, 0.2 * 0.04);
}

TEST(Grain, MidtoneResponse)
{
    // Bright: u = 50 / 50.18, the weight 1 - r + 4 r u (1 - u).
    const double r = 0.8, u = 50.0 / 50.18;
    const Frame out = test::run_node(
        "grain", grey_frame(256, 256, 50.0f), R"({"intensity": 0.3, "response": 0.8})");
    EXPECT_NEAR(stddev(stops(out.image("color"), 50.0f, 0)),
                0.3 * (1.0 - r + 4.0 * r * u * (1.0 - u)),
                0.3 * 0.25 * 0.05);
}

TEST(Grain, MonoSharesOneFieldColorHasThree)
{
    const Frame mono = test::run_node("grain", grey_frame(128, 128, 0.18f), "{}");
    EXPECT_NEAR(
        correlation(stops(mono.image("color"), 0.18f, 0), stops(mono.image("color"), 0.18f, 2)),
        1.0,
        1e-4);
    const Frame color =
        test::run_node("grain", grey_frame(256, 256, 0.18f), R"({"mode": "color", "size": 0.5})");
    EXPECT_NEAR(
        correlation(stops(color.image("color"), 0.18f, 0), stops(color.image("color"), 0.18f, 1)),
        0.0,
        0.03);
    EXPECT_EQ(color.image("color").at(7, 7, 3), 1.0f);  // alpha untouched
}

TEST(Grain, DeterministicPerFrameAndSeed)
{
    const Frame in = grey_frame(200, 120, 0.3f);
    const Frame a = test::run_node("grain", in, "{}", 5);
    set_thread_count(1);
    const Frame b = test::run_node("grain", in, "{}", 5);
    set_thread_count(0);
    EXPECT_TRUE(a.image("color").bit_equal(b.image("color")));
    const Frame next = test::run_node("grain", in, "{}", 6);
    const Frame seeded = test::run_node("grain", in, R"({"seed": 7})", 5);
    const auto ga = stops(a.image("color"), 0.3f, 0);
    EXPECT_NEAR(correlation(ga, stops(next.image("color"), 0.3f, 0)), 0.0, 0.05);
    EXPECT_NEAR(correlation(ga, stops(seeded.image("color"), 0.3f, 0)), 0.0, 0.05);
    const Frame none = test::run_node("grain", in, R"({"intensity": 0})");
    EXPECT_EQ(&none.image("color"), &in.image("color"));
}

TEST(Grain, FixedToFileCoordinates)
{
    // The same pixels in a data window moved to (5, 3) get the same grain.
    filter::GrainParams p;
    const filter::GrainField whole = filter::grain_field(40, 30, 0, 0, 2, p);
    const filter::GrainField part = filter::grain_field(21, 10, 5, 3, 2, p);
    for (int y = 0; y < 10; ++y) {
        for (int x = 0; x < 21; ++x) {
            ASSERT_EQ(part.at(0, x, y), whole.at(0, x + 5, y + 3)) << x << " " << y;
        }
    }
}

TEST(Grain, NonFiniteValuesStay)
{
    Frame in = grey_frame(16, 16, 0.5f);
    Image img = in.image("color");
    img.at(2, 2, 0) = std::numeric_limits<float>::quiet_NaN();
    img.at(3, 3, 1) = std::numeric_limits<float>::infinity();
    in.set("color", std::make_shared<const Image>(img), {"R", "G", "B", "A"});
    const Frame out_frame = test::run_node("grain", in, "{}");
    const Image &o = out_frame.image("color");
    EXPECT_TRUE(std::isnan(o.at(2, 2, 0)));
    EXPECT_TRUE(std::isinf(o.at(3, 3, 1)));
    EXPECT_TRUE(std::isfinite(o.at(3, 3, 0)));
    EXPECT_TRUE(std::isfinite(o.at(2, 2, 1)));
}

}  // namespace
}  // namespace posthaste
