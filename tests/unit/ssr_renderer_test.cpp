// ssr on a production renderer's frames: the reflections weighed as a physically based GGX
// lobe (brdf ggx) and replacing the renderer's world (the world input) instead of the
// rasterizer's Schlick-times-gloss term and sky model; their bits on every target and thread
// count. Measured against Cycles in
// tests/accuracy/cycles_test.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/camera_rays.h"
#include "shading/lighting/env_brdf.h"
#include "shading/lighting/lighting.h"
#include "shading/ssr/environment.h"
#include "test_util.h"

namespace posthaste {
namespace {
using test::render_options;
using test::rms_rgb;
using test::scene_path;

Frame glossy(int w, int h)
{
    raster::Scene s = raster::load_scene(scene_path("glossy.json"));
    return raster::render_frame(
        s, 1, render_options(w, h, {"color", "depth", "normal", "albedo", "material", "position"}));
}

Frame constant_world(const glm::vec3 &c)
{
    Image map(32, 16, 4);
    for (int y = 0; y < 16; ++y) {
        for (int x = 0; x < 32; ++x) {
            for (int k = 0; k < 3; ++k) {
                map.at(x, y, k) = c[k];
            }
            map.at(x, y, 3) = 1.0f;
        }
    }
    Frame env;
    env.set_size(32, 16);
    env.set("color", std::move(map));
    return env;
}

TEST(SsrRenderer, AWorldTheColourReflectsAlreadyIsNotAddedTwice)
{
    // Rays too short to meet anything see the environment. Where the colour pass reflects that
    // world already (the same map as the world input) nothing changes; against the sky model,
    // the world's difference from the sky is added; against another world, the difference
    // between the two, weighed by each pixel's Fresnel and gloss.
    const Frame f = glossy(96, 54);
    const Frame world = constant_world(glm::vec3(2.0f, 0.5f, 0.25f));
    const test::NodeRunner runner("ssr", R"({"max_distance": 0.001})");
    const Image kept =
        runner.run_ports({{"image", f}, {"environment", world}, {"world", world}}).image("color");
    EXPECT_LT(rms_rgb(kept, f.image("color")), 1e-6);
    const Image added = runner.run_ports({{"image", f}, {"environment", world}}).image("color");
    EXPECT_GT(rms_rgb(added, f.image("color")), 0.01);
    // Another world W: out = in + w (E - W), w each pixel's weight. So out(W1) - out(W2) =
    // w (W2 - W1) whatever w: against grey 1 and grey 0.5, (2, 0.5, 0.25) moves each channel
    // by (1, -0.5, -0.75) / -0.5 times what 0.5 does.
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
    for (int y = 0; y < finite.height(); ++y) {
        for (int x = 0; x < finite.width(); ++x) {
            for (int c = 0; c < 4; ++c) {
                ASSERT_TRUE(std::isfinite(finite.at(x, y, c))) << x << "," << y;
            }
        }
    }
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
    const Frame f = glossy(96, 54);
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
    // brdf ggx picks and weighs its pixels in scalar code; the march and the resolve's window
    // stay on the kernels: the scalar reference's bits on every Highway target.
    const Frame f = glossy(101, 57);
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

}  // namespace
}  // namespace posthaste
