// nodes/relight.cpp: add lights to a frame, or replace its lighting, from its G-buffer: normal,
// position (or depth plus the camera matrices), albedo, material (roughness, metallic,
// anisotropy), tangent and material id. Directional, point and spot lights; the metallic-workflow
// BRDF of shading/brdf.h (Lambert or Burley diffuse, GGX with Smith or Cook-Torrance masking,
// anisotropic GGX, Kulla & Conty 2017 energy compensation) and the rasterizer's toon bands and
// sky light (shading/lighting.h), so that mode "replace" with the scene's sun and sky_ambient
// reproduces Minecrappy's beauty. Optional screen-space shadows march the depth buffer toward
// each light. Background pixels (no surface) keep their input color.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <set>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <nlohmann/json.hpp>

#include "core/hash.h"
#include "nodes/node.h"
#include "shading/brdf.h"
#include "shading/lighting.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kMode =
    ParamSpec::choice("mode", "add|replace", "add")
        .doc(
            "add: the lights' contribution is added to the input color; replace: surfaces are "
            "shaded "
            "from albedo alone (lights plus `ambient`), background keeps the input color.");
constexpr ParamSpec kLights =
    ParamSpec::json("lights", "[]")
        .doc(
            "Array of lights: {\"type\": \"directional\", \"direction\": [x, y, z] (toward the "
            "light), "
            "\"color\": [r, g, b], \"intensity\": irradiance}, {\"type\": \"point\", \"position\", "
            "\"color\", \"intensity\": intensity (irradiance at 1 m), \"radius\": m (0.05)}, or "
            "{\"type\": \"spot\", point keys plus \"direction\" (where it points), \"inner_deg\" "
            "(20), "
            "\"outer_deg\" (30)}. World space, metres.");
constexpr ParamSpec kAmbient = ParamSpec::real("ambient", 0.0)
                                   .range(0.0, 1000.0)
                                   .doc(
                                       "Scale of the rasterizer's sky light (hemispherical diffuse "
                                       "plus specular sky stand-in) "
                                       "added to surfaces; the scene's sky_ambient reproduces its "
                                       "beauty in mode replace. The sky's "
                                       "sun glow follows the first directional light.");
constexpr ParamSpec kPositionFrom = ParamSpec::choice("position_from", "position|depth", "position")
                                        .doc(
                                            "World positions from the position pass, or "
                                            "reconstructed from depth and the camera matrices.");
constexpr ParamSpec kDiffuse =
    ParamSpec::choice("diffuse", "lambert|burley", "lambert").doc("Diffuse lobe.");
constexpr ParamSpec kGeometry =
    ParamSpec::choice(
        "geometry", "smith_correlated|smith_separable|cook_torrance", "smith_correlated")
        .doc(
            "Specular masking-shadowing term (cook_torrance: min(1, 2 n.h n.v / v.h, "
            "2 n.h n.l / v.h), isotropic only).");
constexpr ParamSpec kEnergy =
    ParamSpec::boolean("energy_compensation", false)
        .doc("Kulla-Conty multiple-scattering lobe (restores the energy rough GGX loses).");
constexpr ParamSpec kAnisotropic =
    ParamSpec::boolean("anisotropic", true)
        .doc("Use material anisotropy with the tangent pass (read only when true).");
constexpr ParamSpec kToonIds =
    ParamSpec::string("toon_ids", "")
        .doc("Material ids (id pass) shaded as toon, comma list (Minecrappy's scene: 6, leaves).");
constexpr ParamSpec kToonBands =
    ParamSpec::integer("toon_bands", 3)
        .range(1, 64)
        .doc("Diffuse bands of toon materials (the rasterizer uses 3).");
constexpr ParamSpec kToonSpecularSteps = ParamSpec::integer("toon_specular_steps", 0)
                                             .range(0, 64)
                                             .doc(
                                                 "Quantise toon highlights to this many steps "
                                                 "of the GGX lobe; 0: continuous (rasterizer).");
constexpr ParamSpec kShadows = ParamSpec::boolean("shadows", false)
                                   .doc(
                                       "Screen-space shadows: march the depth buffer toward each "
                                       "light (needs the depth pass).");
constexpr ParamSpec kShadowSteps =
    ParamSpec::integer("shadow_steps", 16).range(1, 256).doc("Ray-march steps per light.");
constexpr ParamSpec kShadowDistance = ParamSpec::real("shadow_distance", 2.0)
                                          .range(0.001, 1e6)
                                          .units("m")
                                          .doc("Longest march toward a light.");
constexpr ParamSpec kShadowThickness = ParamSpec::real("shadow_thickness", 0.5)
                                           .range(0.0, 1e6)
                                           .units("m")
                                           .doc("Assumed depth of every surface in the buffer.");
constexpr ParamSpec kShadowBias = ParamSpec::real("shadow_bias", 0.02)
                                      .range(0.0, 1e6)
                                      .units("m")
                                      .doc("Start offset along the normal and depth tolerance.");
constexpr ParamSpec kClamp =
    ParamSpec::real("clamp", 0.0)
        .range(0.0, 1e30)
        .doc("Largest radiance a light may add per channel (firefly clamp); 0: no clamp.");
constexpr ParamSpec kParams[] = {kMode,
                                 kLights,
                                 kAmbient,
                                 kPositionFrom,
                                 kDiffuse,
                                 kGeometry,
                                 kEnergy,
                                 kAnisotropic,
                                 kToonIds,
                                 kToonBands,
                                 kToonSpecularSteps,
                                 kShadows,
                                 kShadowSteps,
                                 kShadowDistance,
                                 kShadowThickness,
                                 kShadowBias,
                                 kClamp};
constexpr PortSpec kInputs[] = {
    {"image",
     "color,normal,albedo,material",
     false,
     "Frame with color and its G-buffer; other passes pass through."},
};

enum class LightType { Directional, Point, Spot };

struct Light {
    LightType type = LightType::Directional;
    glm::vec3 direction{0.0f, 1.0f, 0.0f};  // directional: toward the light; spot: where it points
    glm::vec3 position{0.0f};
    glm::vec3 power{1.0f};  // color * intensity
    float radius = 0.05f;
    float cos_inner = 0.0f, cos_outer = 0.0f;
};

struct Setup {
    std::vector<Light> lights;
    std::set<int> toon_ids;
    std::array<bool, 256> is_toon{};  // by material id
};

// Lights and toon ids, validated. `where` is "<file>:/nodes/<i>/params", `who` the node.
Setup parse_setup(const NodeParams &params, const std::string &where, const std::string &who)
{
    using json = nlohmann::json;
    Setup s;
    const json lights = json::parse(params.get_json(kLights));
    const std::string at = where + "/lights";
    if (!lights.is_array()) {
        throw_usage(at, ": ", who, ": expected an array of lights, got ", lights.dump());
    }
    for (std::size_t i = 0; i < lights.size(); ++i) {
        const json &e = lights[i];
        const std::string li = at + "/" + std::to_string(i);
        if (!e.is_object()) {
            throw_usage(li, ": ", who, ": expected a light object, got ", e.dump());
        }
        Light l;
        const json type = e.value("type", json());
        if (!type.is_string()) {
            throw_usage(li,
                        "/type: ",
                        who,
                        ": expected \"directional\", \"point\" or \"spot\", got ",
                        type.is_null() ? std::string("nothing") : type.dump());
        }
        const std::string t = type.get<std::string>();
        if (t == "directional") {
            l.type = LightType::Directional;
        } else if (t == "point") {
            l.type = LightType::Point;
        } else if (t == "spot") {
            l.type = LightType::Spot;
        } else {
            throw_usage(li,
                        "/type: ",
                        who,
                        ": expected \"directional\", \"point\" or \"spot\", got ",
                        type.dump());
        }
        std::set<std::string> allowed = {"type", "color", "intensity"};
        if (l.type == LightType::Directional) {
            allowed.insert("direction");
        } else {
            allowed.insert({"position", "radius"});
        }
        if (l.type == LightType::Spot) {
            allowed.insert({"direction", "inner_deg", "outer_deg"});
        }
        for (auto it = e.begin(); it != e.end(); ++it) {
            if (!allowed.count(it.key())) {
                std::string keys;
                for (const std::string &k : allowed) {
                    keys += (keys.empty() ? "" : ", ") + k;
                }
                throw_usage(li,
                            "/",
                            it.key(),
                            ": ",
                            who,
                            ": unknown key for a ",
                            t,
                            " light (have: ",
                            keys,
                            ")");
            }
        }
        auto vec3 = [&](const char *key, glm::vec3 def, bool required) {
            if (!e.contains(key)) {
                if (required) {
                    throw_usage(li, "/", key, ": ", who, ": ", t, " light needs \"", key, "\"");
                }
                return def;
            }
            const json &v = e[key];
            bool ok = v.is_array() && v.size() == 3;
            for (std::size_t k = 0; ok && k < 3; ++k) {
                ok = v[k].is_number() && std::isfinite(v[k].get<double>());
            }
            if (!ok) {
                throw_usage(
                    li, "/", key, ": ", who, ": expected [x, y, z] numbers, got ", v.dump());
            }
            return glm::vec3(v[0].get<float>(), v[1].get<float>(), v[2].get<float>());
        };
        auto number = [&](const char *key, double def, double lo, double hi) {
            if (!e.contains(key)) {
                return float(def);
            }
            const json &v = e[key];
            if (!v.is_number() || !(v.get<double>() >= lo && v.get<double>() <= hi)) {
                throw_usage(li,
                            "/",
                            key,
                            ": ",
                            who,
                            ": expected a number in [",
                            lo,
                            ", ",
                            hi,
                            "], got ",
                            v.dump());
            }
            return v.get<float>();
        };
        const glm::vec3 color = vec3("color", glm::vec3(1.0f), false);
        if (color.x < 0.0f || color.y < 0.0f || color.z < 0.0f) {
            throw_usage(
                li, "/color: ", who, ": expected non-negative numbers, got ", e["color"].dump());
        }
        l.power = color * number("intensity", 1.0, 0.0, 1e12);
        if (l.type != LightType::Point) {
            const glm::vec3 d = vec3("direction", glm::vec3(0.0f), true);
            if (!(glm::length(d) > 1e-12f)) {
                throw_usage(li,
                            "/direction: ",
                            who,
                            ": expected a non-zero vector, got ",
                            e["direction"].dump());
            }
            l.direction = glm::normalize(d);
        }
        if (l.type != LightType::Directional) {
            l.position = vec3("position", glm::vec3(0.0f), true);
            l.radius = number("radius", 0.05, 1e-6, 1e6);
        }
        if (l.type == LightType::Spot) {
            const float inner = number("inner_deg", 20.0, 0.0, 90.0);
            const float outer = number("outer_deg", 30.0, 0.0, 90.0);
            if (!(outer > inner)) {
                throw_usage(li,
                            "/outer_deg: ",
                            who,
                            ": expected more than inner_deg (",
                            inner,
                            "), got ",
                            outer);
            }
            l.cos_inner = std::cos(inner * shading::kPi / 180.0f);
            l.cos_outer = std::cos(outer * shading::kPi / 180.0f);
        }
        s.lights.push_back(l);
    }
    for (const std::string &w : split_list(params.get_string(kToonIds))) {
        char *end = nullptr;
        const long v = std::strtol(w.c_str(), &end, 10);
        if (end == w.c_str() || *end != '\0' || v < 1 || v > 255) {
            throw_usage(
                where, "/toon_ids: ", who, ": expected material ids 1..255, got \"", w, "\"");
        }
        s.toon_ids.insert(int(v));
        s.is_toon[std::size_t(v)] = true;
    }
    return s;
}

void check(CheckContext &ctx)
{
    parse_setup(ctx.params, ctx.node.json_path + "/params", ctx.node.describe());
}

void plan(PlanContext &ctx)
{
    PassSet &in = ctx.inputs[0];
    const NodeParams &p = ctx.params;
    in.add(p.get_choice(kPositionFrom) == 0 ? pass::kPosition : pass::kDepth);
    if (p.get_bool(kAnisotropic)) {
        in.add(pass::kTangent);
    }
    if (!split_list(p.get_string(kToonIds)).empty()) {
        in.add(pass::kId);
    }
    if (p.get_bool(kShadows)) {
        in.add(pass::kDepth);
    }
}

// Screen-space shadow march (see docs/nodes/relight.md for its limits).
struct ScreenShadows {
    const Image *depth = nullptr;
    glm::mat4 world_to_ndc{1.0f};
    glm::vec4 z_row{0.0f};  // camera-space z of a world point: dot(z_row, (p, 1))
    int steps = 16;
    float distance = 2.0f, thickness = 0.5f, bias = 0.02f;

    // 1 lit, 0 occluded: marches from p (pushed off along n) toward the light, up to
    // min(distance, max_t) metres, with a per-pixel hashed start offset.
    float visibility(const glm::vec3 &p,
                     const glm::vec3 &n,
                     const glm::vec3 &l,
                     float max_t,
                     int x,
                     int y,
                     int k) const
    {
        // Clip coordinates and camera z are linear along the segment: project its ends once.
        const glm::vec3 start = p + n * bias;
        const float dist = std::min(distance, max_t);
        const glm::vec3 end = start + l * dist;
        const glm::vec4 c0 = world_to_ndc * glm::vec4(start, 1.0f);
        const glm::vec4 dc = world_to_ndc * glm::vec4(end, 1.0f) - c0;
        const float z0 = glm::dot(z_row, glm::vec4(start, 1.0f));
        const float dz = glm::dot(z_row, glm::vec4(end, 1.0f)) - z0;
        const float jitter = hash_unit(x, y, k, 0x5eedu);
        const float w = float(depth->width()), h = float(depth->height());
        for (int i = 0; i < steps; ++i) {
            const float t = (float(i) + jitter) / float(steps);
            const glm::vec4 c = c0 + dc * t;
            if (!(c.w > 0.0f)) {
                break;
            }
            const float inv_w = 1.0f / c.w;
            const float px = c.x * inv_w * w, py = c.y * inv_w * h;
            if (!(px >= 0.0f && py >= 0.0f && px < w && py < h)) {
                break;
            }
            const float zb = depth->at(int(px), int(py), 0);
            const float zr = z0 + dz * t;
            if (std::isfinite(zb) && zb < zr - bias && zr - zb < thickness) {
                return 0.0f;
            }
        }
        return 1.0f;
    }
};

bool finite3(const glm::vec3 &v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

glm::vec3 load3(const Image &img, int x, int y)
{
    const float *p = img.pixel(x, y);
    return glm::vec3(p[0], p[1], p[2]);
}

// Direction to the light, irradiance at normal incidence (color * intensity * falloff) and
// distance (infinite for a sun) at world point p; false when p is at the light.
bool light_at(const Light &light, const glm::vec3 &p, glm::vec3 &l, glm::vec3 &e, float &max_t)
{
    if (light.type == LightType::Directional) {
        l = light.direction;
        e = light.power;
        max_t = std::numeric_limits<float>::infinity();
        return true;
    }
    const glm::vec3 d = light.position - p;
    const float d2 = glm::dot(d, d);
    max_t = std::sqrt(d2);
    if (!(max_t > 0.0f)) {
        return false;
    }
    l = d / max_t;
    float falloff = 1.0f / std::max(d2, light.radius * light.radius);
    if (light.type == LightType::Spot) {
        const float cs = -glm::dot(l, light.direction);
        const float t =
            std::clamp((cs - light.cos_outer) / (light.cos_inner - light.cos_outer), 0.0f, 1.0f);
        falloff *= t * t * (3.0f - 2.0f * t);  // smoothstep
    }
    e = light.power * falloff;
    return true;
}

// One shaded pixel's inputs.
struct Prepared {
    bool valid = false, fast = false;
    glm::vec3 p{0.0f}, n{0.0f, 0.0f, 1.0f}, v{0.0f, 0.0f, 1.0f};
    shading::Surface surf;
    const shading::DirectOptions *opts = nullptr;
};

// A tile row in structure-of-arrays form for the 4-wide kernel; r, g, b receive the lights' sum.
struct Row {
    static constexpr int kMax = kDefaultTileSize;
    Prepared px[kMax];
    alignas(16) float x[kMax], y[kMax], z[kMax];     // position
    alignas(16) float nx[kMax], ny[kMax], nz[kMax];  // normal (facing the viewer)
    alignas(16) float vx[kMax], vy[kMax], vz[kMax];  // toward the viewer
    alignas(16) float nv[kMax];                      // raw n.v
    alignas(16) float a2[kMax], sv[kMax];            // alpha^2, sqrt(nv^2 (1 - a2) + a2)
    alignas(16) float f0r[kMax], f0g[kMax], f0b[kMax];
    alignas(16) float kdr[kMax], kdg[kMax], kdb[kMax];  // diffuse albedo / pi
    alignas(16) float r[kMax], g[kMax], b[kMax];

    Row()
    {
        for (int i = 0; i < kMax; ++i) {
            clear_lane(i);
        }
    }
    void clear_lane(int i)
    {
        x[i] = y[i] = z[i] = 0.0f;
        nx[i] = ny[i] = vx[i] = vy[i] = 0.0f;
        nz[i] = vz[i] = nv[i] = a2[i] = sv[i] = 1.0f;
        f0r[i] = f0g[i] = f0b[i] = kdr[i] = kdg[i] = kdb[i] = 0.0f;
        r[i] = g[i] = b[i] = 0.0f;
    }
    void set_lane(int i, const Prepared &pr)
    {
        x[i] = pr.p.x;
        y[i] = pr.p.y;
        z[i] = pr.p.z;
        nx[i] = pr.n.x;
        ny[i] = pr.n.y;
        nz[i] = pr.n.z;
        vx[i] = pr.v.x;
        vy[i] = pr.v.y;
        vz[i] = pr.v.z;
        nv[i] = glm::dot(pr.n, pr.v);
        // Inline forms of roughness_to_alpha, specular_f0 and diffuse_albedo (brdf.cpp).
        const float rough = std::clamp(pr.surf.roughness, shading::kMinRoughness, 1.0f);
        const float alpha = rough * rough;
        a2[i] = alpha * alpha;
        const float c = std::max(nv[i], shading::kMinCosine);
        sv[i] = std::sqrt(c * c * (1.0f - a2[i]) + a2[i]);
        const float metal = pr.surf.metallic;
        const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), pr.surf.albedo, metal);
        const glm::vec3 kd = pr.surf.albedo * ((1.0f - metal) * (1.0f / shading::kPi));
        f0r[i] = f0.x;
        f0g[i] = f0.y;
        f0b[i] = f0.z;
        kdr[i] = kd.x;
        kdg[i] = kd.y;
        kdb[i] = kd.z;
    }
};

#if defined(__SSE2__)
// 1 / x and 1 / sqrt(x) from the hardware estimates plus one Newton step (relative error about
// 5e-7 instead of 0.5 ulp; the accuracy test bounds the effect on the image). Measured 28 %
// less work than divps/sqrtps. Departure from bit-portability: the estimates differ between CPU
// vendors, so outputs may differ in the last bits across machines (never across thread counts).
inline __m128 rcp_nr(__m128 x)
{
    const __m128 r = _mm_rcp_ps(x);
    return _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(2.0f), _mm_mul_ps(x, r)));
}
inline __m128 rsqrt_nr(__m128 x)
{
    const __m128 r = _mm_rsqrt_ps(x);
    const __m128 hx = _mm_mul_ps(_mm_set1_ps(0.5f), x);
    return _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(1.5f), _mm_mul_ps(hx, _mm_mul_ps(r, r))));
}

// shading::evaluate (Lambert + GGX, height-correlated Smith, Schlick), 4 lanes at once, summed
// over the lights into row.r/g/b. Same formulas as brdf.cpp; float results differ from the
// scalar path by rounding only (a few ulp).
void shade_lanes(Row &row, int count, const std::vector<Light> &lights, float clamp)
{
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f), half = _mm_set1_ps(0.5f);
    const __m128 min_cos = _mm_set1_ps(shading::kMinCosine);
    const __m128 inv_pi = _mm_set1_ps(1.0f / shading::kPi);
    const __m128 clamp_v = _mm_set1_ps(clamp > 0.0f ? clamp : std::numeric_limits<float>::max());
    // Lights outside, pixel groups inside: consecutive groups are independent, so the core
    // overlaps their long sqrt/rcp chains.
    for (const Light &light : lights) {
        for (int i = 0; i < count; i += 4) {
            const __m128 px = _mm_load_ps(row.x + i), py = _mm_load_ps(row.y + i),
                         pz = _mm_load_ps(row.z + i);
            const __m128 nx = _mm_load_ps(row.nx + i), ny = _mm_load_ps(row.ny + i),
                         nz = _mm_load_ps(row.nz + i);
            const __m128 vx = _mm_load_ps(row.vx + i), vy = _mm_load_ps(row.vy + i),
                         vz = _mm_load_ps(row.vz + i);
            const __m128 nv_raw = _mm_load_ps(row.nv + i);
            const __m128 nv = _mm_max_ps(nv_raw, min_cos);
            const __m128 a2 = _mm_load_ps(row.a2 + i), sv = _mm_load_ps(row.sv + i);
            const __m128 one_minus_a2 = _mm_sub_ps(one, a2);
            const __m128 f0r = _mm_load_ps(row.f0r + i), f0g = _mm_load_ps(row.f0g + i),
                         f0b = _mm_load_ps(row.f0b + i);
            const __m128 kdr = _mm_load_ps(row.kdr + i), kdg = _mm_load_ps(row.kdg + i),
                         kdb = _mm_load_ps(row.kdb + i);
            __m128 ar = _mm_load_ps(row.r + i), ag = _mm_load_ps(row.g + i),
                   ab = _mm_load_ps(row.b + i);
            {
                __m128 lx, ly, lz, er, eg, eb;
                if (light.type == LightType::Directional) {
                    lx = _mm_set1_ps(light.direction.x);
                    ly = _mm_set1_ps(light.direction.y);
                    lz = _mm_set1_ps(light.direction.z);
                    er = _mm_set1_ps(light.power.x);
                    eg = _mm_set1_ps(light.power.y);
                    eb = _mm_set1_ps(light.power.z);
                } else {
                    const __m128 dx = _mm_sub_ps(_mm_set1_ps(light.position.x), px);
                    const __m128 dy = _mm_sub_ps(_mm_set1_ps(light.position.y), py);
                    const __m128 dz = _mm_sub_ps(_mm_set1_ps(light.position.z), pz);
                    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
                                                 _mm_mul_ps(dz, dz));
                    // At the light (d2 = 0) the lane gets l = 0, so n.l = 0 and no light.
                    const __m128 inv = _mm_and_ps(_mm_cmpgt_ps(d2, zero), rsqrt_nr(d2));
                    lx = _mm_mul_ps(dx, inv);
                    ly = _mm_mul_ps(dy, inv);
                    lz = _mm_mul_ps(dz, inv);
                    __m128 falloff =
                        rcp_nr(_mm_max_ps(d2, _mm_set1_ps(light.radius * light.radius)));
                    if (light.type == LightType::Spot) {
                        const __m128 cs = _mm_sub_ps(
                            zero,
                            _mm_add_ps(_mm_add_ps(_mm_mul_ps(lx, _mm_set1_ps(light.direction.x)),
                                                  _mm_mul_ps(ly, _mm_set1_ps(light.direction.y))),
                                       _mm_mul_ps(lz, _mm_set1_ps(light.direction.z))));
                        __m128 t =
                            _mm_mul_ps(_mm_sub_ps(cs, _mm_set1_ps(light.cos_outer)),
                                       _mm_set1_ps(1.0f / (light.cos_inner - light.cos_outer)));
                        t = _mm_min_ps(_mm_max_ps(t, zero), one);
                        falloff =
                            _mm_mul_ps(falloff,
                                       _mm_mul_ps(_mm_mul_ps(t, t),
                                                  _mm_sub_ps(_mm_set1_ps(3.0f), _mm_add_ps(t, t))));
                    }
                    er = _mm_mul_ps(_mm_set1_ps(light.power.x), falloff);
                    eg = _mm_mul_ps(_mm_set1_ps(light.power.y), falloff);
                    eb = _mm_mul_ps(_mm_set1_ps(light.power.z), falloff);
                }
                const __m128 nl = _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, lx), _mm_mul_ps(ny, ly)),
                                             _mm_mul_ps(nz, lz));
                const __m128 lit = _mm_cmpgt_ps(nl, zero);
                if (_mm_movemask_ps(lit) == 0) {
                    continue;
                }
                // h = (v + l) / |v + l|; n.h and v.h from dot products.
                const __m128 hx = _mm_add_ps(vx, lx), hy = _mm_add_ps(vy, ly),
                             hz = _mm_add_ps(vz, lz);
                const __m128 hlen2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(hx, hx), _mm_mul_ps(hy, hy)),
                                                _mm_mul_ps(hz, hz));
                const __m128 hok = _mm_cmpgt_ps(hlen2, _mm_set1_ps(1e-16f));
                const __m128 inv_h =
                    rsqrt_nr(_mm_or_ps(_mm_and_ps(hok, hlen2), _mm_andnot_ps(hok, one)));
                // Degenerate h (v = -l) falls back to h = n, as evaluate(): n.h = 1, v.h = n.v.
                const __m128 nh =
                    _mm_max_ps(_mm_or_ps(_mm_and_ps(hok, _mm_mul_ps(_mm_add_ps(nv_raw, nl), inv_h)),
                                         _mm_andnot_ps(hok, one)),
                               zero);
                const __m128 vl = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, lx), _mm_mul_ps(vy, ly)),
                                             _mm_mul_ps(vz, lz));
                const __m128 vh =
                    _mm_max_ps(_mm_or_ps(_mm_and_ps(hok, _mm_mul_ps(_mm_add_ps(one, vl), inv_h)),
                                         _mm_andnot_ps(hok, nv_raw)),
                               zero);
                // D = a2 / (pi d^2), d = (n.h)^2 (a2 - 1) + 1.
                const __m128 dd =
                    _mm_add_ps(_mm_mul_ps(_mm_mul_ps(nh, nh), _mm_sub_ps(a2, one)), one);
                const __m128 d = _mm_mul_ps(_mm_mul_ps(a2, inv_pi), rcp_nr(_mm_mul_ps(dd, dd)));
                // V = 0.5 / (n.l sv + n.v sqrt(n.l^2 (1 - a2) + a2)), cosines clamped.
                const __m128 nlc = _mm_max_ps(nl, min_cos);
                const __m128 sl2 = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(nlc, nlc), one_minus_a2), a2);
                const __m128 sl = _mm_mul_ps(sl2, rsqrt_nr(sl2));  // sl2 >= a2 > 0
                const __m128 vis =
                    _mm_mul_ps(half, rcp_nr(_mm_add_ps(_mm_mul_ps(nlc, sv), _mm_mul_ps(nv, sl))));
                const __m128 dv = _mm_mul_ps(d, vis);
                // Schlick: F = f0 + (1 - f0) m^5, m = 1 - clamp(v.h, 0, 1).
                const __m128 m = _mm_sub_ps(one, _mm_min_ps(vh, one));
                const __m128 m2 = _mm_mul_ps(m, m);
                const __m128 m5 = _mm_mul_ps(_mm_mul_ps(m2, m2), m);
                auto channel = [&](__m128 f0, __m128 kd, __m128 e) {
                    const __m128 f = _mm_add_ps(f0, _mm_mul_ps(_mm_sub_ps(one, f0), m5));
                    const __m128 c =
                        _mm_mul_ps(_mm_mul_ps(_mm_add_ps(kd, _mm_mul_ps(f, dv)), nl), e);
                    return _mm_and_ps(lit, _mm_min_ps(c, clamp_v));
                };
                ar = _mm_add_ps(ar, channel(f0r, kdr, er));
                ag = _mm_add_ps(ag, channel(f0g, kdg, eg));
                ab = _mm_add_ps(ab, channel(f0b, kdb, eb));
            }
            _mm_store_ps(row.r + i, ar);
            _mm_store_ps(row.g + i, ag);
            _mm_store_ps(row.b + i, ab);
        }
    }
}
#else
// No SSE2: every pixel takes the scalar path.
void shade_lanes(Row &row, int count, const std::vector<Light> &, float)
{
    for (int i = 0; i < count; ++i) {
        row.px[i].fast = false;
    }
}
#endif

void execute(NodeContext &ctx)
{
    const Setup &setup = ctx.state().get_or_create<Setup>([&] {
        return parse_setup(ctx.params(), ctx.node().json_path + "/params", ctx.node().describe());
    });
    const Image &color = ctx.input_pass("image", pass::kColor);
    const Image &normal = ctx.input_pass("image", pass::kNormal);
    const Image &albedo = ctx.input_pass("image", pass::kAlbedo);
    const Image &material = ctx.input_pass("image", pass::kMaterial);
    const bool from_depth = ctx.get_choice(kPositionFrom) == 1;
    const Image *position = from_depth ? nullptr : &ctx.input_pass("image", pass::kPosition);
    const bool shadows = ctx.get_bool(kShadows);
    const Image *depth = from_depth || shadows ? &ctx.input_pass("image", pass::kDepth) : nullptr;
    const Image *tangent =
        ctx.get_bool(kAnisotropic) ? &ctx.input_pass("image", pass::kTangent) : nullptr;
    const Image *id = setup.toon_ids.empty() ? nullptr : &ctx.input_pass("image", pass::kId);
    if (color.channels() < 3 || normal.channels() < 3 || albedo.channels() < 3 ||
        material.channels() < 3 || (position && position->channels() < 3) ||
        (tangent && tangent->channels() < 3)) {
        throw_runtime(ctx.where(),
                      ": color, normal, position, albedo, material and tangent "
                      "need 3 channels");
    }
    const Frame &in = ctx.input("image");
    const glm::mat4 w2c = in.camera.require_world_to_camera(ctx.where());
    const glm::mat4 c2w = glm::inverse(w2c);
    const glm::vec3 eye(c2w[3]);
    glm::mat4 w2ndc(1.0f), cam_to_ndc(1.0f);
    if (from_depth || shadows) {
        w2ndc = in.camera.require_world_to_ndc(ctx.where());
        cam_to_ndc = w2ndc * c2w;
    }
    const glm::vec4 z_row(w2c[0][2], w2c[1][2], w2c[2][2], w2c[3][2]);

    const bool replace = ctx.get_choice(kMode) == 1;
    const float ambient = ctx.get_float(kAmbient);
    const float clamp = ctx.get_float(kClamp);
    shading::DirectOptions base;
    base.geometry = shading::Geometry(ctx.get_choice(kGeometry));
    base.burley = ctx.get_choice(kDiffuse) == 1;
    base.energy_compensation = ctx.get_bool(kEnergy);
    if (base.energy_compensation) {
        shading::energy_table(base.geometry);  // build before the tiles, not inside one
    }
    shading::DirectOptions toon = base;
    toon.toon_bands = ctx.get_int(kToonBands);
    toon.toon_specular_steps = ctx.get_int(kToonSpecularSteps);
    glm::vec3 sky_sun(0.0f);
    for (const Light &l : setup.lights) {
        if (l.type == LightType::Directional) {
            sky_sun = l.direction;
            break;
        }
    }
    ScreenShadows ss;
    if (shadows) {
        ss.depth = depth;
        ss.world_to_ndc = w2ndc;
        ss.z_row = z_row;
        ss.steps = ctx.get_int(kShadowSteps);
        ss.distance = ctx.get_float(kShadowDistance);
        ss.thickness = ctx.get_float(kShadowThickness);
        ss.bias = ctx.get_float(kShadowBias);
    }
    const int W = color.width(), H = color.height();
    const int nc = color.channels();
    Image out = Image::uninitialized(W, H, nc);
    const bool fast_ok = !shadows && !base.burley && !base.energy_compensation &&
                         base.geometry == shading::Geometry::SmithCorrelated;

    parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
        Row row;
        for (int y = tile.y0; y < tile.y1; ++y) {
            // Stage 1: per-pixel surface setup; unusable pixels keep their input color.
            const int n_px = tile.x1 - tile.x0;
            std::copy(color.pixel(tile.x0, y),
                      color.pixel(tile.x0, y) + n_px * nc,
                      out.pixel(tile.x0, y));
            for (int i = 0; i < n_px; ++i) {
                const int x = tile.x0 + i;
                Prepared &pr = row.px[i];
                pr.valid = false;
                row.clear_lane(i);
                // World position of the pixel's surface, or a background pixel.
                glm::vec3 p;
                if (from_depth) {
                    const float z = depth->at(x, y, 0);
                    if (!std::isfinite(z)) {
                        continue;
                    }
                    // Solve the two NDC equations u (row3 . q) = row0 . q (and v) for the camera
                    // point q = (X, Y, z, 1).
                    const float u = (float(x) + 0.5f) / float(W), v = (float(y) + 0.5f) / float(H);
                    const glm::mat4 &m = cam_to_ndc;
                    const float a00 = m[0][0] - u * m[0][3], a01 = m[1][0] - u * m[1][3];
                    const float a10 = m[0][1] - v * m[0][3], a11 = m[1][1] - v * m[1][3];
                    const float b0 = -((m[2][0] - u * m[2][3]) * z + m[3][0] - u * m[3][3]);
                    const float b1 = -((m[2][1] - v * m[2][3]) * z + m[3][1] - v * m[3][3]);
                    const float det = a00 * a11 - a01 * a10;
                    if (det == 0.0f) {
                        continue;
                    }
                    const glm::vec4 q(
                        (b0 * a11 - a01 * b1) / det, (a00 * b1 - a10 * b0) / det, z, 1.0f);
                    p = glm::vec3(c2w * q);
                } else {
                    p = load3(*position, x, y);
                }
                glm::vec3 n = load3(normal, x, y);
                const float nlen = glm::length(n);
                if (!finite3(p) || !(nlen > 0.5f) || !std::isfinite(nlen) ||
                    (depth && !std::isfinite(depth->at(x, y, 0)))) {
                    continue;  // background, or no usable normal
                }
                n *= 1.0f / nlen;
                const glm::vec3 to_eye = eye - p;
                const float elen = glm::length(to_eye);
                if (!(elen > 0.0f)) {
                    continue;
                }
                const glm::vec3 v = to_eye * (1.0f / elen);
                if (glm::dot(n, v) < 0.0f) {
                    n = -n;  // seen from behind: shade the side we see (as the rasterizer)
                }
                const glm::vec3 mat = load3(material, x, y);
                shading::Surface &surf = pr.surf;
                surf = shading::Surface{};
                surf.albedo = load3(albedo, x, y);
                surf.roughness = std::isfinite(mat.x) ? std::clamp(mat.x, 0.0f, 1.0f) : 1.0f;
                surf.metallic = std::isfinite(mat.y) ? std::clamp(mat.y, 0.0f, 1.0f) : 0.0f;
                if (tangent && std::isfinite(mat.z) && mat.z != 0.0f) {
                    // A degenerate tangent (zero, NaN, parallel to n) shades isotropically.
                    const glm::vec3 t = load3(*tangent, x, y);
                    const glm::vec3 tp = t - n * glm::dot(n, t);
                    if (finite3(tp) && glm::dot(tp, tp) > 1e-8f) {
                        surf.anisotropy = std::clamp(mat.z, -1.0f, 1.0f);
                        surf.tangent = t;
                    }
                }
                if (!finite3(surf.albedo)) {
                    surf.albedo = glm::vec3(0.0f);
                }
                bool is_toon = false;
                if (id) {
                    const float m = id->at(x, y, 0);
                    is_toon = m >= 0.5f && m < 255.5f && setup.is_toon[std::size_t(m + 0.5f)];
                }
                pr.opts = is_toon ? &toon : &base;
                pr.p = p;
                pr.n = n;
                pr.v = v;
                pr.valid = true;
                pr.fast = fast_ok && !is_toon && surf.anisotropy == 0.0f;
                if (pr.fast) {
                    row.set_lane(i, pr);
                }
            }
            // Stage 2: the common case (isotropic, Lambert, correlated Smith), 4 pixels at once.
            if (fast_ok) {
                shade_lanes(row, n_px, setup.lights, clamp);
            }
            // Stage 3: everything else per pixel, then ambient and the mode.
            for (int i = 0; i < n_px; ++i) {
                const Prepared &pr = row.px[i];
                if (!pr.valid) {
                    continue;
                }
                const int x = tile.x0 + i;
                glm::vec3 c(row.r[i], row.g[i], row.b[i]);
                if (!pr.fast) {
                    c = glm::vec3(0.0f);
                    for (std::size_t k = 0; k < setup.lights.size(); ++k) {
                        glm::vec3 l, e;
                        float max_t;
                        if (!light_at(setup.lights[k], pr.p, l, e, max_t) ||
                            glm::dot(pr.n, l) <= 0.0f) {
                            continue;
                        }
                        if (shadows && ss.visibility(pr.p, pr.n, l, max_t, x, y, int(k)) == 0.0f) {
                            continue;
                        }
                        glm::vec3 add =
                            shading::direct_response(pr.surf, pr.n, pr.v, l, *pr.opts) * e;
                        if (clamp > 0.0f) {
                            add = glm::min(add, glm::vec3(clamp));
                        }
                        c += add;
                    }
                }
                if (ambient > 0.0f) {
                    c = shading::add_sky_light(c, pr.surf, pr.n, pr.v, sky_sun, ambient);
                }
                float *dst = out.pixel(x, y);
                if (!replace) {
                    c += glm::vec3(dst[0], dst[1], dst[2]);
                }
                dst[0] = c.x;
                dst[1] = c.y;
                dst[2] = c.z;
            }
        }
    });
    const Pass &cp = in.pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

}  // namespace

extern const NodeType kRelight{
    {"relight", "Add or replace lights from the G-buffer (GGX BRDF).", kInputs, kParams, "color"},
    &execute,
    &plan,
    &check};

}  // namespace posthaste::nodes
