// nodes/relight.cpp: add lights to a frame, or replace its lighting, from its G-buffer: normal,
// position (or depth plus the camera matrices), albedo, material (roughness, metallic,
// anisotropy), tangent and material id. Directional, point and spot lights; the metallic-workflow
// BRDF of shading/brdf.h (Lambert or Burley diffuse, GGX with Smith or Cook-Torrance masking,
// anisotropic GGX, Kulla & Conty 2017 energy compensation) and the rasterizer's toon bands and
// sky light (shading/lighting.h), so that mode "replace" with the scene's sun and sky_ambient
// reproduces Minecrappy's beauty. Optional screen-space shadows march the depth buffer toward
// each light. Background pixels (no surface) keep their input color. With AVX2 the common
// options run 8 pixels at a time (shade_row_avx2); the portable path is the reference.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <set>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>

#include "core/hash.h"
#include "core/sanitize.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
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
// One light: the fields of a record of `lights`.
constexpr ParamSpec kLightType = ParamSpec::choice("type", "directional|point|spot", "directional")
                                     .mandatory()
                                     .doc("The kind of light.");
constexpr ParamSpec kLightDirection =
    ParamSpec::vec3("direction", 0.0, 1.0, 0.0)
        .mandatory()
        .only_when("type", "directional|spot")
        .doc("World direction: toward the light (directional), where it points (spot).");
constexpr ParamSpec kLightPosition = ParamSpec::vec3("position", 0.0, 0.0, 0.0)
                                         .mandatory()
                                         .only_when("type", "point|spot")
                                         .units("m")
                                         .doc("World position.");
constexpr ParamSpec kLightColor =
    ParamSpec::vec3("color", 1.0, 1.0, 1.0).at_least(0.0).doc("Colour, scales the intensity.");
constexpr ParamSpec kLightIntensity =
    ParamSpec::real("intensity", 1.0)
        .range(0.0, 1e12)
        .doc("Directional: irradiance; point and spot: intensity (irradiance at 1 m).");
constexpr ParamSpec kLightRadius = ParamSpec::real("radius", 0.05)
                                       .range(1e-6, 1e6)
                                       .units("m")
                                       .only_when("type", "point|spot")
                                       .doc("Size of the emitter (softens the 1/d^2 near it).");
constexpr ParamSpec kLightInner = ParamSpec::real("inner_deg", 20.0)
                                      .range(0.0, 90.0)
                                      .units("deg")
                                      .only_when("type", "spot")
                                      .doc("Half-angle of the full-intensity cone.");
constexpr ParamSpec kLightOuter = ParamSpec::real("outer_deg", 30.0)
                                      .range(0.0, 90.0)
                                      .units("deg")
                                      .only_when("type", "spot")
                                      .doc("Half-angle where the light reaches 0 (> inner_deg).");
constexpr ParamSpec kLightFields[] = {kLightType,
                                      kLightDirection,
                                      kLightPosition,
                                      kLightColor,
                                      kLightIntensity,
                                      kLightRadius,
                                      kLightInner,
                                      kLightOuter};
constexpr ParamSpec kLights =
    ParamSpec::records("lights", kLightFields).doc("The lights, in world space and metres.");
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
constexpr ParamSpec kShadowSteps = ParamSpec::integer("shadow_steps", 16)
                                       .range(1, 256)
                                       .doc("Ray-march steps per light.")
                                       .only_when("shadows", "true");
constexpr ParamSpec kShadowDistance = ParamSpec::real("shadow_distance", 2.0)
                                          .range(0.001, 1e6)
                                          .units("m")
                                          .doc("Longest march toward a light.")
                                          .only_when("shadows", "true");
constexpr ParamSpec kShadowThickness = ParamSpec::real("shadow_thickness", 0.5)
                                           .range(0.0, 1e6)
                                           .units("m")
                                           .doc("Assumed depth of every surface in the buffer.")
                                           .only_when("shadows", "true");
constexpr ParamSpec kShadowBias = ParamSpec::real("shadow_bias", 0.02)
                                      .range(0.0, 1e6)
                                      .units("m")
                                      .doc("Start offset along the normal and depth tolerance.")
                                      .only_when("shadows", "true");
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
    Setup s;
    // The graph has checked every field's type, range and mode; what is left are the values
    // that depend on each other.
    const std::vector<NodeParams> &lights = params.get_records(kLights);
    for (std::size_t i = 0; i < lights.size(); ++i) {
        const NodeParams &r = lights[i];
        const std::string li = where + "/lights/" + std::to_string(i);
        const auto vec3 = [&](const ParamSpec &f) {
            const std::vector<double> &v = r.get_vec(f);
            return glm::vec3(float(v[0]), float(v[1]), float(v[2]));
        };
        Light l;
        l.type = LightType(r.get_choice(kLightType));
        l.power = vec3(kLightColor) * r.get_float(kLightIntensity);
        if (l.type != LightType::Point) {
            const glm::vec3 d = vec3(kLightDirection);
            if (!(glm::length(d) > 1e-12f)) {
                throw_usage(li, "/direction: ", who, ": expected a non-zero vector, got [0, 0, 0]");
            }
            l.direction = glm::normalize(d);
        }
        if (l.type != LightType::Directional) {
            l.position = vec3(kLightPosition);
            l.radius = r.get_float(kLightRadius);
        }
        if (l.type == LightType::Spot) {
            const float inner = r.get_float(kLightInner), outer = r.get_float(kLightOuter);
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

// Everything the per-pixel code reads, fixed for one frame.
struct Shading {
    const Setup *setup = nullptr;
    const Image *color = nullptr, *normal = nullptr, *albedo = nullptr, *material = nullptr;
    const Image *position = nullptr, *depth = nullptr, *tangent = nullptr, *id = nullptr;
    bool from_depth = false, shadows = false, replace = false;
    bool fast_ok = false;  // options the SSE2 kernel covers (per pixel: isotropic, not toon)
    bool avx2_ok = false;  // options the AVX2 path covers: fast_ok plus energy compensation
    const shading::EnergyTable *energy = nullptr;  // the Kulla-Conty table when compensating
    glm::mat4 c2w{1.0f}, cam_to_ndc{1.0f};
    glm::vec3 eye{0.0f}, sky_sun{0.0f};
    int width = 0, height = 0;
    float ambient = 0.0f, clamp = 0.0f;
    shading::DirectOptions base, toon;
    ScreenShadows ss;
    std::array<std::uint32_t, 8> toon_words{};  // Setup::is_toon as 256 bits
};

// Stage 1 for one pixel: its surface, or pr.valid = false for background and unusable pixels.
void prepare_pixel(const Shading &sh, int x, int y, Prepared &pr)
{
    pr.valid = false;
    pr.fast = false;
    // World position of the pixel's surface, or a background pixel.
    glm::vec3 p;
    if (sh.from_depth) {
        const float z = sh.depth->at(x, y, 0);
        if (!std::isfinite(z)) {
            return;
        }
        // Solve the two NDC equations u (row3 . q) = row0 . q (and v) for the camera point
        // q = (X, Y, z, 1).
        const float u = (float(x) + 0.5f) / float(sh.width);
        const float v = (float(y) + 0.5f) / float(sh.height);
        const glm::mat4 &m = sh.cam_to_ndc;
        const float a00 = m[0][0] - u * m[0][3], a01 = m[1][0] - u * m[1][3];
        const float a10 = m[0][1] - v * m[0][3], a11 = m[1][1] - v * m[1][3];
        const float b0 = -((m[2][0] - u * m[2][3]) * z + m[3][0] - u * m[3][3]);
        const float b1 = -((m[2][1] - v * m[2][3]) * z + m[3][1] - v * m[3][3]);
        const float det = a00 * a11 - a01 * a10;
        if (det == 0.0f) {
            return;
        }
        const glm::vec4 q((b0 * a11 - a01 * b1) / det, (a00 * b1 - a10 * b0) / det, z, 1.0f);
        p = glm::vec3(sh.c2w * q);
    } else {
        p = load3(*sh.position, x, y);
    }
    glm::vec3 n = load3(*sh.normal, x, y);
    const float nlen = glm::length(n);
    if (!finite3(p) || !(nlen > 0.5f) || !std::isfinite(nlen) ||
        (sh.depth && !std::isfinite(sh.depth->at(x, y, 0)))) {
        return;  // background, or no usable normal
    }
    n *= 1.0f / nlen;
    const glm::vec3 to_eye = sh.eye - p;
    const float elen = glm::length(to_eye);
    if (!(elen > 0.0f)) {
        return;
    }
    const glm::vec3 v = to_eye * (1.0f / elen);
    if (glm::dot(n, v) < 0.0f) {
        n = -n;  // seen from behind: shade the side we see (as the rasterizer)
    }
    const glm::vec3 mat = load3(*sh.material, x, y);
    shading::Surface &surf = pr.surf;
    surf = shading::Surface{};
    surf.albedo = load3(*sh.albedo, x, y);
    surf.roughness = std::isfinite(mat.x) ? std::clamp(mat.x, 0.0f, 1.0f) : 1.0f;
    surf.metallic = std::isfinite(mat.y) ? std::clamp(mat.y, 0.0f, 1.0f) : 0.0f;
    if (sh.tangent && std::isfinite(mat.z) && mat.z != 0.0f) {
        // A degenerate tangent (zero, NaN, parallel to n) shades isotropically.
        const glm::vec3 t = load3(*sh.tangent, x, y);
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
    if (sh.id) {
        const float m = sh.id->at(x, y, 0);
        is_toon = m >= 0.5f && m < 255.5f && sh.setup->is_toon[std::size_t(m + 0.5f)];
    }
    pr.opts = is_toon ? &sh.toon : &sh.base;
    pr.p = p;
    pr.n = n;
    pr.v = v;
    pr.valid = true;
    pr.fast = sh.fast_ok && !is_toon && surf.anisotropy == 0.0f;
}

// The lights' sum at a prepared pixel through direct_response (the reference path).
glm::vec3 light_sum_scalar(const Shading &sh, const Prepared &pr, int x, int y)
{
    glm::vec3 c(0.0f);
    const std::vector<Light> &lights = sh.setup->lights;
    for (std::size_t k = 0; k < lights.size(); ++k) {
        glm::vec3 l, e;
        float max_t;
        if (!light_at(lights[k], pr.p, l, e, max_t) || glm::dot(pr.n, l) <= 0.0f) {
            continue;
        }
        if (sh.shadows && sh.ss.visibility(pr.p, pr.n, l, max_t, x, y, int(k)) == 0.0f) {
            continue;
        }
        glm::vec3 add = shading::direct_response(pr.surf, pr.n, pr.v, l, *pr.opts) * e;
        if (sh.clamp > 0.0f) {
            add = glm::min(add, glm::vec3(sh.clamp));
        }
        c += add;
    }
    return c;
}

// Ambient and the mode: the final color of a surface pixel from its lights' sum c.
glm::vec3 finish_pixel(const Shading &sh, const Prepared &pr, glm::vec3 c, const float *in)
{
    if (sh.ambient > 0.0f) {
        c = shading::add_sky_light(c, pr.surf, pr.n, pr.v, sh.sky_sun, sh.ambient);
    }
    if (!sh.replace) {
        c += glm::vec3(in[0], in[1], in[2]);
    }
    return c;
}

// One row of a tile without AVX2: scalar setup, the 4-wide SSE2 kernel for the common case,
// scalar direct_response for the rest.
void shade_row_portable(const Shading &sh, int x0, int x1, int y, Row &row, Image &out)
{
    const int n_px = x1 - x0, nc = sh.color->channels();
    std::copy(sh.color->pixel(x0, y), sh.color->pixel(x0, y) + n_px * nc, out.pixel(x0, y));
    for (int i = 0; i < n_px; ++i) {
        Prepared &pr = row.px[i];
        row.clear_lane(i);
        prepare_pixel(sh, x0 + i, y, pr);
        if (pr.fast) {
            row.set_lane(i, pr);
        }
    }
    if (sh.fast_ok) {
        shade_lanes(row, n_px, sh.setup->lights, sh.clamp);
    }
    for (int i = 0; i < n_px; ++i) {
        const Prepared &pr = row.px[i];
        if (!pr.valid) {
            continue;
        }
        const int x = x0 + i;
        const glm::vec3 lit =
            pr.fast ? glm::vec3(row.r[i], row.g[i], row.b[i]) : light_sum_scalar(sh, pr, x, y);
        float *dst = out.pixel(x, y);
        const glm::vec3 c = finish_pixel(sh, pr, lit, dst);
        dst[0] = c.x;
        dst[1] = c.y;
        dst[2] = c.z;
    }
}

#if POSTHASTE_HAVE_AVX2_TARGET
// The AVX2 path: one tile row, 8 pixels at a time in structure-of-arrays form, setup and lights
// in vector registers. Same formulas as prepare_pixel and shading::evaluate; it rounds
// differently (FMA, rsqrt/rcp with one Newton step), so it matches the portable path to a few
// ulp, not bit for bit (tests/unit/relight_simd_test.cpp bounds the difference on a real frame).
using simd::v8::V;

// No FMA contraction here: the reference (shading::evaluate, the rasterizer) rounds every
// product, and the GGX peak amplifies a one-ulp change of n.h by about 1 / alpha^2; fused
// multiply-adds raised the relit-vs-beauty RMSE by a fifth.
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif

POSTHASTE_AVX2_INLINE V vset(float x)
{
    return _mm256_set1_ps(x);
}
POSTHASTE_AVX2_INLINE V vadd(V a, V b)
{
    return _mm256_add_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vsub(V a, V b)
{
    return _mm256_sub_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vmul(V a, V b)
{
    return _mm256_mul_ps(a, b);
}
// a b + c with two roundings, like the scalar code (see the note on contraction above).
POSTHASTE_AVX2_INLINE V vfma(V a, V b, V c)
{
    return _mm256_add_ps(_mm256_mul_ps(a, b), c);
}
POSTHASTE_AVX2_INLINE V vdot(V ax, V ay, V az, V bx, V by, V bz)
{
    return vfma(ax, bx, vfma(ay, by, vmul(az, bz)));
}
// All-ones lanes where x is finite (not NaN, not +-inf).
POSTHASTE_AVX2_INLINE V finite_mask(V x)
{
    const V abs = _mm256_andnot_ps(vset(-0.0f), x);
    return _mm256_cmp_ps(abs, vset(std::numeric_limits<float>::infinity()), _CMP_LT_OQ);
}
POSTHASTE_AVX2_INLINE V select(V mask, V if_true, V if_false)
{
    return _mm256_blendv_ps(if_false, if_true, mask);
}

// Channels 0..2 of pixels x .. x + n - 1 (n <= 8) of row y, de-interleaved; missing lanes are 0.
POSTHASTE_AVX2_INLINE void load3x8(const Image &img, int x, int y, int n, V &a, V &b, V &c)
{
    const float *p = img.pixel(x, y);
    const int ch = img.channels();
    if (ch == 3 && n == 8) {
        // 24 floats x0 y0 z0 x1 ... as three 256-bit registers of 128-bit halves
        // [x0 y0 z0 x1 | x4 y4 z4 x5], [y1 z1 x2 y2 | y5 z5 x6 y6], [z2 x3 y3 z3 | z6 x7 y7 z7].
        const V m03 =
            _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 12), 1);
        const V m14 = _mm256_insertf128_ps(
            _mm256_castps128_ps256(_mm_loadu_ps(p + 4)), _mm_loadu_ps(p + 16), 1);
        const V m25 = _mm256_insertf128_ps(
            _mm256_castps128_ps256(_mm_loadu_ps(p + 8)), _mm_loadu_ps(p + 20), 1);
        const V xy = _mm256_shuffle_ps(m14, m25, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
        const V yz = _mm256_shuffle_ps(m03, m14, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
        a = _mm256_shuffle_ps(m03, xy, _MM_SHUFFLE(2, 0, 3, 0));
        b = _mm256_shuffle_ps(yz, xy, _MM_SHUFFLE(3, 1, 2, 0));
        c = _mm256_shuffle_ps(yz, m25, _MM_SHUFFLE(3, 0, 3, 1));
        return;
    }
    alignas(32) float t[3][8] = {};
    for (int i = 0; i < n; ++i) {
        t[0][i] = p[i * ch];
        t[1][i] = p[i * ch + 1];
        t[2][i] = p[i * ch + 2];
    }
    a = _mm256_load_ps(t[0]);
    b = _mm256_load_ps(t[1]);
    c = _mm256_load_ps(t[2]);
}

// Four registers of 8 lanes (one channel each) to four registers of two interleaved pixels
// each ([p0 | p1], [p2 | p3], [p4 | p5], [p6 | p7]); its own inverse up to the register order.
POSTHASTE_AVX2_INLINE void interleave4x8(V r, V g, V b, V a, V out[4])
{
    const V t0 = _mm256_unpacklo_ps(r, g), t1 = _mm256_unpackhi_ps(r, g);
    const V t2 = _mm256_unpacklo_ps(b, a), t3 = _mm256_unpackhi_ps(b, a);
    const V u0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));  // p0 | p4
    const V u1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));  // p1 | p5
    const V u2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));  // p2 | p6
    const V u3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));  // p3 | p7
    out[0] = _mm256_permute2f128_ps(u0, u1, 0x20);
    out[1] = _mm256_permute2f128_ps(u2, u3, 0x20);
    out[2] = _mm256_permute2f128_ps(u0, u1, 0x31);
    out[3] = _mm256_permute2f128_ps(u2, u3, 0x31);
}

// One channel of a light's contribution: (kd dfac + F spec) e, clamped, zero where unlit;
// f1 = 1 - f0.
POSTHASTE_AVX2_INLINE V light_channel(V f0, V f1, V kd, V e, V m5, V dfac, V spec, V lit, V clamp_v)
{
    const V f = vfma(f1, m5, f0);
    const V c = vmul(vfma(kd, dfac, vmul(f, spec)), e);
    return _mm256_and_ps(lit, _mm256_min_ps(c, clamp_v));
}

// The same with the multiple-scattering lobe `ms` (already times n.l) added to the BRDF.
POSTHASTE_AVX2_INLINE V
light_channel_ms(V f0, V f1, V kd, V e, V m5, V dfac, V spec, V ms, V lit, V clamp_v)
{
    const V f = vfma(f1, m5, f0);
    const V c = vmul(vadd(vfma(kd, dfac, vmul(f, spec)), ms), e);
    return _mm256_and_ps(lit, _mm256_min_ps(c, clamp_v));
}

// The coloured term of shading::multiscatter, F_avg^2 E_avg / (1 - F_avg (1 - E_avg)) with
// Schlick's F_avg = (20 F0 + 1) / 21.
POSTHASTE_AVX2_INLINE V ms_colour(V f0, V e_avg)
{
    const V one = vset(1.0f);
    const V f_avg = _mm256_div_ps(vadd(vmul(vset(20.0f), f0), one), vset(21.0f));
    return _mm256_div_ps(vmul(vmul(f_avg, f_avg), e_avg), vsub(one, vmul(f_avg, vsub(one, e_avg))));
}

// EnergyTable::lookup_e for 8 lanes at mu = min(n.l, 1), the roughness row `row0` (j0 kMu) and
// its weight tr fixed per pixel. Unlit lanes (n.l <= 0 or NaN) read a clamped, valid entry.
POSTHASTE_AVX2_INLINE V energy_e(const shading::EnergyTable &t, __m256i row0, V tr, V nl)
{
    constexpr int kMu = shading::EnergyTable::kMu;
    const V mu = _mm256_min_ps(nl, vset(1.0f));
    // max(x, 0) returns 0 for a NaN x (the second operand).
    const V fm = _mm256_min_ps(
        _mm256_max_ps(vsub(vmul(mu, vset(float(kMu))), vset(0.5f)), _mm256_setzero_ps()),
        vset(float(kMu - 1)));
    const __m256i i0 = _mm256_min_epi32(_mm256_cvttps_epi32(fm), _mm256_set1_epi32(kMu - 2));
    const V tm = vsub(fm, _mm256_cvtepi32_ps(i0));
    const __m256i idx = _mm256_add_epi32(row0, i0);
    const float *e = t.e.data();
    const V r00 = _mm256_i32gather_ps(e, idx, 4), r01 = _mm256_i32gather_ps(e + 1, idx, 4);
    const V r10 = _mm256_i32gather_ps(e + kMu, idx, 4),
            r11 = _mm256_i32gather_ps(e + kMu + 1, idx, 4);
    const V a = vadd(r00, vmul(vsub(r01, r00), tm));
    const V b = vadd(r10, vmul(vsub(r11, r10), tm));
    return vadd(a, vmul(vsub(b, a), tr));
}

// Lanes whose bit is set in `bits`, as an all-ones mask.
POSTHASTE_AVX2_INLINE V mask_from_bits(int bits)
{
    const __m256i b =
        _mm256_and_si256(_mm256_set1_epi32(bits), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128));
    return _mm256_castsi256_ps(_mm256_cmpgt_epi32(b, _mm256_setzero_si256()));
}

// Lanes whose material id (rounded) is a toon id: bit i of the 256-bit set `bits` (8 words).
POSTHASTE_AVX2_INLINE V toon_mask(const Image &id, int x, int y, int n, __m256i bits)
{
    V m;
    if (id.channels() == 1 && n == 8) {
        m = _mm256_loadu_ps(id.pixel(x, y));
    } else {
        alignas(32) float t[8] = {};
        for (int i = 0; i < n; ++i) {
            t[i] = id.at(x + i, y, 0);
        }
        m = _mm256_load_ps(t);
    }
    // As prepare_pixel: ids in [0.5, 255.5) round to 1..255; the rest (and NaN) are not toon.
    const V in_range = _mm256_and_ps(_mm256_cmp_ps(m, vset(0.5f), _CMP_GE_OQ),
                                     _mm256_cmp_ps(m, vset(255.5f), _CMP_LT_OQ));
    const __m256i k = _mm256_cvttps_epi32(_mm256_and_ps(in_range, vadd(m, vset(0.5f))));
    const __m256i word = _mm256_permutevar8x32_epi32(bits, _mm256_srli_epi32(k, 5));
    const __m256i bit = _mm256_and_si256(
        _mm256_srlv_epi32(word, _mm256_and_si256(k, _mm256_set1_epi32(31))), _mm256_set1_epi32(1));
    return _mm256_and_ps(in_range,
                         _mm256_castsi256_ps(_mm256_cmpeq_epi32(bit, _mm256_set1_epi32(1))));
}

// World positions of 8 pixels from depth, as prepare_pixel: the 2x2 solve of the NDC equations
// for the camera point (X, Y, z, 1), then camera to world. `ok` clears lanes with an infinite
// depth (background) or a singular system.
POSTHASTE_AVX2_INLINE void position_from_depth(
    const Shading &sh, int x, int y, int n, V &px, V &py, V &pz, V &ok)
{
    const Image &depth = *sh.depth;
    alignas(32) float zs[8] = {};
    for (int i = 0; i < n; ++i) {
        zs[i] = depth.at(x + i, y, 0);
    }
    const V z = _mm256_load_ps(zs);
    const V xs = vadd(vset(float(x)), _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
    const V u = _mm256_div_ps(vadd(xs, vset(0.5f)), vset(float(sh.width)));
    const float v = (float(y) + 0.5f) / float(sh.height);
    const glm::mat4 &m = sh.cam_to_ndc;
    const V a00 = vsub(vset(m[0][0]), vmul(u, vset(m[0][3])));
    const V a01 = vsub(vset(m[1][0]), vmul(u, vset(m[1][3])));
    const V a10 = vset(m[0][1] - v * m[0][3]), a11 = vset(m[1][1] - v * m[1][3]);
    const V b0 = _mm256_xor_ps(
        vset(-0.0f),
        vsub(vadd(vmul(vsub(vset(m[2][0]), vmul(u, vset(m[2][3]))), z), vset(m[3][0])),
             vmul(u, vset(m[3][3]))));
    const V b1 = _mm256_xor_ps(
        vset(-0.0f),
        vsub(vadd(vmul(vset(m[2][1] - v * m[2][3]), z), vset(m[3][1])), vset(v * m[3][3])));
    const V det = vsub(vmul(a00, a11), vmul(a01, a10));
    ok = _mm256_and_ps(finite_mask(z), _mm256_cmp_ps(det, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    const V d = select(ok, det, vset(1.0f));
    const V qx = _mm256_div_ps(vsub(vmul(b0, a11), vmul(a01, b1)), d);
    const V qy = _mm256_div_ps(vsub(vmul(a00, b1), vmul(a10, b0)), d);
    const glm::mat4 &c = sh.c2w;
    px = vadd(vadd(vadd(vmul(vset(c[0][0]), qx), vmul(vset(c[1][0]), qy)), vmul(vset(c[2][0]), z)),
              vset(c[3][0]));
    py = vadd(vadd(vadd(vmul(vset(c[0][1]), qx), vmul(vset(c[1][1]), qy)), vmul(vset(c[2][1]), z)),
              vset(c[3][1]));
    pz = vadd(vadd(vadd(vmul(vset(c[0][2]), qx), vmul(vset(c[1][2]), qy)), vmul(vset(c[2][2]), z)),
              vset(c[3][2]));
}

// kEnergy: with the Kulla-Conty lobe (a separate instance: its live registers slowed the
// default path by a fifth).
template <bool kEnergy>
POSTHASTE_AVX2 void shade_row_avx2(const Shading &sh, int x0, int x1, int y, Image &out)
{
    const V zero = _mm256_setzero_ps(), one = vset(1.0f), half = vset(0.5f);
    const V min_cos = vset(shading::kMinCosine);
    const V clamp_v = vset(sh.clamp > 0.0f ? sh.clamp : std::numeric_limits<float>::max());
    const V lane = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const std::vector<Light> &lights = sh.setup->lights;
    const int bands = sh.toon.toon_bands;
    const V bands_v = vset(float(bands)), inv_bands = vset(1.0f / float(bands));
    // Toon highlights quantised per pixel (toon_specular_steps) take the scalar path.
    const bool toon_in_kernel = sh.toon.toon_specular_steps == 0;
    const int nc = sh.color->channels();
    const V eye_x = vset(sh.eye.x), eye_y = vset(sh.eye.y), eye_z = vset(sh.eye.z);
    const __m256i toon_bits =
        _mm256_loadu_si256(reinterpret_cast<const __m256i *>(sh.toon_words.data()));
    // Streaming (non-temporal) stores when the row is 16-byte aligned: the 33 MB output does
    // not fit in any cache, and a normal store first reads each line it writes.
    const bool stream = nc == 4 && reinterpret_cast<std::uintptr_t>(out.pixel(x0, y)) % 16 == 0;
    for (int x = x0; x < x1; x += 8) {
        const int n = std::min(8, x1 - x);
        // Setup, as prepare_pixel.
        V px, py, pz, nx, ny, nz;
        V depth_ok = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        if (sh.from_depth) {
            position_from_depth(sh, x, y, n, px, py, pz, depth_ok);
        } else {
            load3x8(*sh.position, x, y, n, px, py, pz);
        }
        load3x8(*sh.normal, x, y, n, nx, ny, nz);
        const V nlen2 = vdot(nx, ny, nz, nx, ny, nz);
        // |n| > 0.5 and finite, as nlen2 > 0.25 (rounding can differ only within an ulp of 0.5).
        V valid = _mm256_cmp_ps(lane, vset(float(n)), _CMP_LT_OQ);
        valid = _mm256_and_ps(valid, _mm256_and_ps(finite_mask(px), finite_mask(py)));
        valid = _mm256_and_ps(valid, _mm256_and_ps(finite_mask(pz), depth_ok));
        valid = _mm256_and_ps(valid, _mm256_cmp_ps(nlen2, vset(0.25f), _CMP_GT_OQ));
        valid = _mm256_and_ps(valid, finite_mask(nlen2));
        const V ex = vsub(eye_x, px), ey = vsub(eye_y, py), ez = vsub(eye_z, pz);
        const V elen2 = vdot(ex, ey, ez, ex, ey, ez);
        valid = _mm256_and_ps(valid, _mm256_cmp_ps(elen2, zero, _CMP_GT_OQ));
        int valid_bits = _mm256_movemask_ps(valid);
        alignas(32) float cr[8], cg[8], cb[8];
        V ar = zero, ag = zero, ab = zero;
        if (valid_bits != 0) {
            // Exact sqrt and division, as prepare_pixel: the highlight's D amplifies an error in
            // n or v by about 1 / alpha^2 (rsqrt with one Newton step doubled the RMSE of
            // RelightAccuracy and failed its 1e-4 hand check at a glossy peak).
            const V inv_n = _mm256_div_ps(one, _mm256_sqrt_ps(select(valid, nlen2, one)));
            const V inv_e = _mm256_div_ps(one, _mm256_sqrt_ps(select(valid, elen2, one)));
            nx = vmul(nx, inv_n);
            ny = vmul(ny, inv_n);
            nz = vmul(nz, inv_n);
            const V vx = vmul(ex, inv_e), vy = vmul(ey, inv_e), vz = vmul(ez, inv_e);
            // Seen from behind: flip n (n.v changes sign exactly).
            const V ndv = vdot(nx, ny, nz, vx, vy, vz);
            const V flip = _mm256_and_ps(_mm256_cmp_ps(ndv, zero, _CMP_LT_OQ), vset(-0.0f));
            nx = _mm256_xor_ps(nx, flip);
            ny = _mm256_xor_ps(ny, flip);
            nz = _mm256_xor_ps(nz, flip);
            const V nv_raw = _mm256_xor_ps(ndv, flip);
            const V nv = _mm256_max_ps(nv_raw, min_cos);

            V mr, mm, ma, alb_r, alb_g, alb_b;
            load3x8(*sh.material, x, y, n, mr, mm, ma);
            load3x8(*sh.albedo, x, y, n, alb_r, alb_g, alb_b);
            const V rough = select(finite_mask(mr), simd::v8::clamp(mr, zero, one), one);
            const V metal = select(finite_mask(mm), simd::v8::clamp(mm, zero, one), zero);
            const V alb_ok = _mm256_and_ps(_mm256_and_ps(finite_mask(alb_r), finite_mask(alb_g)),
                                           finite_mask(alb_b));
            alb_r = _mm256_and_ps(alb_r, alb_ok);
            alb_g = _mm256_and_ps(alb_g, alb_ok);
            alb_b = _mm256_and_ps(alb_b, alb_ok);
            V slow = zero;
            V toon = zero;
            if (sh.id) {
                toon = toon_mask(*sh.id, x, y, n, toon_bits);
                if (!toon_in_kernel) {
                    slow = _mm256_or_ps(slow, toon);
                }
            }
            slow = _mm256_and_ps(slow, valid);
            const V fast = _mm256_andnot_ps(slow, valid);

            const V rc = _mm256_max_ps(rough, vset(shading::kMinRoughness));
            const V alpha = vmul(rc, rc);
            const V a2 = vmul(alpha, alpha);
            const V one_minus_a2 = vsub(one, a2);
            const V a2_pi = vmul(a2, vset(1.0f / shading::kPi));
            const V sv2 = vfma(vmul(nv, nv), one_minus_a2, a2);
            const V sv = vmul(sv2, simd::v8::rsqrt(sv2));  // sv2 >= a2 > 0
            // F0 = mix(0.04, albedo, metallic), 0.04 for toon (a black dielectric's highlight).
            const V f0_base = vmul(vset(0.04f), vsub(one, metal));
            const V f0r = select(toon, vset(0.04f), vfma(alb_r, metal, f0_base));
            const V f0g = select(toon, vset(0.04f), vfma(alb_g, metal, f0_base));
            const V f0b = select(toon, vset(0.04f), vfma(alb_b, metal, f0_base));
            const V kd_scale = vmul(vsub(one, metal), vset(1.0f / shading::kPi));
            const V kdr = vmul(alb_r, kd_scale), kdg = vmul(alb_g, kd_scale),
                    kdb = vmul(alb_b, kd_scale);
            // Anisotropic lanes, as prepare_pixel and evaluate(): a material anisotropy and a
            // tangent with a usable part across n. t, b = n x t, the alphas of
            // anisotropic_alphas and the per-pixel half of the anisotropic Smith term.
            V aniso = zero;
            V tx = zero, ty = zero, tz = zero, bx = zero, by = zero, bz = zero;
            V inv_ax = one, inv_ay = one, ax2 = one, ay2 = one, d_scale = one;
            V tv = zero, bv = zero, lv = one;
            if (sh.tangent) {
                const V cand = _mm256_and_ps(
                    valid, _mm256_and_ps(finite_mask(ma), _mm256_cmp_ps(ma, zero, _CMP_NEQ_UQ)));
                V px_ = zero, py_ = zero, pz_ = zero, tp2 = one;
                if (_mm256_movemask_ps(cand) != 0) {
                    V gx, gy, gz;
                    load3x8(*sh.tangent, x, y, n, gx, gy, gz);
                    const V ndt = vdot(nx, ny, nz, gx, gy, gz);
                    px_ = vsub(gx, vmul(nx, ndt));
                    py_ = vsub(gy, vmul(ny, ndt));
                    pz_ = vsub(gz, vmul(nz, ndt));
                    tp2 = vdot(px_, py_, pz_, px_, py_, pz_);
                    aniso = _mm256_and_ps(cand, _mm256_and_ps(finite_mask(px_), finite_mask(py_)));
                    aniso = _mm256_and_ps(aniso, finite_mask(pz_));
                    aniso = _mm256_and_ps(aniso, _mm256_cmp_ps(tp2, vset(1e-8f), _CMP_GT_OQ));
                }
                if (_mm256_movemask_ps(aniso) != 0) {
                    const V inv_t = _mm256_div_ps(one, _mm256_sqrt_ps(select(aniso, tp2, one)));
                    tx = vmul(px_, inv_t);
                    ty = vmul(py_, inv_t);
                    tz = vmul(pz_, inv_t);
                    bx = vsub(vmul(ny, tz), vmul(nz, ty));
                    by = vsub(vmul(nz, tx), vmul(nx, tz));
                    bz = vsub(vmul(nx, ty), vmul(ny, tx));
                    const V an = simd::v8::clamp(ma, vset(-1.0f), one);
                    const V min_alpha = vset(shading::kMinRoughness * shading::kMinRoughness);
                    const V ax = _mm256_max_ps(vmul(alpha, vadd(one, an)), min_alpha);
                    const V ay = _mm256_max_ps(vmul(alpha, vsub(one, an)), min_alpha);
                    inv_ax = _mm256_div_ps(one, ax);
                    inv_ay = _mm256_div_ps(one, ay);
                    ax2 = vmul(ax, ax);
                    ay2 = vmul(ay, ay);
                    d_scale = _mm256_div_ps(vset(1.0f / shading::kPi), vmul(ax, ay));
                    tv = vdot(tx, ty, tz, vx, vy, vz);
                    bv = vdot(bx, by, bz, vx, vy, vz);
                    lv = _mm256_sqrt_ps(
                        vadd(vadd(vmul(ax2, vmul(tv, tv)), vmul(ay2, vmul(bv, bv))), vmul(nv, nv)));
                }
            }
            const bool any_aniso = _mm256_movemask_ps(aniso) != 0;
            const bool any_toon = _mm256_movemask_ps(_mm256_and_ps(toon, valid)) != 0;
            // Kulla-Conty lobe (shading::multiscatter): per pixel E_avg, E(n.v) and the coloured
            // F_ms / (pi (1 - E_avg)) (1 - E(n.v)), looked up exactly as the scalar code; per light
            // E(n.l) from the table row of this roughness. Toon lanes have none.
            V msr = zero, msg = zero, msb = zero, tr = zero;
            __m256i row0 = _mm256_setzero_si256();
            if (kEnergy) {
                alignas(32) float r_a[8], nv_a[8], eavg_a[8] = {}, k_a[8] = {};
                _mm256_store_ps(r_a, rough);
                _mm256_store_ps(nv_a, nv_raw);
                const int fast_bits = _mm256_movemask_ps(_mm256_andnot_ps(toon, fast));
                for (int i = 0; i < n; ++i) {
                    if (!((fast_bits >> i) & 1)) {
                        continue;
                    }
                    const float e_avg = sh.energy->lookup_e_avg(r_a[i]);
                    if (e_avg > 1.0f - 1e-6f) {
                        continue;
                    }
                    const float ev =
                        sh.energy->lookup_e(r_a[i], std::clamp(nv_a[i], shading::kMinCosine, 1.0f));
                    eavg_a[i] = e_avg;
                    k_a[i] = (1.0f - ev) / (shading::kPi * (1.0f - e_avg));
                }
                const V e_avg = _mm256_load_ps(eavg_a), k = _mm256_load_ps(k_a);
                msr = vmul(ms_colour(f0r, e_avg), k);
                msg = vmul(ms_colour(f0g, e_avg), k);
                msb = vmul(ms_colour(f0b, e_avg), k);
                const V fr = vmul(rough, vset(float(shading::EnergyTable::kRoughness - 1)));
                const __m256i j0 =
                    _mm256_min_epi32(_mm256_cvttps_epi32(fr),
                                     _mm256_set1_epi32(shading::EnergyTable::kRoughness - 2));
                tr = vsub(fr, _mm256_cvtepi32_ps(j0));
                row0 = _mm256_mullo_epi32(j0, _mm256_set1_epi32(shading::EnergyTable::kMu));
            }
            const V f1r = vsub(one, f0r), f1g = vsub(one, f0g), f1b = vsub(one, f0b);

            if (_mm256_movemask_ps(fast) != 0) {
                for (const Light &light : lights) {
                    V lx, ly, lz, falloff = one;
                    if (light.type == LightType::Directional) {
                        lx = vset(light.direction.x);
                        ly = vset(light.direction.y);
                        lz = vset(light.direction.z);
                    } else {
                        const V dx = vsub(vset(light.position.x), px);
                        const V dy = vsub(vset(light.position.y), py);
                        const V dz = vsub(vset(light.position.z), pz);
                        const V d2 = vdot(dx, dy, dz, dx, dy, dz);
                        // At the light (d2 = 0) the lane gets l = 0: n.l = 0, no light.
                        const V inv =
                            _mm256_and_ps(_mm256_cmp_ps(d2, zero, _CMP_GT_OQ), simd::v8::rsqrt(d2));
                        lx = vmul(dx, inv);
                        ly = vmul(dy, inv);
                        lz = vmul(dz, inv);
                        falloff =
                            simd::v8::rcp(_mm256_max_ps(d2, vset(light.radius * light.radius)));
                        if (light.type == LightType::Spot) {
                            const V cs = vdot(lx,
                                              ly,
                                              lz,
                                              vset(-light.direction.x),
                                              vset(-light.direction.y),
                                              vset(-light.direction.z));
                            const V t = simd::v8::clamp(
                                vmul(vsub(cs, vset(light.cos_outer)),
                                     vset(1.0f / (light.cos_inner - light.cos_outer))),
                                zero,
                                one);
                            falloff =
                                vmul(falloff, vmul(vmul(t, t), vfma(t, vset(-2.0f), vset(3.0f))));
                        }
                    }
                    const V nl = vdot(nx, ny, nz, lx, ly, lz);
                    V lit = _mm256_and_ps(fast, _mm256_cmp_ps(nl, zero, _CMP_GT_OQ));
                    if (light.type == LightType::Spot) {
                        // Outside the cone the light adds exactly 0: skip it for the group.
                        lit = _mm256_and_ps(lit, _mm256_cmp_ps(falloff, zero, _CMP_GT_OQ));
                    }
                    if (_mm256_movemask_ps(lit) == 0) {
                        continue;
                    }
                    // h = (v + l) / |v + l|; n.h and v.h from dot products.
                    const V hx = vadd(vx, lx), hy = vadd(vy, ly), hz = vadd(vz, lz);
                    const V hlen2 = vdot(hx, hy, hz, hx, hy, hz);
                    const V hok = _mm256_cmp_ps(hlen2, vset(1e-16f), _CMP_GT_OQ);
                    const V inv_h = simd::v8::rsqrt(select(hok, hlen2, one));
                    // Degenerate h (v = -l) falls back to h = n: n.h = 1, v.h = n.v.
                    const V nh =
                        _mm256_max_ps(select(hok, vmul(vadd(nv_raw, nl), inv_h), one), zero);
                    const V vl = vdot(vx, vy, vz, lx, ly, lz);
                    const V vh =
                        _mm256_max_ps(select(hok, vmul(vadd(one, vl), inv_h), nv_raw), zero);
                    // D = a2 / (pi d^2), d = (n.h)^2 (a2 - 1) + 1 = s2 (1 - a2) + a2 with
                    // s2 = 1 - (n.h)^2 from h's part across n, |h - n (n.h)|^2: near the peak
                    // 1 - (n.h)^2 cancels and D inherits an error ~ ulp / a2.
                    const V nhu = vadd(nv_raw, nl);  // n.(v + l)
                    const V qx = vsub(hx, vmul(nx, nhu)), qy = vsub(hy, vmul(ny, nhu)),
                            qz = vsub(hz, vmul(nz, nhu));
                    V s2 =
                        _mm256_min_ps(vmul(vdot(qx, qy, qz, qx, qy, qz), vmul(inv_h, inv_h)), one);
                    s2 = select(_mm256_cmp_ps(nh, zero, _CMP_GT_OQ), s2, one);  // n.h = 0
                    s2 = select(hok, s2, zero);                                 // h = n
                    const V dd = vfma(s2, one_minus_a2, a2);
                    const V d = vmul(a2_pi, simd::v8::rcp(vmul(dd, dd)));
                    // V = 0.5 / (n.l sv + n.v sqrt(n.l^2 (1 - a2) + a2)), cosines clamped.
                    const V nlc = _mm256_max_ps(nl, min_cos);
                    const V sl2 = vfma(vmul(nlc, nlc), one_minus_a2, a2);
                    const V sl = vmul(sl2, simd::v8::rsqrt(sl2));
                    const V vis = vmul(half, simd::v8::rcp(vfma(nlc, sv, vmul(nv, sl))));
                    V dv = vmul(d, vis);
                    if (any_aniso) {
                        // Anisotropic D and V (d_ggx_aniso, v_smith_correlated_aniso).
                        const V tl = vdot(tx, ty, tz, lx, ly, lz);
                        const V bl = vdot(bx, by, bz, lx, ly, lz);
                        const V hxa = vmul(vmul(vadd(tv, tl), inv_h), inv_ax);
                        const V hya = vmul(vmul(vadd(bv, bl), inv_h), inv_ay);
                        const V da2 = vadd(vadd(vmul(hxa, hxa), vmul(hya, hya)), vmul(nh, nh));
                        const V da = _mm256_and_ps(_mm256_cmp_ps(nh, zero, _CMP_GT_OQ),
                                                   vmul(d_scale, simd::v8::rcp(vmul(da2, da2))));
                        const V ll2 = vadd(vadd(vmul(ax2, vmul(tl, tl)), vmul(ay2, vmul(bl, bl))),
                                           vmul(nlc, nlc));
                        const V ll = vmul(ll2, simd::v8::rsqrt(ll2));
                        const V visa = vmul(half, simd::v8::rcp(vadd(vmul(nlc, lv), vmul(nv, ll))));
                        dv = select(aniso, vmul(da, visa), dv);
                    }
                    V spec = vmul(dv, nl);
                    // Schlick: F = f0 + (1 - f0) m^5, m = 1 - clamp(v.h, 0, 1).
                    const V m = vsub(one, _mm256_min_ps(vh, one));
                    const V m2 = vmul(m, m);
                    const V m5 = vmul(vmul(m2, m2), m);
                    // Diffuse n.l, or the toon band ceil(n.l bands) / bands.
                    const V dfac =
                        any_toon
                            ? select(toon, vmul(_mm256_ceil_ps(vmul(nl, bands_v)), inv_bands), nl)
                            : nl;
                    const V er = vmul(vset(light.power.x), falloff);
                    const V eg = vmul(vset(light.power.y), falloff);
                    const V eb = vmul(vset(light.power.z), falloff);
                    if (kEnergy) {
                        const V msl = vmul(vsub(one, energy_e(*sh.energy, row0, tr, nl)), nl);
                        ar = vadd(
                            ar,
                            light_channel_ms(
                                f0r, f1r, kdr, er, m5, dfac, spec, vmul(msr, msl), lit, clamp_v));
                        ag = vadd(
                            ag,
                            light_channel_ms(
                                f0g, f1g, kdg, eg, m5, dfac, spec, vmul(msg, msl), lit, clamp_v));
                        ab = vadd(
                            ab,
                            light_channel_ms(
                                f0b, f1b, kdb, eb, m5, dfac, spec, vmul(msb, msl), lit, clamp_v));
                        continue;
                    }
                    ar = vadd(ar, light_channel(f0r, f1r, kdr, er, m5, dfac, spec, lit, clamp_v));
                    ag = vadd(ag, light_channel(f0g, f1g, kdg, eg, m5, dfac, spec, lit, clamp_v));
                    ab = vadd(ab, light_channel(f0b, f1b, kdb, eb, m5, dfac, spec, lit, clamp_v));
                }
            }
            _mm256_store_ps(cr, ar);
            _mm256_store_ps(cg, ag);
            _mm256_store_ps(cb, ab);
            // Scalar work: anisotropic (and quantised-toon) lanes, then the sky light.
            const int slow_bits = _mm256_movemask_ps(slow);
            if (slow_bits != 0 || sh.ambient > 0.0f) {
                alignas(32) float s[11][8];
                const V keep[11] = {nx, ny, nz, vx, vy, vz, alb_r, alb_g, alb_b, rough, metal};
                for (int k = 0; k < 11; ++k) {
                    _mm256_store_ps(s[k], keep[k]);
                }
                for (int i = 0; i < n; ++i) {
                    if (!((valid_bits >> i) & 1)) {
                        continue;
                    }
                    Prepared pr;
                    glm::vec3 c(cr[i], cg[i], cb[i]);
                    if ((slow_bits >> i) & 1) {
                        prepare_pixel(sh, x + i, y, pr);
                        if (!pr.valid) {  // |n| within an ulp of 0.5: background after all
                            valid_bits &= ~(1 << i);
                            continue;
                        }
                        c = light_sum_scalar(sh, pr, x + i, y);
                    } else {
                        pr.n = glm::vec3(s[0][i], s[1][i], s[2][i]);
                        pr.v = glm::vec3(s[3][i], s[4][i], s[5][i]);
                        pr.surf.albedo = glm::vec3(s[6][i], s[7][i], s[8][i]);
                        pr.surf.roughness = s[9][i];
                        pr.surf.metallic = s[10][i];
                    }
                    if (sh.ambient > 0.0f) {
                        c = shading::add_sky_light(c, pr.surf, pr.n, pr.v, sh.sky_sun, sh.ambient);
                    }
                    cr[i] = c.x;
                    cg[i] = c.y;
                    cb[i] = c.z;
                }
                ar = _mm256_load_ps(cr);
                ag = _mm256_load_ps(cg);
                ab = _mm256_load_ps(cb);
                valid = mask_from_bits(valid_bits);
            }
        }
        // Output: surfaces get their light (plus the input color in mode add), the rest keeps
        // the input color.
        const float *src = sh.color->pixel(x, y);
        float *dst = out.pixel(x, y);
        if (nc == 4 && n == 8) {
            V acc[4], mask[4];
            interleave4x8(ar, ag, ab, zero, acc);
            interleave4x8(valid, valid, valid, zero, mask);
            for (int k = 0; k < 4; ++k) {
                const V in = _mm256_loadu_ps(src + 8 * k);
                const V lit = sh.replace ? acc[k] : vadd(in, acc[k]);
                const V o = select(mask[k], lit, in);
                if (stream) {
                    _mm_stream_ps(dst + 8 * k, _mm256_castps256_ps128(o));
                    _mm_stream_ps(dst + 8 * k + 4, _mm256_extractf128_ps(o, 1));
                } else {
                    _mm256_storeu_ps(dst + 8 * k, o);
                }
            }
            continue;
        }
        _mm256_store_ps(cr, ar);
        _mm256_store_ps(cg, ag);
        _mm256_store_ps(cb, ab);
        std::copy(src, src + n * nc, dst);
        for (int i = 0; i < n; ++i) {
            if ((valid_bits >> i) & 1) {
                float *d = dst + i * nc;
                d[0] = sh.replace ? cr[i] : d[0] + cr[i];
                d[1] = sh.replace ? cg[i] : d[1] + cg[i];
                d[2] = sh.replace ? cb[i] : d[2] + cb[i];
            }
        }
    }
    if (stream) {
        _mm_sfence();  // order the streaming stores before the loop's join
    }
}
#if !defined(__clang__)
#pragma GCC pop_options
#endif
#endif

void execute(NodeContext &ctx)
{
    const Setup &setup = ctx.state().get_or_create<Setup>([&] {
        return parse_setup(ctx.params(), ctx.node().json_path + "/params", ctx.node().describe());
    });
    // Non-finite input never reaches the output (NaN/Inf read as 0; depth's as the sky, below);
    // no copy when everything is finite.
    Image color_storage, normal_storage, albedo_storage, material_storage, position_storage,
        depth_storage, tangent_storage;
    const Image &color = finite_view(ctx.input_pass("image", pass::kColor), 0.0f, color_storage);
    const Image &normal = finite_view(ctx.input_pass("image", pass::kNormal), 0.0f, normal_storage);
    const Image &albedo = finite_view(ctx.input_pass("image", pass::kAlbedo), 0.0f, albedo_storage);
    const Image &material =
        finite_view(ctx.input_pass("image", pass::kMaterial), 0.0f, material_storage);
    const bool from_depth = ctx.get_choice(kPositionFrom) == 1;
    const Image *position =
        from_depth ? nullptr
                   : &finite_view(ctx.input_pass("image", pass::kPosition), 0.0f, position_storage);
    const bool shadows = ctx.get_bool(kShadows);
    const Image *depth = from_depth || shadows
                             ? &finite_view(ctx.input_pass("image", pass::kDepth),
                                            std::numeric_limits<float>::infinity(),
                                            depth_storage,
                                            /*allow_positive_inf=*/true)
                             : nullptr;
    const Image *tangent =
        ctx.get_bool(kAnisotropic)
            ? &finite_view(ctx.input_pass("image", pass::kTangent), 0.0f, tangent_storage)
            : nullptr;
    const Image *id = setup.toon_ids.empty() ? nullptr : &ctx.input_pass("image", pass::kId);
    if (color.channels() < 3 || normal.channels() < 3 || albedo.channels() < 3 ||
        material.channels() < 3 || (position && position->channels() < 3) ||
        (tangent && tangent->channels() < 3)) {
        throw_runtime(ctx.where(),
                      ": color, normal, position, albedo, material and tangent "
                      "need 3 channels");
    }
    const Frame &in = ctx.input("image");
    const Camera camera = in.pixel_camera();  // NDC spans the data window
    const glm::mat4 w2c = camera.require_world_to_camera(ctx.where());
    const glm::mat4 c2w = glm::inverse(w2c);
    const glm::vec3 eye(c2w[3]);
    glm::mat4 w2ndc(1.0f), cam_to_ndc(1.0f);
    if (from_depth || shadows) {
        w2ndc = camera.require_world_to_ndc(ctx.where());
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
    Shading sh;
    sh.setup = &setup;
    sh.color = &color;
    sh.normal = &normal;
    sh.albedo = &albedo;
    sh.material = &material;
    sh.position = position;
    sh.depth = depth;
    sh.tangent = tangent;
    sh.id = id;
    sh.from_depth = from_depth;
    sh.shadows = shadows;
    sh.replace = replace;
    sh.fast_ok = !shadows && !base.burley && !base.energy_compensation &&
                 base.geometry == shading::Geometry::SmithCorrelated;
    sh.avx2_ok = !shadows && !base.burley && base.geometry == shading::Geometry::SmithCorrelated;
    if (base.energy_compensation) {
        sh.energy = &shading::energy_table(base.geometry);
    }
    sh.c2w = c2w;
    sh.cam_to_ndc = cam_to_ndc;
    sh.eye = eye;
    sh.sky_sun = sky_sun;
    sh.width = W;
    sh.height = H;
    sh.ambient = ambient;
    sh.clamp = clamp;
    sh.base = base;
    sh.toon = toon;
    sh.ss = ss;
    for (std::size_t k = 0; k < setup.is_toon.size(); ++k) {
        sh.toon_words[k >> 5] |= std::uint32_t(setup.is_toon[k]) << (k & 31);
    }
    bool use_avx2 = false;
#if POSTHASTE_HAVE_AVX2_TARGET
    use_avx2 = simd::avx2() && sh.avx2_ok;
#endif

    if (use_avx2) {
#if POSTHASTE_HAVE_AVX2_TARGET
        // Whole rows: seven long streams that the hardware prefetcher follows, instead of
        // 64-pixel pieces of them (the tile layout left the loads of color and id waiting on
        // memory). Pixels are independent, so the partition does not change any bits.
        if (sh.energy) {
            parallel_for(0, H, [&](int y) { shade_row_avx2<true>(sh, 0, W, y, out); });
        } else {
            parallel_for(0, H, [&](int y) { shade_row_avx2<false>(sh, 0, W, y, out); });
        }
#endif
    } else {
        parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
            Row row;
            for (int y = tile.y0; y < tile.y1; ++y) {
                shade_row_portable(sh, tile.x0, tile.x1, y, row, out);
            }
        });
    }
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
