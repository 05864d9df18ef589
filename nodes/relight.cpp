// nodes/relight.cpp: add lights to a frame, or replace its lighting, from its G-buffer: normal,
// position (or depth plus the camera matrices), albedo, material (roughness, metallic,
// anisotropy), tangent and material id. Directional, point and spot lights; the metallic-workflow
// BRDF of shading/lighting/brdf.h (Lambert or Burley diffuse, GGX with Smith or Cook-Torrance
// masking, anisotropic GGX, Kulla & Conty 2017 energy compensation) and the rasterizer's toon bands
// and sky light (shading/lighting/lighting.h), so that mode "replace" with the scene's sun and
// sky_ambient reproduces Minecrappy's beauty. Optional screen-space shadows march the depth buffer
// toward each light. Background pixels (no surface) keep their input color. This file declares the
// parameters, checks them, plans the passes and fills shading::relight::Inputs; the method is in
// src/shading/relight.{h,cpp} and relight_kernels.cpp.

#include "shading/lighting/relight.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <set>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/material_params.h"
#include "nodes/node.h"
#include "shading/lighting/brdf.h"
#include "shading/lighting/lighting.h"
#include "shading/lighting/occluder_thickness.h"

namespace posthaste::nodes {
namespace {

using shading::relight::Light;
using shading::relight::LightType;
using shading::relight::Setup;

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
constexpr Binding<Light> kLightFields_[] = {
    bind<&Light::type>(kLightType),
};
constexpr Binding<Light> kPlacedLightFields[] = {
    bind<&Light::position>(kLightPosition),
    bind<&Light::radius>(kLightRadius),
};
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
        .doc(
            "Use material anisotropy with the tangent pass (read only when true); a frame "
            "without a tangent pass is shaded isotropic, with a note.");
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
                                           .doc(
                                               "Assumed depth of every surface in the buffer "
                                               "(with shadow_occluders extent, the most).")
                                           .only_when("shadows", "true");
constexpr ParamSpec kShadowOccluders =
    ParamSpec::choice("shadow_occluders", "extent|constant", "extent")
        .doc(
            "How deep an occluder is taken to be: as deep as it is wide on screen (a pole as "
            "thin as it looks), up to shadow_thickness; or shadow_thickness everywhere.")
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
constexpr Binding<shading::DirectOptions> kDirectFields[] = {
    bind<&shading::DirectOptions::geometry>(kGeometry),
    bind<&shading::DirectOptions::burley>(kDiffuse, "burley"),
    bind<&shading::DirectOptions::energy_compensation>(kEnergy),
};
/// The toon materials' options: their base's, and the bands. DirectOptions starts without toon
/// (0 bands), so these fields have no default of their own.
constexpr Binding<shading::DirectOptions> kToonFields[] = {
    bind<&shading::DirectOptions::toon_bands>(kToonBands).without_default(),
    bind<&shading::DirectOptions::toon_specular_steps>(kToonSpecularSteps).without_default(),
};
constexpr Binding<shading::relight::ScreenShadows> kShadowFields[] = {
    bind<&shading::relight::ScreenShadows::steps>(kShadowSteps),
    bind<&shading::relight::ScreenShadows::distance>(kShadowDistance),
    bind<&shading::relight::ScreenShadows::thickness>(kShadowThickness),
    bind<&shading::relight::ScreenShadows::bias>(kShadowBias),
};
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
                                 kShadowOccluders,
                                 kShadowBias,
                                 kClamp,
                                 kMaterialRoughness,
                                 kMaterialMetallic,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image",
     "color,normal,albedo",
     false,
     "Frame with color and its G-buffer (material, else roughness and metallic); other passes "
     "pass through."},
    kMaskPort};

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
        Light l = fill(r, kLightFields_);
        const float intensity = r.get_float(kLightIntensity);
        l.power = vec3(kLightColor) * intensity;  // derived: colour times intensity
        if (!std::isfinite(l.power.x) || !std::isfinite(l.power.y) || !std::isfinite(l.power.z)) {
            throw_usage(li, ": ", who, ": color times intensity is beyond a float's range");
        }
        if (l.type != LightType::Point) {
            const glm::vec3 d = rescaled_direction(vec3(kLightDirection));
            if (!(glm::length(d) > 0.0f)) {
                throw_usage(li, "/direction: ", who, ": expected a non-zero vector, got [0, 0, 0]");
            }
            l.direction = glm::normalize(d);
        }
        if (l.type != LightType::Directional) {
            fill_into(l, r, std::span<const Binding<Light>>(kPlacedLightFields));
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
    in.camera = true;
    plan_material(ctx);
    in.add(p.get_choice(kPositionFrom) == 0 ? pass::kPosition : pass::kDepth);
    if (p.get_bool(kAnisotropic)) {
        in.add_optional(pass::kTangent);  // most renderers write none
    }
    if (!split_list(p.get_string(kToonIds)).empty()) {
        in.add(pass::kId);
    }
    if (p.get_bool(kShadows)) {
        in.add(pass::kDepth);
    }
}

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
    Image material_const;
    const Image &material =
        finite_view(material_or_constant(ctx, "image", material_const), 0.0f, material_storage);
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
    const bool has_tangent = ctx.input("image").has(pass::kTangent);
    if (ctx.get_bool(kAnisotropic) && !has_tangent) {
        ctx.state().note_once(ctx.node().describe() +
                              ": no tangent pass: anisotropic materials are shaded isotropic");
    }
    const Image *tangent =
        ctx.get_bool(kAnisotropic) && has_tangent
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
    const shading::DirectOptions base = fill(ctx.params(), kDirectFields);
    if (base.energy_compensation) {
        shading::energy_table(base.geometry);  // build before the tiles, not inside one
    }
    shading::DirectOptions toon = base;
    fill_into(toon, ctx.params(), std::span<const Binding<shading::DirectOptions>>(kToonFields));
    glm::vec3 sky_sun(0.0f);
    for (const Light &l : setup.lights) {
        if (l.type == LightType::Directional) {
            sky_sun = l.direction;
            break;
        }
    }
    shading::relight::ScreenShadows ss;
    if (shadows) {
        ss = fill(ctx.params(), kShadowFields);
        ss.depth = depth;
        ss.world_to_ndc = w2ndc;
        ss.z_row = z_row;
    }
    Image occluder;
    if (shadows && ctx.get_choice(kShadowOccluders) == 0) {
        occluder = shading::occluder_thickness(
            *depth, normal, shading::CameraRays(w2c, w2ndc), ss.thickness);
        ss.occluder = &occluder;
    }
    const int W = color.width(), H = color.height();
    const int nc = color.channels();
    Image out = Image::uninitialized(W, H, nc);
    shading::relight::Inputs sh;
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
    sh.kernel_ok = !shadows && !base.burley && base.geometry == shading::Geometry::SmithCorrelated;
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
    shading::relight::shade(sh, out);
    const Pass &cp = in.pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

}  // namespace

extern const NodeType kRelight{{"relight",
                                "Add or replace lights from the G-buffer (GGX BRDF).",
                                kInputs,
                                kParams,
                                "color",
                                /*sink=*/false,
                                /*keeps_specular=*/false,
                                /*maskable=*/true},
                               &execute,
                               &plan,
                               &check,
                               nullptr,
                               [](std::vector<std::string> &problems) {
                                   audit(kRelight, kDirectFields, problems);
                                   audit(kRelight, kToonFields, problems);
                                   audit(kRelight, kShadowFields, problems);
                                   audit(kRelight, kLightFields_, problems);
                                   audit(kRelight, kPlacedLightFields, problems);
                               }};

}  // namespace posthaste::nodes
