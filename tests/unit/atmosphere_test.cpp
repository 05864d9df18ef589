#include "shading/atmosphere/atmosphere.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <glm/trigonometric.hpp>
#include <limits>
#include <random>

#include "core/camera.h"
#include "core/error.h"
#include "core/parallel.h"

namespace posthaste::shading {
namespace {

glm::vec3 sun_at_elevation(float elevation_deg, float azimuth_deg = 0.0f)
{
    const float e = glm::radians(elevation_deg), a = glm::radians(azimuth_deg);
    return {std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a)};
}

const Atmosphere &atmosphere_with_sun(float elevation_deg)
{
    // Built once per elevation used by the tests (immutable and thread-safe afterwards).
    static std::vector<std::pair<float, std::unique_ptr<Atmosphere>>> cache;
    for (const auto &[e, a] : cache) {
        if (e == elevation_deg) {
            return *a;
        }
    }
    AtmosphereParams p;
    p.sun_direction = sun_at_elevation(elevation_deg);
    cache.emplace_back(elevation_deg, std::make_unique<Atmosphere>(p));
    return *cache.back().second;
}

float max_component(const glm::vec3 &v)
{
    return std::max(v.x, std::max(v.y, v.z));
}

bool finite_non_negative(const glm::vec3 &v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z) && v.x >= 0.0f &&
           v.y >= 0.0f && v.z >= 0.0f;
}

TEST(Atmosphere, FastAcosMatchesLibm)
{
    float max_err = 0.0f;
    for (int i = 0; i <= 200000; ++i) {
        const float x = -1.0f + 2.0f * float(i) / 200000.0f;
        max_err = std::max(max_err, std::fabs(fast_acos(x) - std::acos(x)));
    }
    EXPECT_LE(max_err, 1e-6f);
    EXPECT_EQ(fast_acos(std::numeric_limits<float>::quiet_NaN()), 0.0f);
}

TEST(Atmosphere, FastExpMatchesLibm)
{
    double max_rel = 0.0;
    for (int i = 0; i <= 400000; ++i) {
        const float x = -87.0f + 175.0f * float(i) / 400000.0f;
        const double ref = std::exp(double(x));
        max_rel = std::max(max_rel, std::fabs(fast_exp(x) - ref) / ref);
    }
    std::printf("[ measured ] fast_exp max rel error %.3g\n", max_rel);
    EXPECT_LE(max_rel, 3e-7);
    EXPECT_EQ(fast_exp(-100.0f), 0.0f);
    EXPECT_EQ(fast_exp(100.0f), INFINITY);
    EXPECT_EQ(fast_exp(0.0f), 1.0f);
    EXPECT_TRUE(std::isnan(fast_exp(std::numeric_limits<float>::quiet_NaN())));
}

TEST(Atmosphere, TransmittanceLutMatchesNumericOpticalDepth)
{
    const Atmosphere &atmo = atmosphere_with_sun(30.0f);
    const float altitudes[] = {0.0f, 1.0f, 100.0f, 1000.0f, 8000.0f, 30000.0f, 99000.0f};
    double max_rel = 0.0, max_abs = 0.0;
    for (float h : altitudes) {
        const double r = 6360e3 + h;
        const float mu_h = float(-std::sqrt(h * (2.0 * 6360e3 + h)) / r);
        for (float mu : {1.0f, 0.7f, 0.3f, 0.1f, 0.03f, 0.01f, 0.0f, mu_h + 1e-3f}) {
            if (mu < mu_h) {
                continue;
            }
            const glm::vec3 ref = glm::exp(-atmo.optical_depth_numeric(h, mu, 20000));
            const glm::vec3 got = atmo.transmittance_lut(h, mu);
            for (int c = 0; c < 3; ++c) {
                const double abs_err = std::fabs(got[c] - ref[c]);
                max_abs = std::max(max_abs, abs_err);
                if (ref[c] > 1e-3f) {
                    max_rel = std::max(max_rel, abs_err / ref[c]);
                }
                // Stated bound: 1% relative (where T > 1e-3) or 1e-4 absolute.
                EXPECT_LE(abs_err, std::max(1e-2 * ref[c], 1e-4)) << "h " << h << " mu " << mu;
            }
        }
    }
    std::printf(
        "[ measured ] transmittance LUT vs 20k-step optical depth: max rel %.3g (T > 1e-3), "
        "max abs %.3g\n",
        max_rel,
        max_abs);
}

TEST(Atmosphere, SkyViewLutMatchesRayMarch)
{
    // The cached LUT (camera at sky_view_y) for a high and a low sun, and a LUT built for a
    // camera 8 km up, whose horizon lies 2.9 degrees below the horizontal.
    struct Case {
        float sun_elevation, camera_y;
    };
    for (const Case k : {Case{45.0f, -1.0f}, Case{5.0f, -1.0f}, Case{20.0f, 8000.0f}}) {
        const float elevation = k.sun_elevation;
        const Atmosphere &atmo = atmosphere_with_sun(elevation);
        const glm::vec3 camera(
            0.0f, k.camera_y < 0.0f ? atmo.params().sky_view_y : k.camera_y, 0.0f);
        const SkyView own = atmo.make_sky_view(camera);
        const SkyView &sky = k.camera_y < 0.0f ? atmo.cached_sky_view() : own;
        const float horizon_deg = glm::degrees(std::asin(sky.mu_horizon()));
        double sum_sq = 0.0, sum_ref_sq = 0.0, max_rel = 0.0;
        int n = 0;
        for (int i = 0; i < 24; ++i) {
            for (int j = 0; j < 16; ++j) {
                const float azimuth = 360.0f * (i + 0.5f) / 24.0f;
                // Elevations from -60 to 85 degrees, denser near the horizon.
                const float s = -1.0f + 2.0f * (j + 0.5f) / 16.0f;
                const float view_elevation = s >= 0.0f ? 85.0f * s * s : 60.0f * -s * s;
                if (std::fabs(view_elevation - horizon_deg) < 0.5f) {
                    continue;  // the horizon itself is a discontinuity in the LUT's data
                }
                const glm::vec3 dir = sun_at_elevation(view_elevation, azimuth);
                const glm::vec3 got = sky.radiance(dir);
                const glm::vec3 ref = atmo.ray_march(camera, dir, INFINITY, 2000).inscatter;
                for (int c = 0; c < 3; ++c) {
                    const double e = got[c] - ref[c];
                    sum_sq += e * e;
                    sum_ref_sq += double(ref[c]) * ref[c];
                    max_rel = std::max(max_rel, std::fabs(e) / std::max(ref[c], 1e-6f));
                }
                ++n;
            }
        }
        const double rel_rmse = std::sqrt(sum_sq / sum_ref_sq);
        std::printf(
            "[ measured ] sky-view LUT vs 2000-step ray march, sun %.0f deg, camera y %.0f m: %d "
            "dirs, relative RMSE %.3g, max rel %.3g\n",
            elevation,
            camera.y,
            n,
            rel_rmse,
            max_rel);
        EXPECT_LE(rel_rmse, 0.005);
        EXPECT_LE(max_rel, 0.03);
    }
}

TEST(Atmosphere, AerialPerspectiveMatchesRayMarch)
{
    const Atmosphere &atmo = atmosphere_with_sun(20.0f);
    glm::mat4 c2w(1.0f);
    // Camera 30 m up, looking along +z and slightly down.
    const float pitch = glm::radians(-5.0f);
    c2w[1] = glm::vec4(0.0f, std::cos(pitch), std::sin(pitch), 0.0f);
    c2w[2] = glm::vec4(0.0f, -std::sin(pitch), std::cos(pitch), 0.0f);
    c2w[3] = glm::vec4(10.0f, 30.0f, -20.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(c2w, 24.0f, 36.0f, 16.0f / 9.0f, 0.1f);
    const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> uni(0.0f, 1.0f);
    double max_rel_l = 0.0, max_abs_t = 0.0, sum_sq = 0.0, sum_ref_sq = 0.0;
    int n = 0;
    for (int i = 0; i < 300; ++i) {
        const glm::vec2 uv(uni(rng), uni(rng));
        const float distance = 100.0f + 29900.0f * uni(rng) * uni(rng);
        const glm::vec3 dir = ap.rays().direction(uv.x, uv.y);
        const glm::vec3 end = ap.rays().position() + dir * distance;
        if (end.y < 0.0f) {
            continue;  // the reference stops at the planet, the froxels do not
        }
        const ScatteringResult got = ap.sample(uv, distance);
        const ScatteringResult ref = atmo.ray_march(ap.rays().position(), dir, distance, 1000);
        for (int c = 0; c < 3; ++c) {
            const double e = got.inscatter[c] - ref.inscatter[c];
            sum_sq += e * e;
            sum_ref_sq += double(ref.inscatter[c]) * ref.inscatter[c];
            max_rel_l = std::max(max_rel_l, std::fabs(e) / std::max(ref.inscatter[c], 1e-5f));
            max_abs_t =
                std::max(max_abs_t, double(std::fabs(got.transmittance[c] - ref.transmittance[c])));
        }
        ++n;
    }
    const double rel_rmse = std::sqrt(sum_sq / sum_ref_sq);
    std::printf(
        "[ measured ] aerial perspective (32^3 froxels) vs 1000-step ray march: %d points, "
        "in-scatter relative RMSE %.3g, max rel %.3g; transmittance max abs %.3g\n",
        n,
        rel_rmse,
        max_rel_l,
        max_abs_t);
    EXPECT_GT(n, 100);
    EXPECT_LE(rel_rmse, 0.01);
    EXPECT_LE(max_rel_l, 0.05);
    EXPECT_LE(max_abs_t, 0.01);
    // At the camera: nothing in front of the surface.
    const ScatteringResult zero = ap.sample(glm::vec2(0.5f), 0.0f);
    EXPECT_EQ(zero.inscatter, glm::vec3(0.0f));
    EXPECT_EQ(zero.transmittance, glm::vec3(1.0f));
}

TEST(Atmosphere, NumericSunTransmittanceAgreesWithLut)
{
    const Atmosphere &atmo = atmosphere_with_sun(10.0f);
    const glm::vec3 camera(0.0f, 2.0f, 0.0f);
    double max_rel = 0.0;
    for (float e : {2.0f, 10.0f, 45.0f, 90.0f}) {
        const glm::vec3 dir = sun_at_elevation(e, 60.0f);
        const glm::vec3 lut = atmo.ray_march(camera, dir, INFINITY, 200).inscatter;
        const glm::vec3 num = atmo.ray_march(camera, dir, INFINITY, 200, 2000).inscatter;
        for (int c = 0; c < 3; ++c) {
            max_rel = std::max(max_rel, double(std::fabs(lut[c] - num[c]) / num[c]));
        }
    }
    std::printf("[ measured ] ray march, LUT vs numeric sun transmittance: max rel %.3g\n",
                max_rel);
    EXPECT_LE(max_rel, 0.01);
}

TEST(Atmosphere, ZenithBluerThanHorizonAtNoon)
{
    const Atmosphere &atmo = atmosphere_with_sun(80.0f);
    const glm::vec3 camera(0.0f);
    const glm::vec3 zenith = atmo.sky_radiance(glm::vec3(0, 1, 0), camera, false);
    const glm::vec3 horizon = atmo.sky_radiance(sun_at_elevation(2.0f, 180.0f), camera, false);
    std::printf("[ measured ] noon B/R: zenith %.3f, horizon %.3f\n",
                zenith.z / zenith.x,
                horizon.z / horizon.x);
    EXPECT_GT(zenith.z / zenith.x, horizon.z / horizon.x);
    EXPECT_GT(zenith.z, zenith.y);
    EXPECT_GT(zenith.y, zenith.x);
}

TEST(Atmosphere, SunsetReddens)
{
    const Atmosphere &noon = atmosphere_with_sun(80.0f);
    const Atmosphere &sunset = atmosphere_with_sun(2.0f);
    const glm::vec3 camera(0.0f);
    // Direct sunlight.
    const glm::vec3 t_noon = noon.transmittance(camera, noon.sun_direction());
    const glm::vec3 t_set = sunset.transmittance(camera, sunset.sun_direction());
    EXPECT_GT(t_set.x / t_set.z, 2.0f * t_noon.x / t_noon.z);
    // The rasterizer's direct sunlight: the LUT value by day, 0 once the sun has set.
    const glm::vec3 at_noon = noon.sun_transmittance_at(camera);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(at_noon[c], t_noon[c], 1e-5f);
    }
    EXPECT_EQ(atmosphere_with_sun(-10.0f).sun_transmittance_at(camera), glm::vec3(0.0f));
    EXPECT_EQ(noon.sun_transmittance_at(glm::vec3(NAN)), glm::vec3(0.0f));
    // Sky near the sun.
    const glm::vec3 sky_noon = noon.sky_radiance(sun_at_elevation(70.0f), camera, false);
    const glm::vec3 sky_set = sunset.sky_radiance(sun_at_elevation(5.0f), camera, false);
    std::printf(
        "[ measured ] sun T R/B noon %.3f sunset %.3f; sky near sun R/B noon %.3f sunset "
        "%.3f\n",
        t_noon.x / t_noon.z,
        t_set.x / t_set.z,
        sky_noon.x / sky_noon.z,
        sky_set.x / sky_set.z);
    EXPECT_GT(sky_set.x / sky_set.z, sky_noon.x / sky_noon.z);
}

TEST(Atmosphere, SunBelowHorizonIsFiniteAndNonNegative)
{
    for (float e : {-1.0f, -10.0f, -90.0f}) {
        const Atmosphere &atmo = atmosphere_with_sun(e);
        const glm::vec3 camera(0.0f, 1.0f, 0.0f);
        float brightest = 0.0f;
        for (int i = 0; i < 64; ++i) {
            const glm::vec3 dir = sun_at_elevation(-80.0f + 170.0f * i / 63.0f, 37.0f * i);
            const glm::vec3 l = atmo.sky_radiance(dir, camera);
            EXPECT_TRUE(finite_non_negative(l)) << e;
            brightest = std::max(brightest, max_component(l));
            EXPECT_TRUE(finite_non_negative(atmo.ray_march(camera, dir, 1e4f, 16).inscatter));
        }
        EXPECT_TRUE(finite_non_negative(atmo.sun_disc_radiance(atmo.sun_direction(), camera)));
        EXPECT_EQ(atmo.sun_disc_radiance(atmo.sun_direction(), camera), glm::vec3(0.0f));
        // Civil twilight at -1 degree is still bright near the sun; at -10 only a faint glow
        // (the day sky is about 0.03-0.1 per unit illuminance).
        std::printf("[ measured ] sun %.0f deg: brightest sky %.3g\n", e, brightest);
        EXPECT_LT(brightest, e <= -10.0f ? 1e-3f : 0.1f) << e;
    }
}

TEST(Atmosphere, NanInputsGiveFiniteOutput)
{
    const Atmosphere &atmo = atmosphere_with_sun(30.0f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const glm::vec3 nan3(nan);
    const glm::vec3 camera(0.0f, 1.0f, 0.0f);
    EXPECT_TRUE(finite_non_negative(atmo.sky_radiance(nan3, camera)));
    EXPECT_TRUE(finite_non_negative(atmo.sky_radiance(glm::vec3(0, 1, 0), nan3)));
    EXPECT_TRUE(finite_non_negative(atmo.transmittance(nan3, glm::vec3(0, 1, 0))));
    EXPECT_TRUE(finite_non_negative(atmo.transmittance(camera, nan3)));
    EXPECT_TRUE(finite_non_negative(atmo.transmittance_lut(nan, nan)));
    EXPECT_TRUE(finite_non_negative(atmo.multi_scattering_lut(nan, nan)));
    const ScatteringResult r = atmo.ray_march(camera, nan3, 100.0f, 8);
    EXPECT_EQ(r.inscatter, glm::vec3(0.0f));  // documented: (0, 1)
    EXPECT_EQ(r.transmittance, glm::vec3(1.0f));
    const CameraMatrices m = make_camera_matrices(glm::mat4(1.0f), 35.0f, 36.0f, 1.5f, 0.1f);
    const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
    for (float d : {nan, -5.0f, INFINITY, 1e30f}) {
        const ScatteringResult s = ap.sample(glm::vec2(nan, 0.5f), d);
        EXPECT_TRUE(finite_non_negative(s.inscatter)) << d;
        EXPECT_TRUE(finite_non_negative(s.transmittance)) << d;
    }
    EXPECT_EQ(ap.sample(glm::vec2(0.5f), nan).transmittance, glm::vec3(1.0f));
}

TEST(Atmosphere, LutsAreFiniteAndMultipleScatteringAddsLight)
{
    const Atmosphere &atmo = atmosphere_with_sun(30.0f);
    for (const Lut2D *lut : {&atmo.transmittance_table(),
                             &atmo.multi_scattering_table(),
                             &atmo.cached_sky_view().lut()}) {
        for (int y = 0; y < lut->height(); ++y) {
            for (int x = 0; x < lut->width(); ++x) {
                ASSERT_TRUE(finite_non_negative(lut->at(x, y))) << x << " " << y;
            }
        }
    }
    const glm::vec3 t = atmo.transmittance_lut(0.0f, 1.0f);
    EXPECT_NEAR(t.x, 0.92, 0.03);  // Earth's zenith transmittance, red
    const glm::vec3 ms = atmo.multi_scattering_lut(0.0f, 0.5f);
    EXPECT_GT(ms.z, 0.0f);
    EXPECT_LT(ms.z, 1.0f);
}

TEST(Atmosphere, BatchedSkyLookupMatchesScalar)
{
    const Atmosphere &atmo = atmosphere_with_sun(30.0f);
    const SkyView &sky = atmo.cached_sky_view();
    std::mt19937 rng(3);
    std::normal_distribution<float> gauss;
    const int n = 1001;
    std::vector<float> x(n), y(n), z(n);
    for (int i = 0; i < n; ++i) {
        const glm::vec3 d = glm::normalize(glm::vec3(gauss(rng), gauss(rng), gauss(rng)));
        x[i] = d.x;
        y[i] = d.y;
        z[i] = d.z;
    }
    x[5] = y[5] = z[5] = std::numeric_limits<float>::quiet_NaN();
    std::vector<glm::vec3> batch(n);
    sky.radiance_n(x.data(), y.data(), z.data(), n, batch.data());
    for (int i = 0; i < n; ++i) {
        const glm::vec3 one = sky.radiance(glm::vec3(x[i], y[i], z[i]));
        EXPECT_TRUE(finite_non_negative(batch[i])) << i;
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(batch[i][c], one[c], 1e-5f * one[c] + 1e-9f) << i;
        }
    }
}

TEST(Atmosphere, ApplyToFrameMatchesPerPixel)
{
    const Atmosphere &atmo = atmosphere_with_sun(20.0f);
    const int w = 40, h = 24;
    glm::mat4 c2w(1.0f);
    c2w[3] = glm::vec4(0.0f, 50.0f, 0.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(c2w, 20.0f, 36.0f, float(w) / h, 0.1f);
    const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
    Image depth(w, h, 1), color(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            depth.at(x, y, 0) = y < h / 2 ? INFINITY : 10.0f * float(1 + x * y);
            for (int ch = 0; ch < 4; ++ch) {
                color.at(x, y, ch) = 0.1f * float(ch + 1);
            }
        }
    }
    depth.at(3, 20, 0) = std::numeric_limits<float>::quiet_NaN();
    Image out = color;
    apply_atmosphere(atmo, atmo.cached_sky_view(), ap, depth, out);
    // Aerial perspective alone: the same on geometry, the sky pixels untouched.
    Image ap_only = color;
    apply_aerial_perspective(ap, depth, ap_only);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const bool sky = !(depth.at(x, y, 0) < INFINITY);
            for (int c = 0; c < 4; ++c) {
                EXPECT_EQ(ap_only.at(x, y, c), sky ? color.at(x, y, c) : out.at(x, y, c));
            }
        }
    }
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec2 uv((x + 0.5f) / w, (y + 0.5f) / h);
            const float d = depth.at(x, y, 0);
            glm::vec3 expected;
            if (std::isnan(d)) {
                expected = glm::vec3(0.1f, 0.2f, 0.3f);
            } else if (std::isinf(d)) {
                expected = atmo.sky_radiance(ap.rays().direction(uv.x, uv.y), ap.rays().position());
            } else {
                const ScatteringResult s = ap.sample(uv, ap.distance_from_depth(uv, d));
                expected = glm::vec3(0.1f, 0.2f, 0.3f) * s.transmittance + s.inscatter;
            }
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(out.at(x, y, c), expected[c], 1e-5f * expected[c] + 1e-8f)
                    << x << " " << y;
            }
            EXPECT_EQ(out.at(x, y, 3), 0.4f);
        }
    }
}

TEST(Atmosphere, InvalidParamsNameTheParameter)
{
    AtmosphereParams p;
    p.top_radius_m = p.bottom_radius_m;
    try {
        Atmosphere a(p);
        FAIL() << "expected an error";
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Usage);
        EXPECT_NE(std::string(e.what()).find("\"top_radius_m\""), std::string::npos) << e.what();
    }
    p = AtmosphereParams{};
    p.sky_view_width = 1;
    EXPECT_THROW(Atmosphere{p}, Error);
}

TEST(Atmosphere, SameBitsForOneAndTwoThreads)
{
    AtmosphereParams p;
    p.sun_direction = sun_at_elevation(15.0f);
    set_thread_count(1);
    const auto t0 = std::chrono::steady_clock::now();
    const Atmosphere a(p);
    const auto t1 = std::chrono::steady_clock::now();
    set_thread_count(2);
    const Atmosphere b(p);
    set_thread_count(0);
    std::printf("[ measured ] LUT build, 1 thread: %.1f ms\n",
                std::chrono::duration<double, std::milli>(t1 - t0).count());
    for (const auto &[la, lb] :
         {std::pair(&a.transmittance_table(), &b.transmittance_table()),
          std::pair(&a.multi_scattering_table(), &b.multi_scattering_table()),
          std::pair(&a.cached_sky_view().lut(), &b.cached_sky_view().lut())}) {
        for (int y = 0; y < la->height(); ++y) {
            for (int x = 0; x < la->width(); ++x) {
                ASSERT_EQ(la->at(x, y), lb->at(x, y));
            }
        }
    }
    // Frames: aerial perspective and sky.
    const int w = 130, h = 70;
    glm::mat4 c2w(1.0f);
    c2w[3] = glm::vec4(0.0f, 20.0f, 0.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(c2w, 20.0f, 36.0f, float(w) / h, 0.1f);
    Image depth(w, h, 1), color(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            depth.at(x, y, 0) = y < h / 2 ? INFINITY : float(x + 1) * float(y);
            color.at(x, y, 1) = 0.5f;
        }
    }
    Image out1 = color, out2 = color;
    set_thread_count(1);
    apply_atmosphere(a,
                     a.cached_sky_view(),
                     AerialPerspective(a, m.world_to_camera, m.world_to_ndc),
                     depth,
                     out1);
    set_thread_count(2);
    apply_atmosphere(a,
                     a.cached_sky_view(),
                     AerialPerspective(a, m.world_to_camera, m.world_to_ndc),
                     depth,
                     out2);
    set_thread_count(0);
    EXPECT_TRUE(out1.bit_equal(out2));
}

}  // namespace
}  // namespace posthaste::shading
