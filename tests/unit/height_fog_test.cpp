#include "shading/fog/height_fog.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>

#include "core/camera.h"
#include "core/parallel.h"

namespace posthaste::shading {
namespace {

// Brute force: midpoint rule in double over [t0, distance] with `steps` steps. When the
// density decays along the ray (k > 0) the interval is cut where exp(-k t) < exp(-50), which drops
// a relative 2e-22 of the integral and keeps the step size small against 1 / k.
double numeric_optical_depth(
    const HeightFog &fog, const glm::dvec3 &c, const glm::dvec3 &d, double distance, int steps)
{
    const double t0 = fog.start_distance;
    double t1 = distance;
    const double k = double(fog.falloff) * d.y;
    if (k > 0.0) {
        t1 = std::min(t1, t0 + 50.0 / k);
    }
    if (!(t1 > t0)) {
        return 0.0;
    }
    const double dt = (t1 - t0) / steps;
    double sum = 0.0;
    for (int i = 0; i < steps; ++i) {
        const double y = c.y + (t0 + (i + 0.5) * dt) * d.y;
        sum += double(fog.density) * std::exp(-double(fog.falloff) * (y - fog.base_height));
    }
    return sum * dt;
}

glm::dvec3 direction_with_y(double dy)
{
    const double horizontal = std::sqrt(std::max(0.0, 1.0 - dy * dy));
    return {horizontal * 0.6, dy, horizontal * 0.8};
}

TEST(HeightFog, AnalyticMatchesNumericIntegration)
{
    const float falloffs[] = {0.1f, 0.01f, 1e-4f, 1e-7f};
    const float base_heights[] = {0.0f, 10.0f};
    const double camera_heights[] = {-50.0, 0.0, 5.0, 100.0, 2000.0};
    const double dys[] = {0.0, 1e-6, -1e-6, 1e-3, -1e-3, 0.1, -0.1, 0.7, -0.7, 1.0, -1.0};
    const double distances[] = {1.0, 100.0, 1e4, 1e7};
    const float starts[] = {0.0f, 5.0f};
    double max_rel = 0.0;
    int compared = 0;
    for (float b : falloffs) {
        for (float h0 : base_heights) {
            for (double cy : camera_heights) {
                for (double dy : dys) {
                    for (double s : distances) {
                        for (float start : starts) {
                            HeightFog fog;
                            fog.density = 0.05f;
                            fog.falloff = b;
                            fog.base_height = h0;
                            fog.start_distance = start;
                            const glm::dvec3 c(3.0, cy, -7.0);
                            const glm::dvec3 d = direction_with_y(dy);
                            const double ref = numeric_optical_depth(fog, c, d, s, 100000);
                            // Only values a float can hold and that matter for exp(-tau).
                            if (!(ref > 1e-30 && ref < 1e30)) {
                                continue;
                            }
                            const float got =
                                height_fog_optical_depth(fog, glm::vec3(c), glm::vec3(d), float(s));
                            const double rel = std::fabs(got - ref) / ref;
                            max_rel = std::max(max_rel, rel);
                            ++compared;
                            EXPECT_LE(rel, 1e-5) << "b " << b << " h0 " << h0 << " cy " << cy
                                                 << " dy " << dy << " s " << s << " start " << start
                                                 << " ref " << ref << " got " << got;
                        }
                    }
                }
            }
        }
    }
    std::printf("[ measured ] height fog vs 100k-step midpoint: %d rays, max rel error %.3g\n",
                compared,
                max_rel);
    EXPECT_GT(compared, 1000);
}

TEST(HeightFog, HorizontalRayIsExactlyUniform)
{
    HeightFog fog;
    fog.density = 0.03f;
    fog.falloff = 0.2f;
    fog.base_height = 2.0f;
    const glm::vec3 c(0.0f, 2.0f, 0.0f);
    const glm::vec3 d(1.0f, 0.0f, 0.0f);
    EXPECT_FLOAT_EQ(height_fog_optical_depth(fog, c, d, 1e7f), 0.03f * 1e7f);
    EXPECT_FLOAT_EQ(height_fog_optical_depth(fog, c, d, 10.0f), 0.3f);
}

TEST(HeightFog, FalloffToZeroLimit)
{
    // b -> 0 becomes uniform fog of density a: tau = a * s.
    HeightFog fog;
    fog.density = 0.01f;
    fog.base_height = 0.0f;
    const glm::vec3 c(0.0f, 30.0f, 0.0f);
    const glm::vec3 d = glm::normalize(glm::vec3(0.3f, -0.5f, 0.2f));
    for (float b : {1e-6f, 1e-9f, 1e-12f, 0.0f}) {
        fog.falloff = b;
        const float tau = height_fog_optical_depth(fog, c, d, 20.0f);
        EXPECT_NEAR(tau, 0.2f, 0.2f * 1e-4f) << "b " << b;
    }
    fog.falloff = 0.0f;
    EXPECT_FLOAT_EQ(height_fog_optical_depth(fog, c, d, 20.0f), 0.2f);
}

TEST(HeightFog, ZeroDensityGivesExactlyZero)
{
    HeightFog fog;
    fog.density = 0.0f;
    for (float dy : {-1.0f, 0.0f, 1.0f}) {
        const glm::vec3 d = glm::vec3(direction_with_y(dy));
        EXPECT_EQ(height_fog_optical_depth(fog, glm::vec3(0, -1000, 0), d, 1e7f), 0.0f);
        EXPECT_EQ(height_fog_optical_depth(fog, glm::vec3(0, -1000, 0), d, INFINITY), 0.0f);
        const FogResult r = height_fog(prepare_height_fog(fog, glm::vec3(0.0f)), d, 1e7f);
        EXPECT_EQ(r.transmittance, 1.0f);
        EXPECT_EQ(r.inscatter, glm::vec3(0.0f));
    }
}

TEST(HeightFog, StartDistanceAndInfiniteDistance)
{
    HeightFog fog;
    fog.density = 0.02f;
    fog.falloff = 0.05f;
    fog.start_distance = 50.0f;
    fog.opaque_sky = false;  // the infinite ray's fog, not the sky's radiance
    const glm::vec3 c(0.0f, 1.0f, 0.0f);
    const glm::vec3 up = glm::normalize(glm::vec3(1.0f, 1.0f, 0.0f));
    EXPECT_EQ(height_fog_optical_depth(fog, c, up, 49.0f), 0.0f);
    EXPECT_EQ(height_fog_optical_depth(fog, c, up, 50.0f), 0.0f);
    // Infinite distance upwards: the integral from the start converges.
    const double k = 0.05 * up.y;
    const double expected = 0.02 * std::exp(-0.05 * (1.0 + 50.0 * up.y)) / k;
    EXPECT_NEAR(height_fog_optical_depth(fog, c, up, INFINITY), expected, expected * 1e-5);
    // Horizontal or down to infinity: all light is absorbed.
    const FogResult r = height_fog(prepare_height_fog(fog, c), glm::vec3(1, 0, 0), INFINITY);
    EXPECT_EQ(r.transmittance, 0.0f);
    EXPECT_EQ(r.inscatter, fog.color);
}

TEST(HeightFog, NonFiniteInputsGiveFiniteOutput)
{
    HeightFog fog;
    fog.sun_color = glm::vec3(1.0f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const HeightFogCamera c = prepare_height_fog(fog, glm::vec3(0.0f, 1.0f, 0.0f));
    for (const glm::vec3 d : {glm::vec3(nan), glm::vec3(0, 1, 0), glm::vec3(0, -1, 0)}) {
        for (float s : {nan, -1.0f, 0.0f, 10.0f, INFINITY, -INFINITY}) {
            const FogResult r = height_fog(c, d, s);
            EXPECT_TRUE(std::isfinite(r.transmittance)) << s;
            EXPECT_GE(r.transmittance, 0.0f);
            EXPECT_LE(r.transmittance, 1.0f);
            EXPECT_TRUE(std::isfinite(r.inscatter.x + r.inscatter.y + r.inscatter.z)) << s;
        }
    }
    // NaN distance or direction: documented as no fog.
    EXPECT_EQ(height_fog(c, glm::vec3(nan), 10.0f).transmittance, 1.0f);
    EXPECT_EQ(height_fog(c, glm::vec3(0, 1, 0), nan).transmittance, 1.0f);
    // NaN parameters disable the fog.
    fog.falloff = nan;
    EXPECT_TRUE(prepare_height_fog(fog, glm::vec3(0.0f)).empty);
    // Overflow looking far down into dense fog: transmittance 0, not NaN.
    HeightFog dense;
    dense.density = 1.0f;
    dense.falloff = 1.0f;
    const FogResult r =
        height_fog(prepare_height_fog(dense, glm::vec3(0.0f)), glm::vec3(0, -1, 0), 1e6f);
    EXPECT_EQ(r.transmittance, 0.0f);
}

TEST(HeightFog, SunLobeIsHenyeyGreenstein)
{
    // HG integrates to 1 over the sphere.
    double sum = 0.0;
    const int n = 20000;
    for (int i = 0; i < n; ++i) {
        const float mu = -1.0f + 2.0f * (i + 0.5f) / n;
        sum += henyey_greenstein_phase(mu, 0.7f) * 2.0 * M_PI * (2.0 / n);
    }
    EXPECT_NEAR(sum, 1.0, 1e-3);
    HeightFog fog;
    fog.falloff = 0.0f;
    fog.density = 0.1f;
    fog.color = glm::vec3(0.0f);
    fog.sun_color = glm::vec3(1.0f);
    fog.sun_direction = glm::vec3(1, 0, 0);
    const HeightFogCamera c = prepare_height_fog(fog, glm::vec3(0.0f));
    const FogResult towards = height_fog(c, glm::vec3(1, 0, 0), 10.0f);
    const FogResult away = height_fog(c, glm::vec3(-1, 0, 0), 10.0f);
    EXPECT_GT(towards.inscatter.x, 10.0f * away.inscatter.x);
    fog.sun_g = 0.0f;
    const FogResult iso =
        height_fog(prepare_height_fog(fog, glm::vec3(0.0f)), glm::vec3(0, 0, 1), 10.0f);
    EXPECT_NEAR(iso.inscatter.x, 1.0f - iso.transmittance, 1e-6f);
}

TEST(HeightFog, ClassicFogFactors)
{
    EXPECT_EQ(linear_fog_factor(5.0f, 10.0f, 20.0f), 1.0f);
    EXPECT_FLOAT_EQ(linear_fog_factor(15.0f, 10.0f, 20.0f), 0.5f);
    EXPECT_EQ(linear_fog_factor(25.0f, 10.0f, 20.0f), 0.0f);
    EXPECT_EQ(linear_fog_factor(15.0f, 10.0f, 10.0f), 0.0f);
    EXPECT_EQ(linear_fog_factor(NAN, 10.0f, 20.0f), 1.0f);
    EXPECT_FLOAT_EQ(exp_fog_factor(10.0f, 0.1f), std::exp(-1.0f));
    EXPECT_FLOAT_EQ(exp2_fog_factor(10.0f, 0.1f), std::exp(-1.0f));
    EXPECT_FLOAT_EQ(exp2_fog_factor(20.0f, 0.1f), std::exp(-4.0f));
    EXPECT_EQ(exp_fog_factor(INFINITY, 0.1f), 0.0f);
    EXPECT_EQ(exp_fog_factor(NAN, 0.1f), 1.0f);
    EXPECT_EQ(exp2_fog_factor(-3.0f, 0.1f), 1.0f);
}

TEST(HeightFog, ApplyToFrameMatchesPerPixel)
{
    const int w = 16, h = 8;
    const glm::mat4 camera_to_world = glm::mat4(1.0f);  // at origin looking +z
    glm::mat4 c2w = camera_to_world;
    c2w[3] = glm::vec4(0.0f, 3.0f, 0.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(c2w, 35.0f, 36.0f, float(w) / h, 0.1f);
    const CameraRays rays(m.world_to_camera, m.world_to_ndc);
    Image depth(w, h, 1), color(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            depth.at(x, y, 0) = x == 0 ? INFINITY : 5.0f + float(x * y);
            for (int ch = 0; ch < 4; ++ch) {
                color.at(x, y, ch) = 0.25f * float(ch);
            }
        }
    }
    HeightFog fog;
    fog.density = 0.05f;
    fog.sun_color = glm::vec3(0.3f);
    fog.sun_direction = glm::normalize(glm::vec3(0.2f, 0.3f, 1.0f));
    Image out = color;
    set_thread_count(1);
    apply_height_fog(fog, rays, depth, out);
    Image out2 = color;
    set_thread_count(2);
    apply_height_fog(fog, rays, depth, out2);
    set_thread_count(0);
    EXPECT_TRUE(out.bit_equal(out2));
    const HeightFogCamera c = prepare_height_fog(fog, glm::vec3(0.0f, 3.0f, 0.0f));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float u = (x + 0.5f) / w, v = (y + 0.5f) / h;
            // The ray through a pixel centre, rebuilt from the projection by hand.
            const float sx = 35.0f / 36.0f, sy = sx * float(w) / h;
            const glm::vec3 p((u - 0.5f) / sx, -(v - 0.5f) / sy, 1.0f);
            const float dist = depth.at(x, y, 0) * glm::length(p);
            const FogResult f = height_fog(c, glm::normalize(p), dist);
            EXPECT_NEAR(
                out.at(x, y, 1), color.at(x, y, 1) * f.transmittance + f.inscatter.y, 1e-5f);
            EXPECT_EQ(out.at(x, y, 3), color.at(x, y, 3));
        }
    }
}

}  // namespace
}  // namespace posthaste::shading
