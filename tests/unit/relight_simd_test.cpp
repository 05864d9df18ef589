// The relight node's AVX2 path (nodes/relight.cpp, shade_row_avx2) against its portable path
// (scalar setup, SSE2 kernel, shading::direct_response) on a real frame: the Minecrappy scene's
// G-buffer at frame 30 with every material kind (rough and glossy dielectrics, metals, the
// anisotropic ones, toon leaves) under a sun, two point lights and a spot, in both modes and
// with positions from the position pass or from depth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &gbuffer()
{
    static const Frame f = [] {
        const raster::Scene s = raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) +
                                                   "/samples/scenes/minecrappy.json");
        raster::RenderOptions o;
        o.width = 476;  // not a multiple of 8: the last group of each row is partial
        o.height = 270;
        o.shadows = false;
        o.passes = {"color", "normal", "position", "albedo", "material", "tangent", "id", "depth"};
        return raster::render_frame(s, 30, o);
    }();
    return f;
}

Image run_relight(const std::string &params)
{
    return test::run_node("relight", gbuffer(), params, 30).image("color");
}

const char *kLights = R"("lights": [
    {"type": "directional", "direction": [0.4, 0.75, 0.3], "color": [1, 0.95, 0.88], "intensity": 4},
    {"type": "point", "position": [60, 20, 60], "color": [1, 0.6, 0.3], "intensity": 200},
    {"type": "point", "position": [70, 18, 50], "color": [0.3, 0.6, 1], "intensity": 150},
    {"type": "spot", "position": [64, 30, 64], "direction": [0, -1, 0.2], "intensity": 900,
     "inner_deg": 15, "outer_deg": 35}])";

struct Difference {
    double worst_rel = 0.0;    // largest |a - b| / max(|b|, 1e-3) outside the band edges
    std::size_t outliers = 0;  // values beyond the tolerance (toon band edges)
    std::size_t changed = 0;   // values that differ from the input at all
};

// Compares the AVX2 and portable outputs value by value; `in` is the input color.
Difference compare(const Image &fast, const Image &ref, const Image &in, double tolerance)
{
    // Surface pixels: a finite position and a normal longer than 0.5 (the node's own test).
    const Image &normal = gbuffer().image("normal"), &position = gbuffer().image("position");
    Image surface(ref.width(), ref.height(), 1);
    for (int y = 0; y < ref.height(); ++y) {
        for (int x = 0; x < ref.width(); ++x) {
            float n2 = 0.0f;
            bool finite = true;
            for (int c = 0; c < 3; ++c) {
                n2 += normal.at(x, y, c) * normal.at(x, y, c);
                finite = finite && std::isfinite(position.at(x, y, c));
            }
            surface.at(x, y, 0) = finite && n2 > 0.3f;
        }
    }
    Difference d;
    EXPECT_EQ(fast.channels(), ref.channels());
    for (int y = 0; y < ref.height(); ++y) {
        for (int x = 0; x < ref.width(); ++x) {
            for (int c = 0; c < ref.channels(); ++c) {
                const double a = fast.at(x, y, c), b = ref.at(x, y, c);
                EXPECT_TRUE(std::isfinite(a)) << x << "," << y;
                d.changed += b != double(in.at(x, y, c));
                if (c == 3 || !surface.at(x, y, 0)) {
                    // Alpha and background pass through: the same bits on both paths.
                    EXPECT_EQ(a, b) << x << "," << y << " channel " << c;
                    continue;
                }
                const double rel = std::abs(a - b) / std::max(std::abs(b), 1e-3);
                if (rel > tolerance) {
                    ++d.outliers;
                } else {
                    d.worst_rel = std::max(d.worst_rel, rel);
                }
            }
        }
    }
    return d;
}

// Relative tolerance per value. Both paths use rsqrt/rcp with one Newton step (about 5e-7 each);
// at a glossy highlight the portable path's 1 - (n.h)^2 loses about one ulp / alpha^2 to
// cancellation (about 1e-4 at roughness 0.25; the AVX2 path avoids it), which dominates: the
// measured worst is about 8e-5.
constexpr double kTolerance = 2e-4;

void check_paths_agree(const std::string &params, std::size_t max_outliers)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    Image ref;
    {
        simd::ScopedLevel scalar(simd::Level::Scalar);
        ref = run_relight(params);
    }
    const Image fast = run_relight(params);
    const Difference d = compare(fast, ref, gbuffer().image("color"), kTolerance);
    std::printf(
        "relight AVX2 vs portable: worst relative difference %.3g, %zu of %zu values "
        "beyond %.0e\n",
        d.worst_rel,
        d.outliers,
        d.changed,
        kTolerance);
    EXPECT_GT(d.changed, std::size_t(ref.width()) * std::size_t(ref.height()));  // it did shade
    EXPECT_LE(d.worst_rel, kTolerance);
    EXPECT_LE(d.outliers, max_outliers);
}

TEST(RelightSimd, AddModeMatchesPortablePath)
{
    // Toon leaves: a pixel whose n.l sits on a band edge may fall in the next band on one path
    // only (a step of albedo / bands / pi times the light), so a few values may differ.
    check_paths_agree(R"({"mode": "add", "toon_ids": "6", )" + std::string(kLights) + "}", 8);
}

TEST(RelightSimd, ReplaceWithAmbientAndClampMatchesPortablePath)
{
    check_paths_agree(
        R"({"mode": "replace", "ambient": 0.6, "clamp": 2.0, )" + std::string(kLights) + "}", 0);
}

TEST(RelightSimd, PositionFromDepthMatchesPortablePath)
{
    // The AVX2 path's own 2x2 solve for the position against prepare_pixel's.
    check_paths_agree(R"({"mode": "replace", "position_from": "depth", "toon_ids": "6", )" +
                          std::string(kLights) + "}",
                      8);
}

TEST(RelightSimd, EnergyCompensationMatchesPortablePath)
{
    // The Kulla-Conty lobe with the table read per lane (gathers) against multiscatter().
    check_paths_agree(R"({"mode": "add", "energy_compensation": true, "toon_ids": "6", )" +
                          std::string(kLights) + "}",
                      8);
}

TEST(RelightSimd, SameBitsForAnyThreadCount)
{
    const std::string params = R"({"mode": "add", "toon_ids": "6", )" + std::string(kLights) + "}";
    set_thread_count(1);
    const Image one = run_relight(params);
    set_thread_count(2);
    const Image two = run_relight(params);
    set_thread_count(0);
    ASSERT_EQ(one.value_count(), two.value_count());
    EXPECT_TRUE(std::equal(one.data(), one.data() + one.value_count(), two.data()));
}

}  // namespace
}  // namespace posthaste
