// Accuracy of the relight node (nodes/relight.cpp) and of the BRDF pieces it adds to
// shading/brdf: relighting the rasterizer's G-buffer with a new sun matches the rasterizer's own
// beauty rendered with that sun; the Kulla-Conty white furnace; Cook-Torrance against the
// seeds' formula written out by hand; point and spot lights against hand-computed irradiance.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <string>

#include "core/hash.h"
#include "core/parallel.h"
#include "graph/graph.h"
#include "metrics/metrics.h"
#include "nodes/registry.h"
#include "shading/lighting/brdf.h"
#include "shading/lighting/lighting.h"
#include "test_util.h"

namespace posthaste {
namespace {

// A small scene with every material kind the relight node distinguishes: rough and glossy
// dielectrics, a metal, an anisotropic metal (sphere: smooth normals and tangents), a toon
// material (id 5), on a floor, under a sun given as JSON text.
// `extra`: more top-level keys, each followed by a comma.
std::string scene_json(const std::string &sun, const std::string &extra = "")
{
    return R"({"name": "relight_test", "frame_range": [1, 1],
  "world": {"size": [40, 24, 40], "terrain": "none"},
  "sky_ambient": 0.7,
  "materials": [
    {"id": 1, "name": "floor", "albedo": [0.5, 0.5, 0.45], "roughness": 0.9},
    {"id": 2, "name": "red", "albedo": [0.7, 0.1, 0.1], "roughness": 0.3},
    {"id": 3, "name": "gold", "albedo": [1.0, 0.78, 0.34], "roughness": 0.25, "metallic": 1},
    {"id": 4, "name": "brushed", "albedo": [0.9, 0.9, 0.92], "roughness": 0.4, "metallic": 1,
     "anisotropy": 0.6},
    {"id": 5, "name": "toon", "albedo": [0.1, 0.5, 0.1], "roughness": 0.5, "toon": true}],
  "boxes": [
    {"min": [0, 0, 0], "max": [40, 4, 40], "material": 1},
    {"min": [14, 4, 22], "max": [17, 7, 25], "material": 2},
    {"min": [23, 4, 21], "max": [26, 8, 24], "material": 5}],
  "balls": [
    {"center": [18, 5.5, 17], "radius": 1.5, "material": 3, "segments": 64},
    {"center": [22.5, 5.5, 17], "radius": 1.5, "material": 4, "segments": 64}],
  )" + extra +
           R"("sun": )" + sun + R"(,
  "camera": [{"frame": 1, "position": [20, 9, 8], "pitch_deg": -20, "focal_length_mm": 30}]})";
}

std::string write_scene(const std::string &dir,
                        const std::string &name,
                        const std::string &sun,
                        const std::string &extra = "")
{
    const std::string path = dir + "/" + name + ".json";
    std::ofstream(path) << scene_json(sun, extra);
    return path;
}

std::string render_block(
    const std::string &id, const std::string &scene, int w, int h, bool shadows = false)
{
    return R"({"id": ")" + id + R"(", "type": "render", "params": {"scene": ")" + scene +
           R"(", "width": )" + std::to_string(w) + R"(, "height": )" + std::to_string(h) +
           R"(, "shadows": )" + (shadows ? "true" : "false") + "}}";
}

// Graph: render -> relight (params) -> write (a sink; the capture is the relight node).
Frame relight(
    const std::string &scene, int w, int h, const std::string &params, const std::string &dir)
{
    const std::string graph = R"({"nodes": [)" + render_block("r", scene, w, h) + R"(,
        {"id": "l", "type": "relight", "inputs": {"image": "r"}, "params": )" +
                              params + R"(},
        {"id": "o", "type": "write", "inputs": {"image": "l"},
         "params": {"path": ")" +
                              dir + R"(/o.exr", "passes": "color"}}]})";
    Graph g = Graph::parse(graph, "relight.json", nodes::catalog());
    g.set_capture("l");
    return g.evaluate(1);
}

Frame beauty(const std::string &scene, int w, int h, const std::string &dir, bool shadows = false)
{
    const std::string graph = R"({"nodes": [)" + render_block("r", scene, w, h, shadows) + R"(,
        {"id": "o", "type": "write", "inputs": {"image": "r"},
         "params": {"path": ")" +
                              dir + R"(/b.exr", "passes": "color"}}]})";
    Graph g = Graph::parse(graph, "beauty.json", nodes::catalog());
    g.set_capture("r");
    return g.evaluate(1);
}

constexpr const char *kSunA = R"({"direction": [0.3, 0.8, -0.5], "color": [1, 0.95, 0.9],
                                  "illuminance": 3})";
constexpr const char *kSunB = R"({"direction": [-0.6, 0.5, -0.4], "color": [1, 0.8, 0.6],
                                  "illuminance": 4})";
constexpr const char *kLightB = R"({"type": "directional", "direction": [-0.6, 0.5, -0.4],
                                    "color": [1, 0.8, 0.6], "intensity": 4})";

// RMSE over RGB of the pixels with geometry (finite depth in `depth`): the sky is background,
// which relighting keeps, and it depends on the sun (the atmosphere), so it is not compared.
double rmse_rgb(const Image &a, const Image &b, const Image &depth)
{
    double sum = 0.0;
    std::size_t n = 0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            if (!std::isfinite(depth.at(x, y, 0))) {
                continue;
            }
            ++n;
            for (int c = 0; c < 3; ++c) {
                const double d = double(a.at(x, y, c)) - double(b.at(x, y, c));
                sum += d * d;
            }
        }
    }
    EXPECT_GT(n, std::size_t(a.width()) * std::size_t(a.height()) / 2) << "too little geometry";
    return std::sqrt(sum / (3.0 * double(std::max<std::size_t>(n, 1))));
}

TEST(RelightAccuracy, ReplaceWithNewSunMatchesRasterizerBeauty)
{
    const std::string dir = test::scratch_dir("relight_accuracy");
    const std::string a = write_scene(dir, "a", kSunA), b = write_scene(dir, "b", kSunB);
    const int w = 320, h = 180;
    const Frame ref = beauty(b, w, h, dir);
    const std::string params = R"({"mode": "replace", "ambient": 0.7, "toon_ids": "5",
                                   "lights": [)" +
                               std::string(kLightB) + "]}";
    const Frame lit = relight(a, w, h, params, dir);
    const Frame before = beauty(a, w, h, dir);
    const double err = rmse_rgb(lit.image("color"), ref.image("color"), ref.image("depth"));
    const double moved = rmse_rgb(before.image("color"), ref.image("color"), ref.image("depth"));
    std::printf(
        "relight replace: RMSE %.3g vs the beauty with the new sun (the old beauty: %.3g)\n",
        err,
        moved);
    EXPECT_LE(err, 1e-4);
    EXPECT_GT(moved, 0.02);  // the sun change is large: the test can fail
    // Alpha and the other passes pass through.
    EXPECT_EQ(lit.image("color").at(5, 5, 3), 1.0f);
    EXPECT_TRUE(lit.has("normal"));

    // Positions reconstructed from depth and the camera matrices: same image to float precision.
    const Frame from_depth = relight(
        a, w, h, params.substr(0, params.size() - 1) + R"(, "position_from": "depth"})", dir);
    const double err_depth =
        rmse_rgb(from_depth.image("color"), ref.image("color"), ref.image("depth"));
    std::printf("relight replace from depth: RMSE %.3g\n", err_depth);
    EXPECT_LE(err_depth, 1e-3);

    // Without the toon ids the toon block is shaded smoothly: the test sees toon banding.
    const Frame no_toon =
        relight(a,
                w,
                h,
                R"({"mode": "replace", "ambient": 0.7, "lights": [)" + std::string(kLightB) + "]}",
                dir);
    EXPECT_GT(rmse_rgb(no_toon.image("color"), ref.image("color"), ref.image("depth")), 1e-3);
}

TEST(RelightAccuracy, ScreenSpaceShadowsAgainstShadowMaps)
{
    // The new sun's shadows marched through the depth pass against the rasterizer's shadow
    // maps, on the scene above plus a row of thin poles (8 cm square, 3.5 m tall) in front of
    // the red block, whose shadows fall on the floor and the block. With every occluder taken as
    // 0.5 m deep, a ray passing behind a pole finds it in its way; as deep as it is wide on
    // screen, only the rays that meet it do.
    const std::string dir = test::scratch_dir("relight_shadows");
    std::string pillars = R"("movers": [)";
    for (int i = 0; i < 6; ++i) {
        pillars += std::string(i ? ", " : "") + R"({"min": [)" + std::to_string(12.5 + 0.6 * i) +
                   R"(, 4, 21.2], "size": [0.08, 3.5, 0.08], "material": 2})";
    }
    pillars += "],\n";
    const std::string a = write_scene(dir, "a", kSunA, pillars),
                      b = write_scene(dir, "b", kSunB, pillars);
    const int w = 320, h = 180;
    const Frame ref = beauty(b, w, h, dir, /*shadows=*/true);
    const std::string lights = R"({"mode": "replace", "ambient": 0.7, "toon_ids": "5",
                                   "lights": [)" +
                               std::string(kLightB) + "]";
    const auto err = [&](const std::string &more) {
        const Frame lit = relight(a, w, h, lights + more + "}", dir);
        EXPECT_TRUE(test::all_finite_rgb(lit.image("color"))) << more;
        return rmse_rgb(lit.image("color"), ref.image("color"), ref.image("depth"));
    };
    const double none = err(""), constant = err(R"(, "shadows": true, "shadow_distance": 8,
        "shadow_occluders": "constant")"),
                 extent = err(R"(, "shadows": true, "shadow_distance": 8)");
    std::printf(
        "relight against shadow maps: no shadows %.4f, every occluder 0.5 m %.4f, "
        "occluders as deep as wide %.4f\n",
        none,
        constant,
        extent);
    EXPECT_LT(extent, 0.8 * none);
    EXPECT_LT(extent, constant);
}

TEST(RelightAccuracy, AddModeAddsExactlyTheReplaceLighting)
{
    const std::string dir = test::scratch_dir("relight_add");
    const std::string a = write_scene(dir, "a", kSunA);
    const int w = 96, h = 54;
    const std::string lights = R"([{"type": "point", "position": [20, 8, 14], "intensity": 30,
        "color": [1, 0.5, 0.2]}, {"type": "spot", "position": [20, 12, 12],
        "direction": [0, -1, 0.5], "intensity": 80, "inner_deg": 10, "outer_deg": 25}])";
    const Frame add = relight(a, w, h, R"({"mode": "add", "lights": )" + lights + "}", dir);
    const Frame rep = relight(a, w, h, R"({"mode": "replace", "lights": )" + lights + "}", dir);
    const Frame in = beauty(a, w, h, dir);
    int lit = 0;
    const Image &N = add.image("normal");
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const bool surface = N.at(x, y, 0) != 0 || N.at(x, y, 1) != 0 || N.at(x, y, 2) != 0;
            for (int c = 0; c < 3; ++c) {
                const float base = in.image("color").at(x, y, c);
                const float r = rep.image("color").at(x, y, c);
                if (surface) {
                    EXPECT_FLOAT_EQ(add.image("color").at(x, y, c), base + r) << x << "," << y;
                    lit += r > 0.01f;
                } else {
                    // Background keeps its input color in both modes.
                    EXPECT_EQ(add.image("color").at(x, y, c), base);
                    EXPECT_EQ(r, base);
                }
            }
        }
    }
    EXPECT_GT(lit, 100);
}

TEST(RelightAccuracy, PointAndSpotIrradianceByHand)
{
    // Replace mode, no ambient, one point and one spot light: every surface pixel must be the
    // shading response times intensity / d^2 (point) and times the spot's smoothstep between
    // the cone angles, computed here from the frame's own G-buffer.
    const std::string dir = test::scratch_dir("relight_hand");
    const std::string a = write_scene(dir, "a", kSunA);
    const int w = 64, h = 36;
    const glm::vec3 pp(20, 8, 14), sp(20, 12, 12), sd = glm::normalize(glm::vec3(0, -1, 0.5f));
    const Frame f = relight(a,
                            w,
                            h,
                            R"({"mode": "replace", "anisotropic": false, "lights": [
        {"type": "point", "position": [20, 8, 14], "intensity": 30, "color": [1, 0.5, 0.25]},
        {"type": "spot", "position": [20, 12, 12], "direction": [0, -1, 0.5], "intensity": 80,
         "inner_deg": 10, "outer_deg": 25}]})",
                            dir);
    const glm::mat4 c2w = glm::inverse(*f.camera.world_to_camera);
    const glm::vec3 eye(c2w[3]);
    const float ci = std::cos(10.0f * shading::kPi / 180),
                co = std::cos(25.0f * shading::kPi / 180);
    int checked = 0, in_cone = 0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const Image &N = f.image("normal");
            glm::vec3 n(N.at(x, y, 0), N.at(x, y, 1), N.at(x, y, 2));
            if (glm::length(n) < 0.5f) {
                continue;
            }
            const Image &P = f.image("position"), &A = f.image("albedo"), &M = f.image("material");
            const glm::vec3 p(P.at(x, y, 0), P.at(x, y, 1), P.at(x, y, 2));
            const glm::vec3 v = glm::normalize(eye - p);
            if (glm::dot(n, v) < 0) {
                n = -n;
            }
            shading::Surface s;
            s.albedo = glm::vec3(A.at(x, y, 0), A.at(x, y, 1), A.at(x, y, 2));
            s.roughness = M.at(x, y, 0);
            s.metallic = M.at(x, y, 1);
            glm::vec3 want(0.0f);
            const glm::vec3 dp = pp - p;
            want += shading::direct_response(s, n, v, glm::normalize(dp)) *
                    glm::vec3(1, 0.5f, 0.25f) * (30.0f / glm::dot(dp, dp));
            const glm::vec3 ds = sp - p;
            const float cs = glm::dot(-glm::normalize(ds), sd);
            const float t = std::clamp((cs - co) / (ci - co), 0.0f, 1.0f);
            in_cone += t > 0.5f;
            want += shading::direct_response(s, n, v, glm::normalize(ds)) * 80.0f *
                    (t * t * (3 - 2 * t)) / glm::dot(ds, ds);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(f.image("color").at(x, y, c), want[c], 1e-4f * std::max(1.0f, want[c]))
                    << x << "," << y;
            }
            ++checked;
        }
    }
    EXPECT_GT(checked, w * h / 2);
    EXPECT_GT(in_cone, 10);
}

// --- BRDF: Kulla-Conty white furnace and Cook-Torrance -------------------------------------

// Directional albedo of specular (+ multiple scattering) with F = 1, by a quadrature that is
// independent of the table's: jittered stratified GGX sampling of h for the single-scattering
// lobe (256 x 256 hashed strata) and a midpoint rule in mu_l for the multiple-scattering lobe
// (which depends on mu_l only).
double furnace(float roughness, float mu, shading::Geometry g, bool compensate)
{
    using namespace shading;
    Surface s;
    s.albedo = glm::vec3(1.0f);
    s.metallic = 1.0f;
    s.roughness = roughness;
    const float nv = mu;
    const glm::vec3 n(0, 0, 1), v(std::sqrt(1 - nv * nv), 0, nv);
    const float alpha = roughness_to_alpha(roughness);
    const float a2 = alpha * alpha;
    const int k = 256;
    double sum = 0.0;
    for (int i = 0; i < k; ++i) {
        for (int j = 0; j < k; ++j) {
            const float u1 = (float(i) + hash_unit(i, j, 0, 7)) / float(k);
            const float u2 = (float(j) + hash_unit(i, j, 1, 7)) / float(k);
            const float c2 = (1 - u1) / (1 + (a2 - 1) * u1);
            const float ct = std::sqrt(c2), st = std::sqrt(std::max(0.0f, 1 - c2));
            const glm::vec3 h(st * std::cos(2 * kPi * u2), st * std::sin(2 * kPi * u2), ct);
            const float vh = glm::dot(v, h);
            if (vh <= 0) {
                continue;
            }
            const glm::vec3 l = 2 * vh * h - v;
            if (l.z <= 0) {
                continue;
            }
            // D and the cosines at the h that evaluate() rebuilds from v + l, with D in the form
            // evaluate() uses for g (float rounding of n.h matters for alpha ~ 0.002; the ratio
            // then cancels it).
            glm::vec3 he = v + l;  // as evaluate() rebuilds h: a reciprocal for the default lobe
            if (g == Geometry::SmithCorrelated) {
                he *= 1.0f / glm::length(he);
            } else {
                he = he / glm::length(he);
            }
            const float d = g == Geometry::SmithCorrelated ? d_ggx(he.z, sin2_across(n, he), alpha)
                                                           : d_ggx(he.z, alpha);
            const double pdf = double(d) * he.z / (4.0 * glm::dot(v, he));
            sum += double(evaluate(s, n, v, l, g).x) / pdf;
        }
    }
    double e = sum / double(k * k);
    if (compensate) {
        // multiscatter() is f_ms n.l and depends on mu_l only: its hemispherical integral is
        // 2 pi times its integral over mu_l in [0, 1] (d omega = dmu dphi).
        const int m = 4096;
        double ms = 0.0;
        for (int i = 0; i < m; ++i) {
            const float mul = (float(i) + 0.5f) / float(m);
            ms += double(multiscatter(s, nv, mul, g).x);
        }
        e += 2.0 * M_PI * ms / double(m);
    }
    return e;
}

TEST(RelightFurnace, EnergyCompensationIntegratesToOne)
{
    double worst = 0.0;
    for (shading::Geometry g :
         {shading::Geometry::SmithCorrelated, shading::Geometry::SmithSeparable}) {
        for (float r = 0.0f; r <= 1.0001f; r += 0.125f) {
            for (float mu : {0.1f, 0.3f, 0.5f, 0.8f, 1.0f}) {
                const double with = furnace(r, mu, g, true);
                EXPECT_NEAR(with, 1.0, 0.01)
                    << "roughness " << r << " mu " << mu << " geometry " << int(g);
                worst = std::max(worst, std::abs(with - 1.0));
            }
        }
    }
    std::printf("white furnace with compensation: worst |albedo - 1| %.4f\n", worst);
}

TEST(RelightFurnace, LossWithoutCompensationMatchesTable)
{
    double worst = 0.0, largest_loss = 0.0;
    for (shading::Geometry g : {shading::Geometry::SmithCorrelated,
                                shading::Geometry::SmithSeparable,
                                shading::Geometry::CookTorrance}) {
        const shading::EnergyTable &t = shading::energy_table(g);
        for (float r = 0.0f; r <= 1.0001f; r += 0.125f) {
            for (float mu : {0.1f, 0.3f, 0.5f, 0.8f, 1.0f}) {
                const double without = furnace(r, mu, g, false);
                const double table = t.lookup_e(r, mu);
                EXPECT_NEAR(without, table, 0.005) << "roughness " << r << " mu " << mu;
                worst = std::max(worst, std::abs(without - table));
                largest_loss = std::max(largest_loss, 1.0 - without);
            }
        }
    }
    std::printf("E(mu) table vs independent integral: worst |diff| %.4f; largest loss %.3f\n",
                worst,
                largest_loss);
    EXPECT_GT(largest_loss, 0.2);  // rough GGX really loses energy: the test can fail
}

TEST(RelightFurnace, CookTorranceIsTheSeedsFormula)
{
    using namespace shading;
    // min(1, 2 (n.h)(n.v)/(v.h), 2 (n.h)(n.l)/(v.h)), with D GGX and Schlick F, in double.
    Surface s;
    s.albedo = glm::vec3(0.6f, 0.5f, 0.4f);
    s.roughness = 0.35f;
    s.metallic = 0.3f;
    const glm::vec3 n(0, 0, 1);
    int count = 0;
    for (float tv : {0.1f, 0.7f, 1.3f}) {
        for (float tl : {0.2f, 0.9f, 1.5f}) {
            for (float phi : {0.0f, 1.0f, 2.5f}) {
                const glm::vec3 v(std::sin(tv), 0, std::cos(tv));
                const glm::vec3 l(
                    std::sin(tl) * std::cos(phi), std::sin(tl) * std::sin(phi), std::cos(tl));
                DirectOptions o;
                o.geometry = Geometry::CookTorrance;
                const glm::vec3 got = direct_response(s, n, v, l, o);
                const glm::dvec3 V(v), L(l), N(n);
                const glm::dvec3 H = glm::normalize(V + L);
                const double nh = glm::dot(N, H), nv = glm::dot(N, V), nl = glm::dot(N, L),
                             vh = glm::dot(V, H);
                const double a = double(roughness_to_alpha(s.roughness)), a2 = a * a;
                const double dd = nh * nh * (a2 - 1) + 1;
                const double D = a2 / (M_PI * dd * dd);
                const double G = std::min({1.0, 2 * nh * nv / vh, 2 * nh * nl / vh});
                for (int c = 0; c < 3; ++c) {
                    const double f0 = 0.04 * (1 - s.metallic) + s.albedo[c] * s.metallic;
                    const double F = f0 + (1 - f0) * std::pow(1 - vh, 5);
                    const double diffuse = s.albedo[c] * (1 - s.metallic) / M_PI;
                    const double want = (diffuse + F * D * G / (4 * nl * nv)) * nl;
                    EXPECT_NEAR(got[c], want, 1e-5 * std::max(1.0, want));
                }
                ++count;
            }
        }
    }
    EXPECT_EQ(count, 27);
}

}  // namespace
}  // namespace posthaste
