// The fog node: each analytic model against a brute-force numeric integral along the view rays
// it computes from depth and the camera; density 0 gives the input back bit for bit; stability
// cases (horizontal rays, camera at the fog base, 1e7 m, NaN/negative depth, sky, sun below the
// horizon); same bits for 1 and N threads.

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "shading/camera_rays.h"
#include "shading/fog/filtered_edges.h"
#include "shading/fog/height_fog.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// A frame with color 0 (so the output is the fog's in-scatter alone), given depths and a camera
/// at `cam` looking along +Z (pitch by `pitch_deg`).
Frame fog_frame(int w, int h, glm::vec3 cam, float pitch_deg, float depth_value)
{
    Frame f;
    Image color(w, h, 4), depth(w, h, 1);
    depth.fill(depth_value);
    for (std::size_t i = 0; i < color.pixel_count(); ++i) {
        color.data()[i * 4 + 3] = 1.0f;
    }
    f.set("color", std::move(color));
    f.set("depth", std::move(depth));
    glm::mat4 cam_to_world = glm::translate(glm::mat4(1.0f), cam);
    cam_to_world = glm::rotate(cam_to_world, glm::radians(-pitch_deg), glm::vec3(1, 0, 0));
    const CameraMatrices m = make_camera_matrices(cam_to_world, 35.0f, 36.0f, float(w) / h, 0.1f);
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    return f;
}

Frame run_fog(const Frame &in, const std::string &params)
{
    return test::run_node("fog", in, params);
}

/// Height fog optical depth along the ray by a midpoint sum.
double brute_optical_depth(
    glm::dvec3 o, glm::dvec3 d, double dist, double a, double b, double h0, double start)
{
    const int n = 200000;
    const double ds = (dist - start) / n;
    double tau = 0.0;
    for (int i = 0; i < n; ++i) {
        const double s = start + (i + 0.5) * ds;
        tau += a * std::exp(-b * (o.y + d.y * s - h0)) * ds;
    }
    return tau;
}

TEST(FogNode, HeightFogMatchesNumericIntegration)
{
    for (float pitch : {0.0f, 10.0f, -25.0f, 60.0f}) {
        for (float cam_y : {0.0f, 5.0f, 40.0f}) {
            const Frame in = fog_frame(16, 12, {0.0f, cam_y, 0.0f}, pitch, 150.0f);
            const Frame out = run_fog(in, R"({"model": "height", "density": 0.02,
                "falloff": 0.08, "base_height": 5, "start": 3, "color": [1, 1, 1]})");
            const shading::CameraRays rays(*in.camera.world_to_camera, *in.camera.world_to_ndc);
            for (int y = 0; y < 12; y += 5) {
                for (int x = 0; x < 16; x += 7) {
                    const float u = (x + 0.5f) / 16.0f, v = (y + 0.5f) / 12.0f;
                    const double dist = 150.0 * glm::length(rays.depth_ray(u, v));
                    const glm::dvec3 dir = glm::dvec3(rays.direction(u, v));
                    const double tau = brute_optical_depth(
                        glm::dvec3(rays.position()), dir, dist, 0.02, 0.08, 5.0, 3.0);
                    const double want = 1.0 - std::exp(-tau);  // in-scatter with color 1
                    const double got = out.image("color").at(x, y, 1);
                    EXPECT_NEAR(got, want, 1e-5 * std::max(1.0, want))
                        << "pitch " << pitch << " cam_y " << cam_y << " pixel " << x << "," << y;
                    EXPECT_EQ(out.image("color").at(x, y, 3), 1.0f);  // alpha untouched
                }
            }
        }
    }
}

TEST(FogNode, ClassicModelsFollowTheirFormulas)
{
    const Frame in = fog_frame(8, 6, {0, 1, 0}, 0.0f, 40.0f);
    const shading::CameraRays rays(*in.camera.world_to_camera, *in.camera.world_to_ndc);
    const double d = 40.0 * glm::length(rays.depth_ray(0.5f / 8, 0.5f / 6));
    const Frame lin =
        run_fog(in, R"({"model": "linear", "start": 10, "end": 90, "color": [1,1,1]})");
    EXPECT_NEAR(lin.image("color").at(0, 0, 0), 1.0 - (90.0 - d) / 80.0, 1e-6);
    const Frame ex = run_fog(in, R"({"model": "exp", "density": 0.03, "color": [1,1,1]})");
    EXPECT_NEAR(ex.image("color").at(0, 0, 0), 1.0 - std::exp(-0.03 * d), 1e-6);
    const Frame ex2 = run_fog(in, R"({"model": "exp2", "density": 0.03, "color": [1,1,1]})");
    EXPECT_NEAR(ex2.image("color").at(0, 0, 0), 1.0 - std::exp(-(0.03 * d) * (0.03 * d)), 1e-6);
}

TEST(FogNode, HorizontalRaysAndCameraAtTheBase)
{
    // Camera exactly at the fog base, looking level: the centre row is a horizontal ray with
    // constant density a, so T = exp(-a d) exactly.
    const Frame in = fog_frame(9, 9, {0, 5, 0}, 0.0f, 100.0f);
    const Frame out = run_fog(in, R"({"model": "height", "density": 0.01, "falloff": 0.5,
        "base_height": 5, "color": [1, 1, 1]})");
    const shading::CameraRays rays(*in.camera.world_to_camera, *in.camera.world_to_ndc);
    const float d = 100.0f * glm::length(rays.depth_ray(4.5f / 9, 4.5f / 9));
    const double want = 1.0 - std::exp(-0.01 * d);
    EXPECT_NEAR(out.image("color").at(4, 4, 0), want, 1e-5 * want);  // the issue's bound
}

TEST(FogNode, DensityZeroIsTheInputBitForBit)
{
    const Frame in = test::make_sample_frame(32, 16, 1);
    for (const char *model : {"exp", "exp2", "height"}) {
        const Frame out =
            run_fog(in, std::string(R"({"model": ")") + model + R"(", "density": 0})");
        EXPECT_EQ(out.pass("color").image, in.pass("color").image) << model;  // shared, not copied
    }
}

TEST(FogNode, StabilityCasesStayFiniteAndBounded)
{
    Frame in = fog_frame(16, 8, {0, 3, 0}, -5.0f, 20.0f);
    Image depth = in.image("depth");
    depth.at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    depth.at(1, 0, 0) = -5.0f;
    depth.at(2, 0, 0) = std::numeric_limits<float>::infinity();
    depth.at(3, 0, 0) = 1e7f;
    depth.at(4, 0, 0) = 0.0f;
    in.set("depth", std::move(depth));
    Image color = in.image("color");
    color.fill(0.25f);
    in.set("color", std::move(color));
    for (
        const char *params :
        {R"({"model": "height", "density": 0.05, "falloff": 0.0, "color": [0.5, 0.6, 0.7]})",
         R"({"model": "height", "density": 1e3, "falloff": 50, "color": [0.5, 0.6, 0.7]})",
         R"({"model": "height", "density": 0.05, "sun_color": [2, 2, 2], "sun_direction": [0, -1, 0.2]})",
         R"({"model": "exp", "density": 0.05})",
         R"({"model": "exp2", "density": 10})",
         R"({"model": "linear", "start": 0, "end": 0})",
         R"({"model": "atmosphere", "sun_direction": [0.3, -0.2, 0.9]})",
         R"({"model": "atmosphere", "sun_direction": [0.0, 1.0, 0.0], "metres_per_unit": 1000})",
         R"({"model": "exp", "density": 0.05, "pixel_filter": 0.6})",
         R"({"model": "height", "density": 1e3, "falloff": 50, "pixel_filter": 1.5})",
         R"({"model": "atmosphere", "pixel_filter": 0.6})"}) {
        SCOPED_TRACE(params);
        const Frame out = run_fog(in, params);
        const Image &c = out.image("color");
        for (int y = 0; y < c.height(); ++y) {
            for (int x = 0; x < c.width(); ++x) {
                for (int k = 0; k < 4; ++k) {
                    ASSERT_TRUE(std::isfinite(c.at(x, y, k))) << x << "," << y << "," << k;
                    ASSERT_GE(c.at(x, y, k), 0.0f);
                    ASSERT_LE(c.at(x, y, k), 100.0f);
                }
            }
        }
        EXPECT_EQ(c.at(0, 0, 0), 0.25f);  // NaN depth: untouched
        if (std::string(params).find("atmosphere") == std::string::npos) {
            EXPECT_NEAR(c.at(1, 0, 0), 0.25f, 1e-6f);  // negative depth counts as 0
        }
    }
    // Sky pixels get the fog color under the analytic models.
    const Frame sky =
        run_fog(in, R"({"model": "height", "density": 0.05, "color": [0.5, 0.6, 0.7]})");
    EXPECT_FLOAT_EQ(sky.image("color").at(2, 0, 1), 0.6f);
}

TEST(FogNode, SkyFogIsColourPlusTheSunLobe)
{
    // sky "fog" (the default): every sky pixel shows the fog's radiance, colour + sun colour x
    // 4 pi x Henyey-Greenstein(view . sun); sky "ray" gives the fog of the infinite ray instead.
    Frame in = fog_frame(24, 9, {0, 3, 0}, 20.0f, std::numeric_limits<float>::infinity());
    const glm::vec3 sun = glm::normalize(glm::vec3(0.0f, 0.3f, 1.0f));
    const Frame fog = run_fog(in, R"({"model": "height", "density": 0.05, "falloff": 0.1,
        "color": [0.5, 0.6, 0.7], "sun_color": [2, 1, 0.5], "sun_g": 0.6,
        "sun_direction": [0, 0.3, 1]})");
    const Frame ray = run_fog(in, R"({"model": "height", "density": 0.05, "falloff": 0.1,
        "color": [0.5, 0.6, 0.7], "sun_color": [2, 1, 0.5], "sun_g": 0.6,
        "sun_direction": [0, 0.3, 1], "sky": "ray"})");
    const shading::CameraRays rays(*in.camera.world_to_camera, *in.camera.world_to_ndc);
    int looking_up = 0;
    for (const auto &[x, y] : {std::pair(0, 0), std::pair(11, 4), std::pair(23, 8)}) {
        const glm::vec3 d = rays.direction((x + 0.5f) / 24.0f, (y + 0.5f) / 9.0f);
        const float lobe =
            4.0f * 3.14159265f * shading::henyey_greenstein_phase(glm::dot(d, sun), 0.6f);
        const glm::vec3 expected = glm::vec3(0.5f, 0.6f, 0.7f) + glm::vec3(2, 1, 0.5f) * lobe;
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(fog.image("color").at(x, y, c), expected[c], 2e-5f * expected[c]);
            // Looking up through thinning fog the infinite ray does not reach full fog.
            if (d.y > 0.1f) {
                EXPECT_LT(ray.image("color").at(x, y, c), 0.99f * expected[c]);
                ++looking_up;
            }
        }
        EXPECT_EQ(fog.image("color").at(x, y, 3), 1.0f);
    }
    EXPECT_GT(looking_up, 0);
}

TEST(FogNode, SameBitsForOneAndManyThreads)
{
    const Frame in = test::make_sample_frame(96, 64, 1);
    for (const char *params : {R"({"model": "height", "density": 0.05, "sun_color": [1, 1, 1]})",
                               R"({"model": "atmosphere"})",
                               R"({"model": "exp2"})",
                               R"({"model": "height", "density": 0.05, "pixel_filter": 0.6})"}) {
        set_thread_count(1);
        const Frame a = run_fog(in, params);
        set_thread_count(3);
        const Frame b = run_fog(in, params);
        set_thread_count(0);
        EXPECT_TRUE(a.image("color").bit_equal(b.image("color"))) << params;
    }
}

/// Four pixels in a row: a surface left unfogged (0-1: T 1, I 0, colour 1) beside the sky
/// (2-3: T 0, I 0.8, colour `sky_colour`), each already fogged (T c + I).
struct EdgeRow {
    Image color{4, 1, 3}, t{4, 1, 3}, i{4, 1, 3}, depth{4, 1, 1}, out{4, 1, 3};
    explicit EdgeRow(float sky_colour)
    {
        for (int x = 0; x < 4; ++x) {
            const bool sky = x >= 2;
            depth.at(x, 0, 0) = sky ? std::numeric_limits<float>::infinity() : 5.0f;
            for (int c = 0; c < 3; ++c) {
                color.at(x, 0, c) = sky ? sky_colour : 1.0f;
                t.at(x, 0, c) = sky ? 0.0f : 1.0f;
                i.at(x, 0, c) = sky ? 0.8f : 0.0f;
                out.at(x, 0, c) = sky ? 0.8f : 1.0f;  // T c + I
            }
        }
    }
};

// A filtered edge by hand, four pixels in a row: 0 and 1 a surface left unfogged (T 1, I 0,
// colour 1), 2 and 3 the sky (T 0, I 0.8, colour 0.2), sigma 1 (a side neighbour weighs
// w = exp(-1/2)). Pixel 1 takes w ((0 - 1) 0.2 + 0.8 - 0) / (1 + 2 w) of the sky beside it,
// pixel 2 w ((1 - 0) 1 + 0 - 0.8) / (1 + 2 w) of the surface; the end pixels have no whole
// line through them and stay.
TEST(FogFilteredEdges, FourPixelsByHand)
{
    EdgeRow row(0.2f);
    Image &out = row.out;
    shading::correct_filtered_edges(row.color, row.t, row.i, row.depth, 1.0f, out);
    const double w = std::exp(-0.5);
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(out.at(0, 0, c), 1.0f);
        EXPECT_NEAR(out.at(1, 0, c), 1.0 + w * 0.6 / (1.0 + 2.0 * w), 1e-6);
        EXPECT_NEAR(out.at(2, 0, c), 0.8 + w * 0.2 / (1.0 + 2.0 * w), 1e-6);
        EXPECT_EQ(out.at(3, 0, c), 0.8f);
    }
}

// A sigma whose square float cannot hold (the parameter's range starts at 0): the filter is the
// pixel alone and nothing changes, where the centre's weight 0 / 0 made every edge pixel NaN.
TEST(FogFilteredEdges, ASigmaTooSmallToSquareChangesNothing)
{
    EdgeRow row(std::numeric_limits<float>::infinity());
    const Image before = row.out;
    for (const float sigma : {1e-30f, 1e-23f, 1e-20f}) {
        shading::correct_filtered_edges(row.color, row.t, row.i, row.depth, sigma, row.out);
        EXPECT_TRUE(row.out.bit_equal(before)) << sigma;
    }
}

// Uniform T and I: nothing changes, bit for bit; a NaN depth neither changes nor counts, and
// the result stays within [0, max T * max c + max I] at a contrast that would overshoot.
TEST(FogFilteredEdges, UniformFogIsUntouchedAndNaNDepthsAreLeftOut)
{
    Image color(3, 3, 3), t(3, 3, 3), i(3, 3, 3), depth(3, 3, 1);
    color.fill(0.3f);
    color.at(1, 1, 0) = 7.0f;
    t.fill(0.5f);
    i.fill(0.2f);
    depth.fill(4.0f);
    Image out(3, 3, 3);
    for (std::size_t k = 0; k < out.value_count(); ++k) {
        out.data()[k] = t.data()[k] * color.data()[k] + i.data()[k];
    }
    const Image before = out;
    shading::correct_filtered_edges(color, t, i, depth, 0.6f, out);
    EXPECT_TRUE(out.bit_equal(before));

    // A NaN-depth neighbour with another T: ignored, so the centre stays as it was.
    depth.at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    t.at(0, 0, 0) = 0.0f;
    shading::correct_filtered_edges(color, t, i, depth, 0.6f, out);
    EXPECT_TRUE(out.bit_equal(before));

    // A dark surface (T 1) ringed by a bright sky of T 0: the correction would take the centre
    // below 0; it is clamped there.
    Image c2(3, 3, 3), t2(3, 3, 3), i2(3, 3, 3), d2(3, 3, 1), o2(3, 3, 3);
    c2.fill(50.0f);
    i2.fill(0.1f);
    d2.fill(std::numeric_limits<float>::infinity());
    for (int c = 0; c < 3; ++c) {
        c2.at(1, 1, c) = 0.0f;
        t2.at(1, 1, c) = 1.0f;
        i2.at(1, 1, c) = 0.0f;
    }
    d2.at(1, 1, 0) = 2.0f;
    for (std::size_t k = 0; k < o2.value_count(); ++k) {
        o2.data()[k] = t2.data()[k] * c2.data()[k] + i2.data()[k];
    }
    shading::correct_filtered_edges(c2, t2, i2, d2, 1.5f, o2);
    for (std::size_t k = 0; k < o2.value_count(); ++k) {
        EXPECT_TRUE(std::isfinite(o2.data()[k]));
        EXPECT_GE(o2.data()[k], 0.0f);
    }
    EXPECT_EQ(o2.at(1, 1, 0), 0.0f);
}

// A tilted plane (inverse depth affine on the screen) is no edge, however its fog varies
// from pixel to pixel: left bit for bit; a step in depth within it is corrected.
TEST(FogFilteredEdges, APlaneIsNoEdgeAStepIs)
{
    const int w = 8, h = 6;
    Image color(w, h, 3), t(w, h, 3), i(w, h, 3), depth(w, h, 1), out(w, h, 3);
    auto fill = [&] {
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                const float z = depth.at(x, y, 0), tr = std::exp(-0.1f * z);
                for (int c = 0; c < 3; ++c) {
                    color.at(x, y, c) = 0.1f * float((x * 7 + y * 3 + c) % 5);
                    t.at(x, y, c) = tr;
                    i.at(x, y, c) = 0.6f * (1.0f - tr);
                    out.at(x, y, c) = tr * color.at(x, y, c) + i.at(x, y, c);
                }
            }
        }
    };
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            depth.at(x, y, 0) = 1.0f / (0.05f + 0.01f * float(x) + 0.02f * float(y));
        }
    }
    fill();
    Image before = out;
    shading::correct_filtered_edges(color, t, i, depth, 0.6f, out);
    EXPECT_TRUE(out.bit_equal(before));

    for (int y = 0; y < h; ++y) {
        for (int x = 4; x < w; ++x) {
            depth.at(x, y, 0) *= 3.0f;  // a step between columns 3 and 4
        }
    }
    fill();
    before = out;
    shading::correct_filtered_edges(color, t, i, depth, 0.6f, out);
    EXPECT_NE(out.at(3, 2, 0), before.at(3, 2, 0));
    EXPECT_NE(out.at(4, 2, 0), before.at(4, 2, 0));
    EXPECT_EQ(out.at(1, 2, 0), before.at(1, 2, 0));
    EXPECT_EQ(out.at(6, 2, 0), before.at(6, 2, 0));
}

TEST(FogNode, NoNoteOfASunDirectionItDoesNotUse)
{
    // The height model draws a sun lobe only with sun_color: without one it neither reads nor
    // notes a sun direction (the frame's header has none); with one it says it took the
    // default. The exp model never uses the sun.
    const Frame f = fog_frame(16, 9, glm::vec3(0.0f, 2.0f, 0.0f), 5.0f, 20.0f);
    const auto notes = [&](const std::string &params) {
        testing::internal::CaptureStderr();
        run_fog(f, params);
        return testing::internal::GetCapturedStderr();
    };
    const std::string height = R"({"model": "height", "density": 0.1)";
    EXPECT_EQ(notes(height + "}").find("sun_direction"), std::string::npos);
    EXPECT_EQ(notes(R"({"model": "exp", "density": 0.1})").find("sun_direction"),
              std::string::npos);
    EXPECT_NE(notes(height + R"(, "sun_color": [1, 1, 1]})").find("sun_direction"),
              std::string::npos);
}

TEST(FogNode, MissingCameraIsNamed)
{
    Frame in = fog_frame(4, 4, {0, 1, 0}, 0.0f, 5.0f);
    in.camera.world_to_ndc.reset();
    try {
        run_fog(in, R"({"model": "exp"})");
        FAIL();
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("camera attribute \"worldToNDC\" is missing"),
                  std::string::npos)
            << e.what();
    }
}

// A value a float cannot hold is refused with the graph (1e300 once became inf in every pixel),
// a header vector is held to the parameter's range in every component (a negative sun
// illuminance once reached the atmosphere's own check, whose message lost the node and the
// value), and a header vector that is not finite says so.
TEST(FogNode, ValuesOutOfAFloatsOrTheParametersRangeAreNamed)
{
    Frame in = fog_frame(4, 4, {0, 1, 0}, 0.0f, 5.0f);
    const auto message = [&](const Frame &f, const std::string &params) {
        try {
            run_fog(f, params);
        } catch (const Error &e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message(in, R"({"model": "exp", "color": [1e300, 1, 1]})")
                  .find("param \"color\": expected array of 3 numbers within a float's range"),
              std::string::npos);
    EXPECT_NE(message(in, R"({"model": "exp", "density": 1e300})").find("within a float's range"),
              std::string::npos);
    Frame neg = in;
    const glm::vec3 minus(-1.0f, 1.0f, 1.0f);
    neg.attributes.push_back(
        OIIO::ParamValue("posthaste:sunIlluminance", OIIO::TypeVector, 1, &minus));
    EXPECT_NE(
        message(neg, R"({"model": "atmosphere"})")
            .find(
                "node \"n\" (fog), frame 1: param \"sun_illuminance\": not given, and "
                "the frame's header \"posthaste:sunIlluminance\" is [-1, 1, 1], outside 0..1e+06"),
        std::string::npos)
        << message(neg, R"({"model": "atmosphere"})");
    Frame nan_sun = in;
    const glm::vec3 nan_dir(std::numeric_limits<float>::quiet_NaN(), 1.0f, 0.0f);
    nan_sun.attributes.push_back(
        OIIO::ParamValue("posthaste:sunDirection", OIIO::TypeVector, 1, &nan_dir));
    EXPECT_NE(message(nan_sun, R"({"model": "atmosphere"})").find("is [nan, 1, 0], not finite"),
              std::string::npos)
        << message(nan_sun, R"({"model": "atmosphere"})");
}

}  // namespace
}  // namespace posthaste
