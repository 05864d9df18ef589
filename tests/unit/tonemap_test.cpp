// Tone curves against their formulas computed here, their shape (monotonic, 0 to 0, bounded by
// 1, the white point to 1), the luminance mode keeping RGB ratios, alpha and non-finite pixels.

#include <gtest/gtest.h>

#include <cmath>

#include "test_util.h"

namespace posthaste {
namespace {

Frame ramp_frame(const std::vector<float> &values)
{
    const int n = int(values.size());
    Frame f;
    f.set_size(n, 1);
    Image img(n, 1, 4);
    for (int i = 0; i < n; ++i) {
        img.at(i, 0, 0) = values[std::size_t(i)];
        img.at(i, 0, 1) = values[std::size_t(i)];
        img.at(i, 0, 2) = values[std::size_t(i)];
        img.at(i, 0, 3) = 1.0f;
    }
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    return f;
}

const std::vector<float> kRamp = {
    0.0f, 0.001f, 0.01f, 0.05f, 0.18f, 0.5f, 1.0f, 2.0f, 4.0f, 11.2f, 100.0f, 1e4f};

double hable(double x)
{
    const double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}

TEST(Tonemap, CurvesEqualTheirFormulas)
{
    const Frame in = ramp_frame(kRamp);
    const Frame r = test::run_node("tonemap", in, R"({"curve": "reinhard", "white": 4})");
    const Frame h = test::run_node("tonemap", in, R"({"curve": "hable", "white": 11.2})");
    const Frame a = test::run_node("tonemap", in, R"({"curve": "aces"})");
    for (std::size_t i = 0; i < kRamp.size(); ++i) {
        const double x = kRamp[i];
        // Beyond their white points both clip to 1.
        EXPECT_NEAR(
            r.image("color").at(int(i), 0, 1), std::min(1.0, x * (1 + x / 16.0) / (1 + x)), 1e-6);
        EXPECT_NEAR(
            h.image("color").at(int(i), 0, 1), std::min(1.0, hable(2 * x) / hable(11.2)), 1e-6);
        EXPECT_NEAR(a.image("color").at(int(i), 0, 1),
                    std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0),
                    1e-6);
    }
    EXPECT_NEAR(r.image("color").at(8, 0, 0), 1.0, 1e-6);  // reinhard: white (4) -> 1
    // hable: Hable's exposure bias of 2 puts his white W = 11.2 at an input of 5.6.
    EXPECT_NEAR(h.image("color").at(9, 0, 0), 1.0, 1e-6);
    EXPECT_LT(h.image("color").at(8, 0, 0), 1.0);
}

TEST(Tonemap, EveryCurveIsMonotonicAndBounded)
{
    std::vector<float> ramp;
    for (int i = 0; i <= 400; ++i) {
        ramp.push_back(float(std::exp2(-14.0 + i * 0.05)));  // 2^-14 .. 2^6
    }
    for (const char *curve : {"reinhard", "hable", "aces", "agx"}) {
        SCOPED_TRACE(curve);
        const Frame out_frame = test::run_node(
            "tonemap", ramp_frame(ramp), std::string(R"({"curve": ")") + curve + "\"}");
        const Image &o = out_frame.image("color");
        for (int i = 1; i < o.width(); ++i) {
            ASSERT_GE(o.at(i, 0, 1), o.at(i - 1, 0, 1)) << i;
        }
        EXPECT_GE(o.at(0, 0, 1), 0.0f);
        EXPECT_LE(o.at(o.width() - 1, 0, 1), 1.0f + 1e-6f);
        EXPECT_LT(o.at(0, 0, 1), 0.01f);             // deep shadow stays dark
        EXPECT_GT(o.at(o.width() - 1, 0, 1), 0.8f);  // 64x middle grey is near white
    }
}

TEST(Tonemap, LuminanceModeKeepsRatiosAndAlpha)
{
    Frame f;
    f.set_size(1, 1);
    Image img(1, 1, 4);
    const float px[4] = {0.4f, 0.2f, 0.1f, 0.5f};  // premultiplied by alpha 0.5
    std::copy(px, px + 4, img.pixel(0, 0));
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    const Frame out_frame =
        test::run_node("tonemap", f, R"({"curve": "reinhard", "mode": "luminance"})");
    const Image &o = out_frame.image("color");
    EXPECT_NEAR(o.at(0, 0, 0) / o.at(0, 0, 1), 2.0, 1e-5);
    EXPECT_NEAR(o.at(0, 0, 2) / o.at(0, 0, 1), 0.5, 1e-5);
    EXPECT_EQ(o.at(0, 0, 3), 0.5f);
    // Unpremultiplied luminance of (0.8, 0.4, 0.2) through Reinhard (white 4), premultiplied back.
    const double lum = 0.2126 * 0.8 + 0.7152 * 0.4 + 0.0722 * 0.2;
    const double k = lum * (1 + lum / 16.0) / (1 + lum) / lum;
    EXPECT_NEAR(o.at(0, 0, 1), 0.4 * k * 0.5, 1e-6);
}

// ACES and Hable squared their input: from about 1e19 up inf / inf made NaN, and the clamp
// turned the brightest finite values black. They stay at 1, in luminance mode too.
TEST(Tonemap, TheBrightestFiniteValuesStayWhite)
{
    const std::vector<float> huge = {1e3f, 1e10f, 1e18f, 1e19f, 3e19f, 1e20f, 1e30f, 3e38f};
    for (const char *curve : {"aces", "hable", "reinhard"}) {
        SCOPED_TRACE(curve);
        const Frame o = test::run_node(
            "tonemap", ramp_frame(huge), std::string(R"({"curve": ")") + curve + "\"}");
        for (int i = 0; i < int(huge.size()); ++i) {
            EXPECT_EQ(o.image("color").at(i, 0, 0), 1.0f) << huge[std::size_t(i)];
        }
    }
    Frame f;
    f.set_size(1, 1);
    Image img(1, 1, 4);
    const float px[4] = {1e30f, 0.5f, 0.5f, 1.0f};
    std::copy(px, px + 4, img.pixel(0, 0));
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    const Frame o = test::run_node("tonemap", f, R"({"curve": "aces", "mode": "luminance"})");
    // The luminance maps to 1 and the channels keep their ratios to it.
    const double lum = 0.2126 * 1e30 + 0.7152 * 0.5 + 0.0722 * 0.5;
    EXPECT_NEAR(o.image("color").at(0, 0, 0), 1e30 / lum, 1e-5);
    EXPECT_GT(o.image("color").at(0, 0, 0), 4.0f);
}

TEST(Tonemap, NonFinitePixelsStay)
{
    Frame f = ramp_frame({1.0f, std::numeric_limits<float>::quiet_NaN(), 2.0f});
    const Frame out_frame = test::run_node("tonemap", f, "{}");
    const Image &o = out_frame.image("color");
    EXPECT_TRUE(std::isnan(o.at(1, 0, 0)));
    EXPECT_TRUE(std::isfinite(o.at(0, 0, 0)));
}

}  // namespace
}  // namespace posthaste
