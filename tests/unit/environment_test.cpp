// Environment maps and reflection probes: the latitude-longitude layout (directions and back,
// its polynomial arctangent, the bilinear lookup, the seam), the probe's parallax against a closed
// form, the probe the renderer traces (distances to a known floor, the sky where rays leave), and
// the renderer's shadow pass (lit and shadowed points of a hand-built scene).

#include "shading/ssr/environment.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>

#include "core/passes.h"
#include "raster/ray_cast.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/fast_math.h"
#include "test_util.h"

namespace posthaste {
namespace {

TEST(Environment, LatLongLayoutAndItsInverse)
{
    // The middle of the map looks down -z, u grows toward +x, the top row is straight up.
    const glm::vec2 ahead = shading::latlong_uv({0.0f, 0.0f, -1.0f});
    EXPECT_NEAR(ahead.x, 0.5f, 1e-6f);
    EXPECT_NEAR(ahead.y, 0.5f, 1e-6f);
    EXPECT_NEAR(shading::latlong_uv({1.0f, 0.0f, 0.0f}).x, 0.75f, 1e-6f);
    EXPECT_NEAR(shading::latlong_uv({-1.0f, 0.0f, 0.0f}).x, 0.25f, 1e-6f);
    EXPECT_NEAR(shading::latlong_uv({0.0f, 1.0f, 0.0f}).y, 0.0f, 1e-6f);
    EXPECT_NEAR(shading::latlong_uv({0.0f, -1.0f, 0.0f}).y, 1.0f, 1e-6f);
    for (const glm::vec3 d : {glm::vec3(0.3f, 0.5f, -0.8f),
                              glm::vec3(-0.9f, -0.2f, 0.4f),
                              glm::vec3(0.1f, 0.95f, 0.3f),
                              glm::vec3(-0.2f, -0.1f, -0.97f)}) {
        const glm::vec3 n = glm::normalize(d);
        const glm::vec2 uv = shading::latlong_uv(n);
        EXPECT_LT(glm::length(shading::latlong_direction(uv.x, uv.y) - n), 1e-5f);
    }
}

TEST(Environment, FastArctangentMatchesLibm)
{
    float max_err = 0.0f;
    for (int i = 0; i < 100000; ++i) {
        const float a = 6.2831853f * float(i) / 100000.0f;
        for (const float r : {1e-3f, 1.0f, 1e3f}) {
            const float y = r * std::sin(a), x = r * std::cos(a);
            max_err = std::max(max_err, std::fabs(shading::fast_atan2(y, x) - std::atan2(y, x)));
        }
    }
    EXPECT_LE(max_err, 1e-6f);
    EXPECT_EQ(shading::fast_atan2(0.0f, 0.0f), 0.0f);
    EXPECT_NEAR(shading::fast_atan2(0.0f, -1.0f), 3.14159265f, 1e-6f);
    EXPECT_NEAR(shading::fast_atan2(-1.0f, 0.0f), -1.5707963f, 1e-6f);
}

TEST(Environment, BilinearLookupWrapsAroundTheSeam)
{
    // An 8x4 map whose red is the column and green the row.
    Image map(8, 4, 3);
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 8; ++x) {
            map.at(x, y, 0) = float(x);
            map.at(x, y, 1) = float(y);
        }
    }
    const shading::LatLongMap env(map);
    // At a texel's centre: that texel.
    const glm::vec3 c = env.radiance(shading::latlong_direction(2.5f / 8.0f, 1.5f / 4.0f));
    EXPECT_NEAR(c.x, 2.0f, 1e-4f);
    EXPECT_NEAR(c.y, 1.0f, 1e-4f);
    // Halfway between two columns and two rows: their mean.
    const glm::vec3 m = env.radiance(shading::latlong_direction(3.0f / 8.0f, 2.0f / 4.0f));
    EXPECT_NEAR(m.x, 2.5f, 1e-4f);
    EXPECT_NEAR(m.y, 1.5f, 1e-4f);
    // Across the seam (u = 0 = 1): the last and the first column, half each.
    const glm::vec3 seam = env.radiance(shading::latlong_direction(0.0f, 1.5f / 4.0f));
    EXPECT_NEAR(seam.x, 3.5f, 1e-4f);
    // Straight up: the top row (clamped), whatever the column.
    const glm::vec3 up = env.radiance({0.0f, 1.0f, 0.0f});
    EXPECT_NEAR(up.y, 0.0f, 1e-4f);
}

TEST(Environment, ProbeParallaxMeetsTheSurfaceWhereTheRayCrossesIt)
{
    // A probe at the origin inside a sphere of radius 10 whose radiance is its height (green =
    // y + 1 of the direction): a ray from (0, -5, 0) along +x meets the sphere at
    // (sqrt(75), -5, 0), seen from the probe 30 degrees below the horizon (y = -0.5).
    const int w = 256, h = 128;
    Image radiance(w, h, 3), distance(w, h, 1);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec3 d = shading::latlong_direction((float(x) + 0.5f) / float(w),
                                                           (float(y) + 0.5f) / float(h));
            radiance.at(x, y, 1) = d.y + 1.0f;
            distance.at(x, y, 0) = 10.0f;
        }
    }
    shading::Probe probe;
    probe.radiance = &radiance;
    probe.position = glm::vec3(0.0f);
    probe.max_distance = 40.0f;
    probe.march_steps = 32;
    probe.refine_steps = 8;
    const glm::vec3 origin(0.0f, -5.0f, 0.0f), east(1.0f, 0.0f, 0.0f);
    // No distances: everything infinitely far, the ray's own direction (the horizon).
    EXPECT_NEAR(probe.seen(origin, east).y, 1.0f, 0.01f);
    const shading::DistanceCube cube(distance);
    EXPECT_EQ(cube.size(), 64);
    EXPECT_EQ(cube.reach(), 10.0f);
    EXPECT_EQ(cube.at({0.3f, -7.0f, 2.0f}), 10.0f);
    probe.distance = &cube;
    EXPECT_NEAR(probe.seen(origin, east).y, 0.5f, 0.01f);
    // Looking down from (0, -5, 0): the sphere's bottom (y = -1).
    EXPECT_NEAR(probe.seen(origin, {0.0f, -1.0f, 0.0f}).y, 0.0f, 0.01f);
    // A ray that cannot reach the surface within max_distance sees its own direction.
    probe.max_distance = 5.0f;
    EXPECT_NEAR(probe.seen(origin, east).y, 1.0f, 0.01f);
    // The sky (+inf distance; NaN reads as the sky) is infinitely far: no parallax.
    probe.max_distance = 40.0f;
    for (std::size_t i = 0; i < distance.value_count(); ++i) {
        distance.data()[i] = i % 2 ? std::numeric_limits<float>::infinity()
                                   : std::numeric_limits<float>::quiet_NaN();
    }
    const shading::DistanceCube sky(distance);
    EXPECT_EQ(sky.reach(), 0.0f);
    probe.distance = &sky;
    EXPECT_NEAR(probe.seen(origin, east).y, 1.0f, 0.01f);
}

/// A direction toward each face of a cube (+x, -x, +y, -y, +z, -z), of various lengths.
const glm::vec3 kOneOnEachFace[] = {glm::vec3(1, 0.2f, -0.3f),
                                    glm::vec3(-1, 0.1f, 0.4f),
                                    glm::vec3(0.2f, 2, 0.1f),
                                    glm::vec3(-0.3f, -3, 0.2f),
                                    glm::vec3(0.1f, -0.4f, 1),
                                    glm::vec3(0.3f, 0.2f, -5)};

TEST(Environment, DistanceCubeFacesHoldTheirDirections)
{
    // A map whose distance is 1 + the index of the direction's major axis and sign (+x 1, -x
    // 2, +y 3, -y 4, +z 5, -z 6), sampled at texel centres: each face of the cube holds its own.
    const int w = 128, h = 64;
    Image distance(w, h, 1);
    const auto face_of = [](const glm::vec3 &d) {
        const glm::vec3 a = glm::abs(d);
        const int m = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
        return 2 * m + (d[m] >= 0.0f ? 0 : 1);
    };
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            distance.at(x, y, 0) =
                float(1 + face_of(shading::latlong_direction((float(x) + 0.5f) / float(w),
                                                             (float(y) + 0.5f) / float(h))));
        }
    }
    const shading::DistanceCube cube(distance);
    EXPECT_EQ(cube.size(), 32);
    for (const glm::vec3 &d : kOneOnEachFace) {
        EXPECT_EQ(cube.at(d), float(1 + face_of(d))) << d.x << "," << d.y << "," << d.z;
        EXPECT_EQ(cube.at(d * 100.0f), cube.at(d));  // any length
    }
    EXPECT_EQ(cube.reach(), 6.0f);
}

TEST(Environment, ACubeFromDirectionsHoldsEachTexelsCentre)
{
    // Each texel holds the unit direction through its centre; any direction reads the texel
    // it passes through, whose centre lies within half a texel's diagonal of it.
    constexpr int n = 8;
    const auto cube =
        shading::LatLongCube<glm::vec3>::from_directions(n, [](const glm::vec3 &d) { return d; });
    EXPECT_EQ(cube.size(), n);
    // A texel's centre on face +x: (1, -1 + (i + 0.5) 2 / n, ...) for y then z.
    const glm::vec3 centre =
        glm::normalize(glm::vec3(1.0f, -1.0f + 2.5f * 2.0f / n, -1.0f + 6.5f * 2.0f / n));
    EXPECT_NEAR(glm::length(cube.at(centre) - centre), 0.0f, 1e-6f);
    EXPECT_NEAR(glm::length(cube.at(centre * 7.0f) - centre), 0.0f, 1e-6f);  // any length
    // Half a texel's diagonal at a face's centre, where texels are widest: atan(sqrt(2) / n).
    const float half_diagonal = std::atan(std::sqrt(2.0f) / n);
    for (const glm::vec3 &d : kOneOnEachFace) {
        const glm::vec3 u = glm::normalize(d), got = cube.at(d);
        EXPECT_NEAR(glm::length(got), 1.0f, 1e-6f);
        EXPECT_LE(std::acos(std::min(1.0f, glm::dot(got, u))), half_diagonal)
            << d.x << "," << d.y << "," << d.z;
    }
}

/// A 64 x 8 x 64 voxel world with a floor (top at y = 1) and, with `block`, a 5 x 1 x 5 slab
/// floating over [30, 35]^2 at y 5 to 6; the sun straight overhead, the camera above the floor.
raster::Scene floor_scene(bool block)
{
    raster::Scene s;
    s.world.nx = s.world.nz = 64;
    s.world.ny = 8;
    s.world.cells.assign(64 * 8 * 64, 0);
    for (int z = 0; z < 64; ++z) {
        for (int x = 0; x < 64; ++x) {
            s.world.set(x, 0, z, 1);
        }
    }
    if (block) {
        for (int z = 30; z < 35; ++z) {
            for (int x = 30; x < 35; ++x) {
                s.world.set(x, 5, z, 1);
            }
        }
    }
    raster::Material m;
    m.id = 1;
    m.albedo = glm::vec3(0.5f);
    m.roughness = 0.5f;
    s.materials = {m};
    s.sun.direction = glm::normalize(glm::vec3(0.0f, 1.0f, 0.001f));
    raster::CameraKey key;
    key.position = glm::vec3(32.0f, 8.0f, 24.0f);  // looking toward +z
    key.pitch_deg = -45.0f;
    key.focal_length_mm = 18.0f;
    s.camera_keys = {key};
    return s;
}

TEST(Environment, RenderedProbeSeesTheFloorAtItsDistanceAndTheSkyAbove)
{
    const raster::Scene s = floor_scene(false);
    const raster::EnvironmentProbe probe = raster::render_environment_probe(s, 1, 64, 32, 4, 1);
    EXPECT_EQ(probe.position, glm::vec3(32.0f, 8.0f, 24.0f));
    ASSERT_EQ(probe.color.channels(), 4);
    const shading::SceneSky &sky = shading::scene_sky(s.sun.direction);
    const glm::vec3 sky_camera(0.0f, shading::kSkyCameraY, 0.0f);
    for (int y = 0; y < 32; ++y) {
        for (int x = 0; x < 64; ++x) {
            for (int c = 0; c < 4; ++c) {
                ASSERT_TRUE(std::isfinite(probe.color.at(x, y, c)));
            }
            EXPECT_EQ(probe.color.at(x, y, 3), 1.0f);
            const glm::vec3 d =
                shading::latlong_direction((float(x) + 0.5f) / 64.0f, (float(y) + 0.5f) / 32.0f);
            const float dist = probe.distance.at(x, y, 0);
            if (d.y > 0.0f) {
                // Above the horizon: nothing (the world has no walls), the sky times the
                // scene's sky_ambient.
                EXPECT_EQ(dist, std::numeric_limits<float>::infinity());
                const glm::vec3 want = sky.radiance(d, sky_camera, false) * s.sky_ambient;
                EXPECT_NEAR(probe.color.at(x, y, 2), want.z, 0.1f * want.z + 1e-3f);
            } else if (d.y < -0.5f) {
                // Steeply down: the floor, 7 below the probe.
                EXPECT_NEAR(dist, 7.0f / -d.y, 1e-3f) << x << "," << y;
            }
        }
    }
}

TEST(Environment, ShadowPassIsZeroUnderTheBlockAndOneInTheOpen)
{
    const raster::Scene s = floor_scene(true);
    const Frame f = raster::render_frame(
        s, 1, test::render_options(96, 64, {"shadow", "position", "depth", "color"}));
    const Image &shadow = f.image(pass::kShadow), &pos = f.image(pass::kPosition),
                &depth = f.image(pass::kDepth);
    int under = 0, open = 0;
    for (int y = 0; y < shadow.height(); ++y) {
        for (int x = 0; x < shadow.width(); ++x) {
            const float v = shadow.at(x, y, 0);
            ASSERT_GE(v, 0.0f);
            ASSERT_LE(v, 1.0f);
            if (!std::isfinite(depth.at(x, y, 0))) {
                EXPECT_EQ(v, 0.0f);  // the sky
                continue;
            }
            const glm::vec3 p(pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2));
            if (std::abs(p.y - 1.0f) > 1e-3f) {
                continue;  // not the floor
            }
            // The block's shadow falls straight down onto [30, 35]^2 of the floor.
            if (p.x > 31.0f && p.x < 34.0f && p.z > 31.0f && p.z < 34.0f) {
                EXPECT_EQ(v, 0.0f) << p.x << "," << p.z;
                ++under;
            } else if (p.x < 28.0f || p.x > 37.0f || p.z < 28.0f || p.z > 37.0f) {
                EXPECT_EQ(v, 1.0f) << p.x << "," << p.z;
                ++open;
            }
        }
    }
    EXPECT_GT(under, 10);
    EXPECT_GT(open, 100);
}

}  // namespace
}  // namespace posthaste
