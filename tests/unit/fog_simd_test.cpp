// The vector paths of the height fog (Highway: the best target against the portable one-lane
// target of the same source, and both against the exact per-pixel formula) and of the atmosphere
// (aerial perspective + sky; AVX2 against its scalar twin), on frames with every kind of pixel:
// ground at many distances, sky, the sun disc, NaN and negative depth, and rays looking steeply
// down into dense fog (the height fog's per-pixel fallback). Widths not a multiple of 8 exercise
// the row tails.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/trigonometric.hpp>
#include <limits>
#include <memory>

#include "core/camera.h"
#include "core/image.h"
#include "core/simd.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/camera_rays.h"
#include "shading/fog/height_fog.h"

namespace posthaste::shading {
namespace {

constexpr int kW = 203, kH = 97;

CameraMatrices looking_at_horizon(float pitch_deg, float height)
{
    glm::mat4 c2w(1.0f);
    const float p = glm::radians(pitch_deg);
    c2w[1] = glm::vec4(0.0f, std::cos(p), std::sin(p), 0.0f);
    c2w[2] = glm::vec4(0.0f, -std::sin(p), std::cos(p), 0.0f);
    c2w[3] = glm::vec4(0.0f, height, 0.0f, 1.0f);
    return make_camera_matrices(c2w, 18.0f, 36.0f, float(kW) / kH, 0.1f);
}

/// Ground plane y = 0 (sky above the horizon), with NaN, negative and zero depths sprinkled in.
Image ground_depth(const CameraRays &rays)
{
    Image depth(kW, kH, 1);
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            const glm::vec3 r = rays.depth_ray((x + 0.5f) / kW, (y + 0.5f) / kH);
            depth.at(x, y, 0) =
                r.y < -1e-4f ? rays.position().y / -r.y : std::numeric_limits<float>::infinity();
        }
    }
    depth.at(5, 60, 0) = std::numeric_limits<float>::quiet_NaN();
    depth.at(6, 60, 0) = -3.0f;
    depth.at(7, 60, 0) = 0.0f;
    depth.at(200, 10, 0) = std::numeric_limits<float>::quiet_NaN();
    return depth;
}

Image colour(int channels)
{
    Image c(kW, kH, channels);
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            for (int ch = 0; ch < channels; ++ch) {
                c.at(x, y, ch) = 0.05f + 0.01f * float((x * 7 + y * 3 + ch) % 50);
            }
        }
    }
    return c;
}

/// Largest |a - b| / (|b| + 1e-6) over every channel; alpha must match exactly.
float worst_relative(const Image &a, const Image &b)
{
    float worst = 0.0f;
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            for (int ch = 0; ch < a.channels(); ++ch) {
                const float va = a.at(x, y, ch), vb = b.at(x, y, ch);
                if (std::isnan(vb)) {
                    EXPECT_TRUE(std::isnan(va)) << x << " " << y;
                    continue;
                }
                if (ch == 3) {
                    EXPECT_EQ(va, vb) << "alpha at " << x << " " << y;
                }
                worst = std::max(worst, std::abs(va - vb) / (std::abs(vb) + 1e-6f));
            }
        }
    }
    return worst;
}

/// The frame by height_fog() pixel by pixel: the exact path the row kernel approximates.
Image per_pixel(const HeightFog &fog, const CameraRays &rays, const Image &depth, Image color)
{
    const HeightFogCamera c = prepare_height_fog(fog, rays.position());
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            const glm::vec3 ray = rays.depth_ray((x + 0.5f) / kW, (y + 0.5f) / kH);
            const float len = glm::length(ray);
            const FogResult f = height_fog(c, ray * (1.0f / len), depth.at(x, y, 0) * len);
            for (int ch = 0; ch < 3; ++ch) {
                color.at(x, y, ch) =
                    color.at(x, y, ch) * f.transmittance + f.inscatter[std::size_t(ch)];
            }
        }
    }
    return color;
}

TEST(FogSimd, HeightFogVectorTargetMatchesScalarTargetAndExactPath)
{
    // Pitch -20: the ground lies where b * ray_y * depth < -40 (per-pixel fallback), the sky
    // above the horizon does not, so 8-pixel groups mix both.
    for (const float pitch : {-5.0f, -20.0f}) {
        const CameraMatrices m = looking_at_horizon(pitch, 30.0f);
        const CameraRays rays(m.world_to_camera, m.world_to_ndc);
        const Image depth = ground_depth(rays);
        HeightFog fog;
        fog.density = pitch < -10.0f ? 1.0f : 0.02f;
        fog.falloff = pitch < -10.0f ? 1.5f : 0.05f;
        fog.sun_color = glm::vec3(0.4f, 0.3f, 0.2f);
        fog.sun_direction = glm::normalize(glm::vec3(0.3f, 0.2f, 1.0f));
        for (const int channels : {3, 4}) {
            Image fast = colour(channels), slow = colour(channels);
            apply_height_fog(fog, rays, depth, fast);
            {
                const simd::ScopedLevel scalar(simd::Level::Scalar);
                apply_height_fog(fog, rays, depth, slow);
            }
            const Image exact = per_pixel(fog, rays, depth, colour(channels));
            const float worst = worst_relative(fast, slow);
            const float worst_exact =
                std::max(worst_relative(fast, exact), worst_relative(slow, exact));
            EXPECT_LT(worst, 2e-5f) << "pitch " << pitch << ", " << channels << " channels";
            EXPECT_LT(worst_exact, 2e-5f) << "pitch " << pitch << ", " << channels << " channels";
            std::printf(
                "[ measured ] height fog, pitch %g, %d channels: vector vs scalar target "
                "%.2g, either vs per-pixel %.2g\n",
                pitch,
                channels,
                worst,
                worst_exact);
        }
    }
}

/// The aerial perspective by AerialPerspective::sample pixel by pixel.
Image per_pixel_ap(const AerialPerspective &ap, const Image &depth, Image color)
{
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            const float d = depth.at(x, y, 0);
            if (!(d < std::numeric_limits<float>::infinity())) {
                continue;  // sky and NaN: left alone
            }
            const glm::vec2 uv((x + 0.5f) / kW, (y + 0.5f) / kH);
            const ScatteringResult s = ap.sample(uv, ap.distance_from_depth(uv, d));
            for (int ch = 0; ch < 3; ++ch) {
                color.at(x, y, ch) = color.at(x, y, ch) * s.transmittance[ch] + s.inscatter[ch];
            }
        }
    }
    return color;
}

TEST(FogSimd, AtmosphereVectorTargetMatchesScalarTargetAndExactPath)
{
    AtmosphereParams p;
    p.sun_direction = glm::normalize(glm::vec3(0.0f, 0.05f, 1.0f));  // low sun, in view
    const Atmosphere atmo(p);
    const CameraMatrices m = looking_at_horizon(-2.0f, 20.0f);
    const CameraRays rays(m.world_to_camera, m.world_to_ndc);
    const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
    const Image depth = ground_depth(rays);
    for (const int channels : {3, 4}) {
        Image fast = colour(channels), slow = colour(channels);
        Image fast_ap = colour(channels), slow_ap = colour(channels);
        apply_atmosphere(atmo, atmo.cached_sky_view(), ap, depth, fast);
        apply_aerial_perspective(ap, depth, fast_ap);
        {
            const simd::ScopedLevel scalar(simd::Level::Scalar);
            apply_atmosphere(atmo, atmo.cached_sky_view(), ap, depth, slow);
            apply_aerial_perspective(ap, depth, slow_ap);
        }
        const float worst = worst_relative(fast, slow), worst_ap = worst_relative(fast_ap, slow_ap);
        const Image exact_ap = per_pixel_ap(ap, depth, colour(channels));
        const float worst_exact =
            std::max(worst_relative(fast_ap, exact_ap), worst_relative(slow_ap, exact_ap));
        EXPECT_LT(worst, 1e-4f) << channels << " channels";
        EXPECT_LT(worst_ap, 1e-5f) << channels << " channels";
        EXPECT_LT(worst_exact, 1e-5f) << channels << " channels";
        std::printf(
            "[ measured ] atmosphere, %d channels: vector vs scalar target %.2g (aerial "
            "perspective alone %.2g; either vs AerialPerspective::sample %.2g)\n",
            channels,
            worst,
            worst_ap,
            worst_exact);
        // The sun disc is in the frame and both paths put it there.
        float brightest = 0.0f;
        for (int y = 0; y < kH; ++y) {
            for (int x = 0; x < kW; ++x) {
                brightest = std::max(brightest, fast.at(x, y, 0));
            }
        }
        EXPECT_GT(brightest, 1000.0f);
    }
}

TEST(FogSimd, DepthLimitedFroxelsGiveTheSameFrame)
{
    // Froxels built only as deep as the frame's geometry: the same bits on that frame, on both
    // paths, for a fraction of the integration.
    AtmosphereParams p;
    p.sun_direction = glm::normalize(glm::vec3(0.2f, 0.3f, 1.0f));
    const Atmosphere atmo(p);
    for (const float height : {20.0f, 400.0f}) {
        const CameraMatrices m = looking_at_horizon(-8.0f, height);
        const CameraRays rays(m.world_to_camera, m.world_to_ndc);
        const Image depth = ground_depth(rays);
        const AerialPerspective full(atmo, m.world_to_camera, m.world_to_ndc);
        const AerialPerspective limited(atmo, m.world_to_camera, m.world_to_ndc, {}, depth);
        EXPECT_LT(limited.froxels_built(), full.froxels_built());
        EXPECT_EQ(full.froxels_built(), 32LL * 32 * 32);
        std::printf("[ measured ] camera at %g: %lld of %lld froxels integrated\n",
                    height,
                    limited.froxels_built(),
                    full.froxels_built());
        for (const simd::Level level : {simd::Level::Scalar, simd::detected()}) {
            const simd::ScopedLevel scoped(level);
            Image a = colour(4), b = colour(4);
            apply_atmosphere(atmo, atmo.cached_sky_view(), full, depth, a);
            apply_atmosphere(atmo, atmo.cached_sky_view(), limited, depth, b);
            for (std::size_t i = 0; i < a.value_count(); ++i) {
                ASSERT_EQ(a.data()[i], b.data()[i]) << i;
            }
        }
    }
}

}  // namespace
}  // namespace posthaste::shading
