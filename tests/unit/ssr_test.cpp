// Reflections: the exact ray caster's first hits (voxels, balls, blocks), the reflection truth
// (the beauty itself where the rays see only sky; its noise falling with the ray count), the ssr
// node against that truth on the glossy scene, and its failure cases: non-finite passes,
// extreme parameters, thread counts, and the refusals (missing pass, no camera, sizes).

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "raster/ray_cast.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/atmosphere/atmosphere_kernels.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/camera_rays.h"
#include "shading/lighting/env_brdf.h"
#include "shading/lighting/lighting.h"
#include "shading/ssr/environment.h"
#include "shading/ssr/ssr_kernels.h"
#include "test_util.h"

namespace posthaste {
namespace {
using test::render_options;
using test::rms_rgb;
using test::scene_path;

/// The glossy scene's frame with every pass ssr reads, and the header the render node writes.
Frame glossy_frame(const raster::Scene &s, int w, int h, int frame = 1)
{
    Frame f = raster::render_frame(
        s,
        frame,
        render_options(
            w, h, {"color", "depth", "normal", "albedo", "material", "position", "shadow"}));
    const glm::vec3 d = s.sun.direction;
    f.attributes.push_back(OIIO::ParamValue("posthaste:sunDirection", OIIO::TypeVector, 1, &d));
    f.attributes.push_back(OIIO::ParamValue("posthaste:skyAmbient", s.sky_ambient));
    const glm::vec3 sun = s.sun.color * s.sun.illuminance;
    f.attributes.push_back(OIIO::ParamValue("posthaste:sunIrradiance", OIIO::TypeVector, 1, &sun));
    return f;
}

TEST(Ssr, RayCasterFindsTheFirstSurface)
{
    raster::Scene s;
    s.world.nx = s.world.ny = s.world.nz = 40;
    s.world.cells.assign(40 * 40 * 40, 0);
    for (int z = 0; z < 40; ++z) {
        for (int x = 0; x < 40; ++x) {
            s.world.set(x, 0, z, 3);  // floor, top at y = 1
            for (int y = 0; y < 40; ++y) {
                if (x >= 20) {
                    s.world.set(x, y, z, 4);  // wall, face at x = 20
                }
            }
        }
    }
    raster::Ball ball;
    ball.center = glm::vec3(10.0f, 3.0f, 10.0f);
    ball.radius = 1.0f;
    ball.material = 7;
    s.balls.push_back(ball);
    raster::Mover block;
    block.min = glm::vec3(5.0f, 1.0f, 30.0f);
    block.size = glm::vec3(1.0f);
    block.material = 9;
    s.movers.push_back(block);
    const raster::RayScene rays(s, 1.0);
    const glm::vec3 up(0, 1, 0), east(1, 0, 0);

    auto wall = rays.closest({17.5f, 5.0f, 5.0f}, east, 100.0f);
    ASSERT_TRUE(wall);
    EXPECT_NEAR(wall->distance, 2.5f, 1e-4f);
    EXPECT_EQ(wall->normal, glm::vec3(-1, 0, 0));
    EXPECT_EQ(wall->material, 4);
    EXPECT_FALSE(rays.closest({17.5f, 5.0f, 5.0f}, east, 2.0f));  // beyond max_dist

    auto floor = rays.closest({3.0f, 4.0f, 3.0f}, glm::normalize(glm::vec3(1, -1, 0)), 100.0f);
    ASSERT_TRUE(floor);
    EXPECT_NEAR(floor->distance, 3.0f * std::sqrt(2.0f), 1e-4f);
    EXPECT_EQ(floor->normal, up);
    EXPECT_EQ(floor->material, 3);

    auto on_ball = rays.closest({10.0f, 1.001f, 10.0f}, up, 100.0f);  // the ball's underside
    ASSERT_TRUE(on_ball);
    EXPECT_NEAR(on_ball->distance, 0.999f, 1e-3f);
    EXPECT_NEAR(glm::dot(on_ball->normal, -up), 1.0f, 1e-4f);
    EXPECT_EQ(on_ball->material, 7);

    auto on_block = rays.closest({2.0f, 1.5f, 30.5f}, east, 100.0f);  // the block before the wall
    ASSERT_TRUE(on_block);
    EXPECT_NEAR(on_block->distance, 3.0f, 1e-4f);
    EXPECT_EQ(on_block->normal, glm::vec3(-1, 0, 0));
    EXPECT_EQ(on_block->material, 9);

    auto entering = rays.closest({-5.0f, 10.0f, 5.0f}, east, 100.0f);  // from outside the grid
    ASSERT_TRUE(entering);
    EXPECT_NEAR(entering->distance, 25.0f, 1e-4f);
    EXPECT_EQ(entering->material, 4);
    EXPECT_FALSE(rays.closest({10.0f, 5.0f, 5.0f}, up, 1e3f));  // open sky
}

TEST(Ssr, TruthIsTheBeautyWhereTheRaysSeeOnlySky)
{
    // A polished floor and nothing else: every reflected ray leaves the scene, so the truth
    // differs from the beauty only by the lobe's spread around the mirror direction.
    raster::Scene s;
    s.world.nx = s.world.nz = 64;
    s.world.ny = 4;
    s.world.cells.assign(64 * 4 * 64, 0);
    for (int z = 0; z < 64; ++z) {
        for (int x = 0; x < 64; ++x) {
            s.world.set(x, 0, z, 1);
        }
    }
    raster::Material m;
    m.id = 1;
    m.albedo = glm::vec3(0.05f);
    m.roughness = 0.06f;
    s.materials = {m};
    raster::CameraKey key;
    key.position = glm::vec3(32.0f, 4.0f, 4.0f);
    key.pitch_deg = -20.0f;
    s.camera_keys = {key};
    const raster::RenderOptions o = render_options(64, 36, {"color"});
    const Frame beauty = raster::render_frame(s, 1, o);
    const Image truth = raster::render_reflection_truth(s, 1, o, 16, 1);
    const Image &b = beauty.image("color");
    double diff = 0.0, total = 0.0, worst = 0.0;
    for (int y = 0; y < b.height(); ++y) {
        for (int x = 0; x < b.width(); ++x) {
            for (int c = 0; c < 4; ++c) {
                ASSERT_TRUE(std::isfinite(truth.at(x, y, c)));
                const double d = std::abs(double(truth.at(x, y, c) - b.at(x, y, c)));
                diff += d;
                total += std::abs(double(b.at(x, y, c)));
                worst = std::max(worst, d / std::max(0.05, double(b.at(x, y, c))));
            }
        }
    }
    // On the whole within 1 %; the worst pixels reflect the horizon, where the sky changes
    // fastest across the lobe.
    EXPECT_LT(diff / total, 0.01);
    EXPECT_LT(worst, 0.2);
}

TEST(Ssr, TruthNoiseFallsWithTheRayCount)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const raster::RenderOptions o = render_options(96, 54, {"color"});
    const Image t4 = raster::render_reflection_truth(s, 1, o, 4, 1);
    const Image t16 = raster::render_reflection_truth(s, 1, o, 16, 2);
    const Image t64 = raster::render_reflection_truth(s, 1, o, 64, 3);
    const double coarse = rms_rgb(t4, t16), fine = rms_rgb(t16, t64);
    EXPECT_GT(coarse, 0.0);
    EXPECT_LT(fine, 0.75 * coarse) << coarse << " " << fine;
    const Frame beauty = raster::render_frame(s, 1, o);
    // The reflections are what the truth adds: far more than its noise.
    EXPECT_GT(rms_rgb(beauty.image("color"), t64), 2.0 * fine);
}

TEST(Ssr, RemovesMostOfTheMissingReflectionsOnTheGlossyScene)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 480, 270);
    const Image truth =
        raster::render_reflection_truth(s, 1, render_options(480, 270, {"color"}), 64, 7);
    const double none = rms_rgb(f.image("color"), truth);
    const Frame out = test::run_node("ssr", f, "{}");
    const double ssr = rms_rgb(out.image("color"), truth);
    EXPECT_LT(ssr, 0.5 * none) << "ssr " << ssr << " nothing " << none;
    // Without the shadow pass, hits facing the sun are taken to be lit: close, on this scene.
    Frame no_shadow = f;
    no_shadow.erase("shadow");
    const Frame lit = test::run_node("ssr", no_shadow, "{}");
    EXPECT_LT(rms_rgb(lit.image("color"), truth), 0.6 * none);
    // Only colour changes: alpha and every other pass are the input's.
    const Image &a = out.image("color"), &b = f.image("color");
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            ASSERT_EQ(a.at(x, y, 3), b.at(x, y, 3));
        }
    }
    EXPECT_EQ(out.pass("depth").image, f.pass("depth").image);
}

TEST(Ssr, ReshadedHitsShowHighlightsWhereTheReflectedRaysSeeThem)
{
    // Frame 16: the gold ball and its image in the polished floor, each showing the sun's
    // highlight as the other sees it. Hits that keep the colour the camera saw (no
    // sun_irradiance) put those highlights where the camera saw them.
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 480, 270, 16);
    const Image truth =
        raster::render_reflection_truth(s, 16, render_options(480, 270, {"color"}), 64, 7);
    const double none = rms_rgb(f.image("color"), truth);
    const double reshaded = rms_rgb(test::run_node("ssr", f, "{}", 16).image("color"), truth);
    const double as_seen = rms_rgb(
        test::run_node("ssr", f, R"({"sun_irradiance": [0, 0, 0]})", 16).image("color"), truth);
    EXPECT_LT(reshaded, 0.9 * as_seen) << "re-shaded " << reshaded << " as seen " << as_seen;
    EXPECT_LT(as_seen, none);
}

TEST(Ssr, SkyRoughSurfacesAndZeroIntensityAreLeftAlone)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 96, 54);
    const Frame off = test::run_node("ssr", f, R"({"intensity": 0})");
    EXPECT_EQ(off.pass("color").image, f.pass("color").image);
    const Frame out = test::run_node("ssr", f, "{}");
    const Image &a = out.image("color"), &b = f.image("color");
    const Image &depth = f.image("depth"), &material = f.image("material");
    int changed = 0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            const bool sky = !std::isfinite(depth.at(x, y, 0));
            const bool rough = material.at(x, y, 0) > 0.78f;
            for (int c = 0; c < 4; ++c) {
                if (sky || rough) {
                    ASSERT_EQ(a.at(x, y, c), b.at(x, y, c)) << x << "," << y;
                }
            }
            changed += a.at(x, y, 0) != b.at(x, y, 0) ? 1 : 0;
        }
    }
    EXPECT_GT(changed, a.width() * a.height() / 10);
}

TEST(Ssr, NonFinitePassesAndExtremeParametersGiveFiniteOutput)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame clean = glossy_frame(s, 96, 54);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    for (const char *pass : {"color", "depth", "normal", "albedo", "material", "shadow"}) {
        for (const float bad : {nan, inf, -inf}) {
            Frame f = clean;
            Image img = f.image(pass);
            for (int y = 10; y < 40; y += 3) {
                for (int x = 0; x < img.width(); x += 2) {
                    for (int c = 0; c < img.channels(); ++c) {
                        img.at(x, y, c) = bad;
                    }
                }
            }
            f.set(pass, std::move(img), f.pass(pass).channels);
            const Frame out = test::run_node("ssr", f, "{}");
            const Image &o = out.image("color");
            for (std::size_t i = 0; i < o.value_count(); ++i) {
                ASSERT_TRUE(std::isfinite(o.data()[i])) << pass << " " << bad << " at " << i;
                ASSERT_GE(o.data()[i], 0.0f) << pass << " " << bad << " at " << i;
            }
        }
    }
    // The sky reflection ssr takes away is its model's: over a black colour pass, or with the
    // sky scaled up, it exceeds what the colour holds, and the colour stays at 0 (it went to
    // -0.19). Colours near the largest float stay finite (two of them once added to inf).
    for (const float value : {0.0f, 3e38f}) {
        Frame f = clean;
        Image img = f.image("color");
        for (std::size_t i = 0; i < img.value_count(); ++i) {
            img.data()[i] = value;
        }
        f.set("color", std::move(img), f.pass("color").channels);
        for (const char *params : {"{}", R"({"sky_scale": 10})", R"({"resolution": "full"})"}) {
            const Frame out = test::run_node("ssr", f, params);
            const Image &o = out.image("color");
            for (std::size_t i = 0; i < o.value_count(); ++i) {
                ASSERT_TRUE(std::isfinite(o.data()[i])) << value << " " << params;
                ASSERT_GE(o.data()[i], 0.0f) << value << " " << params;
            }
        }
    }
    for (const char *params :
         {R"({"rays": 64, "steps": 512, "refine": 16, "denoise": 8})",
          R"({"rays": 1, "steps": 1, "refine": 0, "denoise": 0, "thickness": 0.0001})",
          R"({"thickness": 10000, "max_distance": 1000000, "edge_fade": 0.5})",
          R"({"max_distance": 0.001, "max_roughness": 1, "offscreen": "sky"})",
          R"({"sky_scale": 1000000, "sun_direction": [0, -1, 0]})",
          R"({"sun_irradiance": [1000000, 0, 1000000]})"}) {
        const Frame out = test::run_node("ssr", clean, params);
        const Image &o = out.image("color");
        for (std::size_t i = 0; i < o.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(o.data()[i])) << params;
        }
    }
}

TEST(Ssr, SameBitsForAnyThreadCount)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 128, 72);
    set_thread_count(1);
    const Frame one = test::run_node("ssr", f, "{}");
    set_thread_count(2);
    const Frame two = test::run_node("ssr", f, "{}");
    set_thread_count(0);
    EXPECT_TRUE(one.image("color").bit_equal(two.image("color")));
}

TEST(Ssr, VectorKernelsGiveTheScalarReferenceBits)
{
    // The kernels (ssr_kernels.cpp: the march's depth tests, the resolve's weights and window)
    // run on every Highway target and give the scalar reference's bits: whole vectors of steps
    // (16), a partial one (37), one step, many (512); resolve windows from one pixel to 17, at
    // full, half and quarter resolution; an odd size (the last cell column partly outside).
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 161, 91);
    for (const char *params : {R"({})",
                               R"({"steps": 37, "thickness": 0.05, "denoise": 8})",
                               R"({"steps": 1, "resolution": "full", "denoise": 0})",
                               R"({"resolution": "full", "denoise": 2, "intensity": 0.5})",
                               R"({"steps": 512, "offscreen": "extend", "rays": 2})",
                               R"({"resolution": "half", "denoise": 3})",
                               R"({"denoise": 8, "rays": 8})"}) {
        Frame reference;
        {
            const simd::ScopedLevel scalar(simd::Level::Scalar);
            reference = test::run_node("ssr", f, params);
        }
        // The march changes the picture: a broken kernel cannot pass as the sky.
        EXPECT_FALSE(reference.image("color").bit_equal(f.image("color"))) << params;
        test::for_each_highway_target([&](const char *target) {
            const Frame out = test::run_node("ssr", f, params);
            EXPECT_TRUE(out.image("color").bit_equal(reference.image("color")))
                << target << " " << params << ": RMS "
                << rms_rgb(out.image("color"), reference.image("color"));
        });
    }
}

TEST(Ssr, SkyKernelGivesTheSkyViewBits)
{
    // The sky-view lookups of missed rays (ssr_sky_view_radiance) against SkyView::radiance,
    // bit for bit on every target: directions over the whole sphere (zenith, nadir, the horizon
    // and just either side of it, towards and away from the sun), n not a whole vector.
    const shading::SceneSky &sky = shading::scene_sky(glm::vec3(0.4f, 0.75f, 0.3f));
    const shading::SkyView &view = sky.atmosphere().cached_sky_view();
    std::vector<glm::vec3> dirs = {{0, 1, 0}, {0, -1, 0}, {1, 0, 0}, {0.4f, 0.75f, 0.3f}};
    for (int i = 0; i < 53; ++i) {
        for (int j = 0; j < 29; ++j) {
            const float phi = 6.2831853f * float(i) / 53.0f;
            const float y = -1.0f + 2.0f * float(j) / 28.0f + (j == 14 ? 1e-4f : 0.0f);
            const float r = std::sqrt(std::max(0.0f, 1.0f - y * y));
            dirs.push_back(glm::normalize(glm::vec3(r * std::cos(phi), y, r * std::sin(phi))));
        }
    }
    const int n = int(dirs.size());
    const std::size_t pitch = std::size_t(n + shading::kSsrStepPad);
    std::vector<float> soa(6 * pitch, 0.0f);
    for (int i = 0; i < n; ++i) {
        soa[std::size_t(i)] = dirs[std::size_t(i)].x;
        soa[pitch + std::size_t(i)] = dirs[std::size_t(i)].y;
        soa[2 * pitch + std::size_t(i)] = dirs[std::size_t(i)].z;
    }
    const shading::SkyCoordParams lut = view.coord_params();
    test::for_each_highway_target([&](const char *target) {
        shading::ssr_sky_view_radiance(lut,
                                       soa.data(),
                                       soa.data() + pitch,
                                       soa.data() + 2 * pitch,
                                       n,
                                       soa.data() + 3 * pitch,
                                       soa.data() + 4 * pitch,
                                       soa.data() + 5 * pitch);
        int differ = 0;
        for (int i = 0; i < n; ++i) {
            const glm::vec3 want = view.radiance(dirs[std::size_t(i)]);
            for (int c = 0; c < 3; ++c) {
                differ += soa[std::size_t(3 + c) * pitch + std::size_t(i)] != want[c] ? 1 : 0;
            }
        }
        EXPECT_EQ(differ, 0) << target;
    });
}

TEST(Ssr, SamplerTwinDrawsTheTruthsDirections)
{
    // The node draws its rays with ggx_reflection_twin (a polynomial sine and cosine, so that its
    // vector kernel can give the same bits); the truth with shading::sample_ggx_reflection. The
    // same (n, v, alpha, u1, u2) must give the same direction to float precision, or the node
    // would sample a different lobe than the one it is charted against.
    double worst_sc = 0.0, worst_l = 0.0;
    for (int i = 0; i <= 4096; ++i) {
        const float u = float(i) / 4096.0f;
        float sv, cv;
        shading::sincos_turns(u, sv, cv);
        const double a = 6.283185307179586 * double(u);
        worst_sc = std::max({worst_sc, std::abs(sv - std::sin(a)), std::abs(cv - std::cos(a))});
    }
    EXPECT_LT(worst_sc, 3e-7);
    for (int i = 0; i < 2000; ++i) {
        const float h0 = float((i * 7919) % 1000) / 1000.0f,
                    h1 = float((i * 104729) % 997) / 997.0f;
        const glm::vec3 n = glm::normalize(glm::vec3(std::cos(6.2831853f * h0) * (1.0f - h1),
                                                     (i % 3 == 0 ? -1.0f : 1.0f) * (0.1f + h1),
                                                     std::sin(6.2831853f * h0)));
        const glm::vec3 v = glm::normalize(n + glm::vec3(0.3f * h1, 0.2f, -0.4f * h0));
        const float alpha = 0.0025f + 0.6f * h1;
        const float u1 = float(i % 50) / 50.0f, u2 = float(i % 37) / 37.0f;
        const glm::vec3 want = shading::sample_ggx_reflection(n, v, alpha, u1, u2);
        float l[3];
        shading::ggx_reflection_twin(&n.x, &v.x, alpha, u1, u2, l);
        worst_l = std::max(worst_l, double(glm::length(glm::vec3(l[0], l[1], l[2]) - want)));
    }
    EXPECT_LT(worst_l, 1e-6);
}

/// A latitude-longitude map of w x h whose every texel is `f(direction at its centre)`.
template <typename F>
Frame environment_frame(int w, int h, F f)
{
    Image map(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec3 c = f(shading::latlong_direction((float(x) + 0.5f) / float(w),
                                                             (float(y) + 0.5f) / float(h)));
            map.at(x, y, 0) = c.x;
            map.at(x, y, 1) = c.y;
            map.at(x, y, 2) = c.z;
            map.at(x, y, 3) = 1.0f;
        }
    }
    Frame env;
    env.set_size(w, h);
    env.set("color", std::move(map));
    return env;
}

/// A world of one colour: a renderer's panorama of a constant sky.
Frame constant_world(const glm::vec3 &c)
{
    return environment_frame(32, 16, [&](const glm::vec3 &) { return c; });
}

// On a production renderer's frames (measured against Cycles in
// tests/accuracy/cycles_ssr_test.cpp): the reflections weighed as a physically based GGX lobe
// (brdf ggx) and replacing the renderer's world (the world input) instead of the rasterizer's
// Schlick-times-gloss term and sky model; their bits on every target and thread count.

TEST(SsrRenderer, AWorldTheColourReflectsAlreadyIsNotAddedTwice)
{
    // Rays too short to meet anything see the environment. Where the colour pass reflects that
    // world already (the same map as the world input) nothing changes; against the sky model,
    // the world's difference from the sky is added; against another world, the difference
    // between the two, weighed by each pixel's Fresnel and gloss.
    const Frame f = glossy_frame(raster::load_scene(scene_path("glossy.json")), 96, 54);
    const Frame world = constant_world(glm::vec3(2.0f, 0.5f, 0.25f));
    const test::NodeRunner runner("ssr", R"({"max_distance": 0.001})");
    const Image kept =
        runner.run_ports({{"image", f}, {"environment", world}, {"world", world}}).image("color");
    EXPECT_LT(rms_rgb(kept, f.image("color")), 1e-6);
    const Image added = runner.run_ports({{"image", f}, {"environment", world}}).image("color");
    EXPECT_GT(rms_rgb(added, f.image("color")), 0.01);
    // Another world W: out = in + w (E - W), w each pixel's weight. So out(W1) - out(W2) =
    // w (W2 - W1) whatever w: against grey 1 and grey 0.5, (2, 0.5, 0.25) moves each channel
    // by (1, -0.5, -0.75) / -0.5 times what 0.5 does (where out stays above 0, where ssr holds it).
    const auto with_world = [&](const glm::vec3 &c) {
        return runner
            .run_ports({{"image", f}, {"environment", world}, {"world", constant_world(c)}})
            .image("color");
    };
    const Image one = with_world(glm::vec3(1.0f)), half = with_world(glm::vec3(0.5f));
    const Image &in = f.image("color");
    const float expected[3] = {-2.0f, 1.0f, 1.5f};
    int changed = 0;
    for (int y = 0; y < in.height(); ++y) {
        for (int x = 0; x < in.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                if (one.at(x, y, c) <= 0.0f || half.at(x, y, c) <= 0.0f) {
                    continue;  // held at 0: a world brighter than the colour takes away less
                }
                const float unit = one.at(x, y, c) - half.at(x, y, c);
                const float moved = one.at(x, y, c) - kept.at(x, y, c);
                if (std::abs(unit) > 1e-3f) {
                    EXPECT_NEAR(moved / unit, expected[c], 0.02f) << x << "," << y << " " << c;
                    ++changed;
                } else {
                    EXPECT_LT(std::abs(moved), 5e-3f) << x << "," << y << " " << c;
                }
            }
        }
    }
    EXPECT_GT(changed, in.width() * in.height() / 10);
    // Non-finite texels in the world read as black: the output stays finite.
    Frame bad = world;
    Image texels = bad.image("color");
    texels.at(3, 2, 0) = std::numeric_limits<float>::quiet_NaN();
    texels.at(20, 9, 1) = std::numeric_limits<float>::infinity();
    texels.at(31, 15, 2) = -std::numeric_limits<float>::infinity();
    for (int y = 0; y < 16; ++y) {
        texels.at(16, y, 0) = std::numeric_limits<float>::quiet_NaN();  // a whole column
    }
    bad.set("color", std::move(texels));
    const Image finite = test::NodeRunner("ssr", R"({"brdf": "ggx"})")
                             .run_ports({{"image", f}, {"environment", bad}, {"world", bad}})
                             .image("color");
    EXPECT_TRUE(test::all_finite_rgb(finite));
    // A world without RGB is refused, naming the input.
    Frame two = world;
    two.set("color", Image(32, 16, 2), {"R", "G"});
    try {
        runner.run_ports({{"image", f}, {"environment", world}, {"world", two}});
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("\"world\""), std::string::npos) << e.what();
    }
}

TEST(SsrRenderer, GgxWeighsTheSameRaysAsTheLobesAlbedo)
{
    // The same rays and resolve, weighed differently: each changed pixel's change under ggx is
    // its change under posthaste's weight times ggx_reflection_weight / sky_reflection_weight.
    const Frame f = glossy_frame(raster::load_scene(scene_path("glossy.json")), 96, 54);
    const Image &in = f.image("color");
    const Image post = test::run_node("ssr", f, R"({"resolution": "full"})").image("color");
    const Image ggx =
        test::run_node("ssr", f, R"({"resolution": "full", "brdf": "ggx"})").image("color");
    const Camera camera = f.pixel_camera();
    const shading::CameraRays rays(camera.require_world_to_camera("test"),
                                   camera.require_world_to_ndc("test"));
    const Image &normal = f.image("normal"), &albedo = f.image("albedo"),
                &material = f.image("material");
    int compared = 0;
    for (int y = 0; y < in.height(); ++y) {
        for (int x = 0; x < in.width(); ++x) {
            const float u = (float(x) + 0.5f) / float(in.width());
            const float v = (float(y) + 0.5f) / float(in.height());
            glm::vec3 n = glm::normalize(
                glm::vec3(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2)));
            const glm::vec3 view = -rays.direction(u, v);
            if (glm::dot(n, view) < 0.0f) {
                n = -n;
            }
            shading::Surface s;
            s.albedo = glm::vec3(albedo.at(x, y, 0), albedo.at(x, y, 1), albedo.at(x, y, 2));
            s.roughness = material.at(x, y, 0);
            s.metallic = material.at(x, y, 1);
            const glm::vec3 wp = shading::sky_reflection_weight(s, n, view);
            const glm::vec3 wg = shading::ggx_reflection_weight(s, n, view);
            for (int c = 0; c < 3; ++c) {
                const float dp = post.at(x, y, c) - in.at(x, y, c);
                const float dg = ggx.at(x, y, c) - in.at(x, y, c);
                if (wp[c] > 0.02f && std::abs(dp) > 0.01f) {
                    EXPECT_NEAR(dg, dp * wg[c] / wp[c], 2e-3f * (1.0f + std::abs(dg)))
                        << x << "," << y << " channel " << c;
                    ++compared;
                } else if (wp[c] == 0.0f) {
                    EXPECT_EQ(dp, 0.0f) << x << "," << y;
                }
            }
        }
    }
    EXPECT_GT(compared, in.width() * in.height() / 10);
}

TEST(SsrRenderer, SameBitsOnEveryTargetAndThreadCount)
{
    // brdf ggx's weights (the GGX table's gathers in the weight kernel, and the pixels from
    // roughness 0.776 that only a GGX lobe reflects, at max_roughness 1), the march and the
    // resolve's window: the scalar reference's bits on every Highway target.
    const Frame f = glossy_frame(raster::load_scene(scene_path("glossy.json")), 101, 57);
    const Frame world = constant_world(glm::vec3(0.45f, 0.6f, 0.9f));
    const std::vector<std::pair<std::string, Frame>> ports = {
        {"image", f}, {"environment", world}, {"world", world}};
    for (const char *params : {R"({"brdf": "ggx"})",
                               R"({"brdf": "ggx", "max_roughness": 1})",
                               R"({"brdf": "ggx", "resolution": "half", "denoise": 2})"}) {
        const test::NodeRunner runner("ssr", params);
        Image reference;
        {
            const simd::ScopedLevel scalar(simd::Level::Scalar);
            reference = runner.run_ports(ports).image("color");
        }
        EXPECT_FALSE(reference.bit_equal(f.image("color"))) << params;
        test::for_each_highway_target([&](const char *target) {
            const Image out = runner.run_ports(ports).image("color");
            EXPECT_TRUE(out.bit_equal(reference)) << target << " " << params;
        });
        set_thread_count(1);
        const Image one = runner.run_ports(ports).image("color");
        set_thread_count(0);
        EXPECT_TRUE(one.bit_equal(reference)) << params;
    }
}

TEST(Ssr, EnvironmentInputReplacesTheSkyForWhatTheScreenMisses)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 120, 68);
    const test::NodeRunner runner("ssr", "{}");
    const Image sky_out = runner.run(f).image("color");
    // The sky itself as the environment: the same result but for the map's resolution.
    const shading::SceneSky &sky = shading::scene_sky(s.sun.direction);
    const glm::vec3 sky_camera(0.0f, shading::kSkyCameraY, 0.0f);
    const Frame sky_env = environment_frame(512, 256, [&](const glm::vec3 &d) {
        return sky.radiance(d, sky_camera, false) * s.sky_ambient;
    });
    const Image same = runner.run_ports({{"image", f}, {"environment", sky_env}}).image("color");
    EXPECT_LT(rms_rgb(same, sky_out), 0.02 * rms_rgb(sky_out, f.image("color")));
    // A red environment: reflections turn red where rays leave the screen, nowhere bluer.
    const Frame red_env =
        environment_frame(64, 32, [](const glm::vec3 &) { return glm::vec3(4.0f, 0.0f, 0.0f); });
    const Image red = runner.run_ports({{"image", f}, {"environment", red_env}}).image("color");
    int redder = 0;
    for (int y = 0; y < red.height(); ++y) {
        for (int x = 0; x < red.width(); ++x) {
            ASSERT_LE(red.at(x, y, 2), sky_out.at(x, y, 2) + 1e-6f) << x << "," << y;
            redder += red.at(x, y, 0) > sky_out.at(x, y, 0) + 1e-3f ? 1 : 0;
        }
    }
    EXPECT_GT(redder, red.width() * red.height() / 20);
}

TEST(Ssr, EnvironmentInputNamesWhatIsWrong)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 48, 27);
    Frame env = environment_frame(32, 16, [](const glm::vec3 &) { return glm::vec3(1.0f); });
    auto expect_error = [&](const Frame &e, const std::string &params, const std::string &needle) {
        try {
            test::NodeRunner("ssr", params).run_ports({{"image", f}, {"environment", e}});
            ADD_FAILURE() << "no error for " << needle;
        } catch (const Error &err) {
            EXPECT_NE(std::string(err.what()).find(needle), std::string::npos) << err.what();
        }
    };
    Frame two = env;
    two.set("color", Image(32, 16, 2), {"R", "G"});
    expect_error(two, "{}", "environment");
    // Distances without the position they were taken from.
    Frame with_depth = env;
    with_depth.set("depth", Image(32, 16, 1));
    expect_error(with_depth, "{}", "environment_position");
    // ... which the parameter gives, or parallax off ignores.
    const Image ok = test::NodeRunner("ssr", R"({"environment_position": [10, 5, 10]})")
                         .run_ports({{"image", f}, {"environment", with_depth}})
                         .image("color");
    EXPECT_EQ(ok.width(), 48);
    test::NodeRunner("ssr", R"({"parallax": false})")
        .run_ports({{"image", f}, {"environment", with_depth}});
    expect_error(env, R"({"sun_irradiance": [-1, 0, 0]})", "sun_irradiance");
}

TEST(Ssr, NodeNamesWhatIsMissing)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    const Frame f = glossy_frame(s, 48, 27);
    auto expect_error = [](const Frame &in, const std::string &needle) {
        try {
            test::run_node("ssr", in, "{}");
            ADD_FAILURE() << "no error for " << needle;
        } catch (const Error &e) {
            EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
        }
    };
    for (const char *pass : {"albedo", "normal", "depth"}) {
        Frame missing = f;
        missing.erase(pass);
        expect_error(missing, pass);
    }
    Frame no_camera = f;
    no_camera.camera = Camera{};
    expect_error(no_camera, "worldTo");
    // Passes of another size never reach the node: the frame refuses them, naming the pass.
    Frame wrong_size = f;
    try {
        wrong_size.set("material", Image(24, 27, 3), f.pass("material").channels);
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("material"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace posthaste
