// The relight node's vector rows (shading/lighting/relight_kernels.cpp, one Highway source) against
// its reference (shading/lighting/relight.cpp: prepare_pixel and shading::direct_response, one
// pixel at a time) on a real frame: the Minecrappy scene's G-buffer at frame 30 with every material
// kind (rough and glossy dielectrics, metals, the anisotropic ones, toon leaves) under a sun, two
// point lights and a spot, in both modes and with positions from the position pass or from
// depth. The rows do the reference's operations in its order with exact division and square
// root, so every value must be the same bits, on every target this CPU has: the best, AVX2,
// SSE4 and the portable one-lane target.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>

#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "shading/lighting/relight_pixel.h"
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

/// Values whose bits differ between a and b (the same size).
std::size_t differing_values(const Image &a, const Image &b)
{
    EXPECT_EQ(a.value_count(), b.value_count());
    std::size_t n = 0;
    for (std::size_t i = 0; i < a.value_count(); ++i) {
        n += std::memcmp(a.data() + i, b.data() + i, sizeof(float)) != 0;
    }
    return n;
}

/// Values that differ from the input colour: what the lights changed.
std::size_t changed_values(const Image &out)
{
    const Image &in = gbuffer().image("color");
    std::size_t n = 0;
    for (std::size_t i = 0; i < out.value_count(); ++i) {
        n += out.data()[i] != in.data()[i];
    }
    return n;
}

/// The node with `params` on the reference (POSTHASTE_SIMD=scalar) and on every target.
void check_same_bits(const std::string &params)
{
    Image ref;
    {
        simd::ScopedLevel scalar(simd::Level::Scalar);
        ref = run_relight(params);
    }
    EXPECT_GT(changed_values(ref), std::size_t(ref.width()) * std::size_t(ref.height()));
    test::for_each_highway_target([&](const char *target) {
        EXPECT_EQ(differing_values(run_relight(params), ref), 0u) << target;
    });
}

TEST(RelightSimd, AddModeGivesTheReferenceBitsOnEveryTarget)
{
    check_same_bits(R"({"mode": "add", "toon_ids": "6", )" + std::string(kLights) + "}");
}

TEST(RelightSimd, ReplaceWithAmbientAndClampGivesTheReferenceBits)
{
    check_same_bits(R"({"mode": "replace", "ambient": 0.6, "clamp": 2.0, "toon_ids": "6", )" +
                    std::string(kLights) + "}");
}

TEST(RelightSimd, PositionFromDepthGivesTheReferenceBits)
{
    // The rows' own 2x2 solve for the position against prepare_pixel's.
    check_same_bits(R"({"mode": "replace", "position_from": "depth", "toon_ids": "6", )" +
                    std::string(kLights) + "}");
}

TEST(RelightSimd, EnergyCompensationGivesTheReferenceBits)
{
    // The Kulla-Conty lobe with the table read per lane (gathers) against multiscatter().
    check_same_bits(R"({"mode": "add", "energy_compensation": true, "toon_ids": "6", )" +
                    std::string(kLights) + "}");
}

TEST(RelightSimd, QuantisedToonHighlightsGiveTheReferenceBits)
{
    // Toon lanes with stepped highlights go through the reference inside the rows.
    check_same_bits(R"({"mode": "add", "toon_ids": "6", "toon_specular_steps": 3, )" +
                    std::string(kLights) + "}");
}

TEST(RelightSimd, TheRowsThemselvesGiveTheReferenceBits)
{
    // The rows called directly (so this cannot pass by both runs taking the reference), on
    // Inputs built here: positions from the position pass, an eye above the scene, anisotropic
    // and toon materials, every light kind.
    const Frame &f = gbuffer();
    shading::relight::Setup setup;
    shading::relight::Light sun, point, spot;
    sun.direction = glm::normalize(glm::vec3(0.4f, 0.75f, 0.3f));
    sun.power = glm::vec3(4.0f, 3.8f, 3.5f);
    point.type = shading::relight::LightType::Point;
    point.position = glm::vec3(60.0f, 20.0f, 60.0f);
    point.power = glm::vec3(200.0f, 120.0f, 60.0f);
    spot.type = shading::relight::LightType::Spot;
    spot.position = glm::vec3(64.0f, 30.0f, 64.0f);
    spot.direction = glm::normalize(glm::vec3(0.0f, -1.0f, 0.2f));
    spot.power = glm::vec3(900.0f);
    spot.cos_inner = std::cos(0.26f);
    spot.cos_outer = std::cos(0.61f);
    setup.lights = {sun, point, spot};
    setup.is_toon[6] = true;
    shading::relight::Inputs sh;
    sh.setup = &setup;
    sh.color = &f.image("color");
    sh.normal = &f.image("normal");
    sh.albedo = &f.image("albedo");
    sh.material = &f.image("material");
    sh.position = &f.image("position");
    sh.tangent = &f.image("tangent");
    sh.id = &f.image("id");
    sh.eye = glm::vec3(40.0f, 35.0f, 20.0f);
    sh.width = sh.color->width();
    sh.height = sh.color->height();
    sh.toon.toon_bands = 3;
    sh.toon_words[0] = 1u << 6;
    Image ref = Image::uninitialized(sh.width, sh.height, sh.color->channels());
    shading::relight::shade(sh, ref);  // kernel_ok is false: the reference
    EXPECT_GT(changed_values(ref), std::size_t(ref.width()) * std::size_t(ref.height()));
    test::for_each_highway_target([&](const char *target) {
        Image out = Image::uninitialized(sh.width, sh.height, sh.color->channels());
        shading::relight::shade_rows_vector(sh, out);
        EXPECT_EQ(differing_values(out, ref), 0u) << target;
    });
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
