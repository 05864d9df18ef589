// A depth pass through transform, reformat and lens with a reconstruction filter: the sky (+inf)
// stays the sky exactly where the nearest input pixel is sky, no NaN or -inf appears, no depth
// overshoots the range of its neighbourhood, and away from edges the filter still interpolates.

#include "filter/depth_resample.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>

#include "test_util.h"

namespace posthaste {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

TEST(DepthResample, RangeIsTheBoxMinimumAndMaximumOfTheFiniteValues)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Image d(23, 17, 1);
    for (int y = 0; y < 17; ++y) {
        for (int x = 0; x < 23; ++x) {
            const float r = u(rng);
            d.at(x, y, 0) = r < 0.1f ? kInf : r < 0.15f ? std::nanf("") : 100.0f * u(rng);
        }
    }
    for (int radius : {0, 1, 2, 5, 40}) {
        const Image range = filter::depth_range(d, radius);
        for (int y = 0; y < 17; ++y) {
            for (int x = 0; x < 23; ++x) {
                float lo = kInf, hi = -kInf;
                for (int j = std::max(0, y - radius); j <= std::min(16, y + radius); ++j) {
                    for (int i = std::max(0, x - radius); i <= std::min(22, x + radius); ++i) {
                        const float v = d.at(i, j, 0);
                        if (std::isfinite(v)) {
                            lo = std::min(lo, v);
                            hi = std::max(hi, v);
                        }
                    }
                }
                ASSERT_EQ(range.at(x, y, 0), lo) << radius << " " << x << " " << y;
                ASSERT_EQ(range.at(x, y, 1), hi) << radius << " " << x << " " << y;
            }
        }
    }
}

TEST(DepthResample, GuardTakesTheNearestOnTheSkyAndClampsOvershoot)
{
    // 4x1: 5, 5, 50, sky; one channel.
    Image d(4, 1, 1);
    d.at(0, 0, 0) = 5.0f;
    d.at(1, 0, 0) = 5.0f;
    d.at(2, 0, 0) = 50.0f;
    d.at(3, 0, 0) = kInf;
    const Image split = filter::sky_split(d);
    ASSERT_EQ(split.channels(), 2);
    EXPECT_EQ(split.at(3, 0, 0), 0.0f);
    EXPECT_EQ(split.at(3, 0, 1), 1.0f);
    EXPECT_EQ(split.at(2, 0, 1), 0.0f);
    const Image range = filter::depth_range(d, 1);
    const std::int32_t nearest[] = {0, 1, 2, 3, -1, 2};
    // (filtered depth, sky indicator's sum) per output pixel.
    const float filtered[] = {
        -3.0f, 0.0f, 7.0f, 0.0f, 9.0f, 0.25f, 60.0f, 0.0f, 5.0f, 0.0f, 9.0f, std::nanf("")};
    float row[6];
    filter::guard_depth_row(d, range, nearest, 6, filtered, row);
    EXPECT_EQ(row[0], 5.0f);   // undershoot clamped to the neighbourhood's 5
    EXPECT_EQ(row[1], 7.0f);   // within [5, 50]: kept
    EXPECT_EQ(row[2], 50.0f);  // a tap on the sky: the nearest pixel
    EXPECT_EQ(row[3], kInf);   // the nearest pixel is sky: the sky
    EXPECT_EQ(row[4], kInf);   // outside the input: the sky
    EXPECT_EQ(row[5], 50.0f);  // a tap outside the input (NaN): the nearest pixel
}

/// 64x48: a depth ramp (10 + 0.05 x) with a near box (depth 2) and the sky above row 12.
Frame edge_frame()
{
    Frame f;
    f.set_size(64, 48);
    Image color(64, 48, 3), depth(64, 48, 1);
    for (int y = 0; y < 48; ++y) {
        for (int x = 0; x < 64; ++x) {
            const bool box = x >= 30 && x < 44 && y >= 20 && y < 34;
            depth.at(x, y, 0) = y < 12 ? kInf : box ? 2.0f : 10.0f + 0.05f * float(x);
            for (int c = 0; c < 3; ++c) {
                color.at(x, y, c) = 0.5f;
            }
        }
    }
    f.set("color", color);
    f.set("depth", depth);
    f.set("specular_depth", depth);
    return f;
}

TEST(DepthResample, FilteredDepthKeepsTheSkyAndTheRangeThroughEveryNode)
{
    const Frame f = edge_frame();
    const struct {
        const char *type, *params;
    } cases[] = {
        {"transform", R"("scale": 1.37, "rotate": 11, "filter": "bicubic")"},
        {"transform", R"("scale": 1.37, "rotate": 11, "filter": "bilinear")"},
        {"transform", R"("scale": 1.37, "rotate": 11, "filter": "lanczos3")"},
        {"transform", R"("scale": 0.8, "rotate": -7, "filter": "gaussian")"},
        {"reformat", R"("scale": 0.37, "filter": "lanczos3")"},
        {"reformat", R"("scale": 2.5, "filter": "catmull-rom")"},
        {"reformat", R"("scale": 1.5, "filter": "bicubic")"},
        {"lens", R"("k1": 0.15, "filter": "bicubic")"},
        {"lens", R"("k1": -0.15, "filter": "bilinear")"},
        // Source points on pixel edges: the guard's nearest pixel is nearest sampling's.
        {"transform", R"("rotate": 270, "scale": 0.5, "filter": "bilinear")"},
        {"reformat", R"("width": 49, "filter": "lanczos3")"},
        {"reformat", R"("width": 39, "filter": "box")"},
    };
    for (const auto &c : cases) {
        const std::string p = std::string("{") + c.params;
        const Frame nearest = test::run_node(c.type, f, p + R"(, "filtered": "color"})");
        const Frame out =
            test::run_node(c.type, f, p + R"(, "filtered": "color,depth,specular_depth"})");
        ASSERT_EQ(out.data_window, nearest.data_window) << c.type << c.params;
        // specular_depth is depth too: its sky stays the sky, unfiltered or filtered.
        ASSERT_TRUE(out.image("specular_depth").bit_equal(out.image("depth")));
        ASSERT_TRUE(nearest.image("specular_depth").bit_equal(nearest.image("depth")));
        const Image &a = out.image("depth"), &b = nearest.image("depth");
        int sky = 0, interpolated = 0;
        for (int y = 0; y < a.height(); ++y) {
            for (int x = 0; x < a.width(); ++x) {
                const float v = a.at(x, y, 0), n = b.at(x, y, 0);
                // The sky exactly where the nearest pixel is sky (or outside the input).
                ASSERT_EQ(std::isinf(v), std::isinf(n))
                    << c.type << c.params << " " << x << "," << y;
                if (std::isinf(v)) {
                    ASSERT_GT(v, 0.0f);
                    ++sky;
                    continue;
                }
                // Never beyond the input's finite depths: no NaN, no negative lobe's overshoot.
                ASSERT_GE(v, 2.0f) << c.type << c.params << " " << x << "," << y;
                ASSERT_LE(v, 10.0f + 0.05f * 63.0f) << c.type << c.params << " " << x << "," << y;
                interpolated += v != n;
            }
        }
        EXPECT_GT(sky, 0) << c.type << c.params;
        // The filter still filters: most ramp pixels differ from their nearest sample.
        EXPECT_GT(interpolated, a.width() * a.height() / 4) << c.type << c.params;
    }
}

TEST(DepthResample, AwayFromTheSkyAndEdgesDepthIsFilteredAsAnyOtherPass)
{
    Frame f;
    f.set_size(64, 64);
    Image depth(64, 64, 1);
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
            depth.at(x, y, 0) = 10.0f + 0.25f * float(x) + 0.125f * float(y);
        }
    }
    f.set("depth", depth);
    f.set("ramp", depth);  // the same values under a name the guard leaves alone
    for (const char *filter : {"bicubic", "bilinear", "lanczos3"}) {
        const Frame out = test::run_node(
            "transform",
            f,
            std::string(R"({"translate_x": 0.25, "translate_y": 0.5, "rotate": 3, )") +
                R"("filtered": "depth,ramp", "filter": ")" + filter + "\"}");
        const Image &a = out.image("depth"), &b = out.image("ramp");
        int differs = 0;
        for (int y = 8; y < a.height() - 8; ++y) {
            for (int x = 8; x < a.width() - 8; ++x) {
                ASSERT_EQ(a.at(x, y, 0), b.at(x, y, 0)) << filter << " " << x << "," << y;
                differs += a.at(x, y, 0) != depth.at(x, y, 0);
            }
        }
        EXPECT_GT(differs, 1000) << filter;  // resampled, not copied
    }
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

TEST(DepthResample, TapsOfZeroWeightOnTheSkyDoNotCount)
{
    // A ramp with one sky pixel, through a box filter: a pixel whose box holds the sky pixel at
    // weight 0 is filtered as any other pass (it fell back to the nearest pixel when the sky was
    // marked as NaN: 0 x NaN).
    Frame f;
    f.set_size(21, 21);
    Image depth(21, 21, 1), ramp(21, 21, 1), sky(21, 21, 1);
    for (int y = 0; y < 21; ++y) {
        for (int x = 0; x < 21; ++x) {
            ramp.at(x, y, 0) = 100.0f + float(x) + 4.0f * float(y);
            depth.at(x, y, 0) = x == 10 && y == 10 ? kInf : ramp.at(x, y, 0);
            sky.at(x, y, 0) = x == 10 && y == 10 ? 1.0f : 0.0f;
        }
    }
    f.set("depth", depth);
    f.set("ramp", ramp);
    f.set("sky", sky);
    const Frame out = test::run_node(
        "transform", f, R"({"rotate": 30, "filter": "box", "filtered": "depth,ramp,sky"})");
    const Frame near = test::run_node("transform", f, R"({"rotate": 30, "filter": "nearest"})");
    const Image &a = out.image("depth"), &r = out.image("ramp"), &s = out.image("sky");
    int filtered = 0, kept = 0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            const float n = near.image("depth").at(x, y, 0);
            if (std::isinf(n)) {
                ASSERT_EQ(a.at(x, y, 0), n);
            } else if (s.at(x, y, 0) == 0.0f) {
                ASSERT_EQ(a.at(x, y, 0), r.at(x, y, 0)) << x << "," << y;
                ++filtered;
            } else {
                ASSERT_EQ(a.at(x, y, 0), n) << x << "," << y;  // the sky in its box: nearest
                ++kept;
            }
        }
    }
    EXPECT_GT(filtered, 200);
    EXPECT_LT(kept, 12);
}

TEST(DepthResample, LensTreatsEveryViewsDepthAsDepth)
{
    // A stereo frame: the right eye's depth and colour go through the lens as the left's (lens
    // looked passes up by their full names: depth@right's sky became 0, and a filtered
    // depth@right went negative).
    Frame f = edge_frame();
    f.set("depth@right", f.image("depth"));
    f.set("color@right", f.image("color"));
    for (const char *params : {R"({"k1": 0.2})", R"({"k1": 0.2, "filtered": "color,depth"})"}) {
        const Frame out = test::run_node("lens", f, params);
        EXPECT_TRUE(out.image("depth@right").bit_equal(out.image("depth"))) << params;
        EXPECT_TRUE(out.image("color@right").bit_equal(out.image("color"))) << params;
    }
}

}  // namespace
}  // namespace posthaste
