// nodes/ssgi.cpp: screen-space diffuse global illumination (src/shading/gi/ssgi.h): one bounce of
// the beauty's light from the surfaces the depth pass shows, gathered along GTAO-style slices at
// a reduced resolution, denoised and brought back with the ao node's depth-aware filters, then
// added to color times the diffuse albedo (albedo (1 - metallic) where a material pass is
// given). Estimates what `render` with truth "gi" computes exactly. Outputs pass "gi" (RGB, the
// light added); non-finite inputs read as in the ao node (depth: sky, normal: facing the
// camera, colour: 0).

#include "shading/gi/ssgi.h"

#include <array>
#include <cmath>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/material_params.h"
#include "nodes/node.h"
#include "nodes/sun_params.h"
#include "shading/camera_rays.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kRadius = ParamSpec::real("radius", 4.0)
                                  .range(1e-4, 1e4)
                                  .units("scene units")
                                  .doc("Surfaces farther than this from the point light nothing.");
constexpr ParamSpec kSlices = ParamSpec::integer("slices", 1)
                                  .range(1, 16)
                                  .doc(
                                      "Slice directions per computed pixel (rotated over a 4x4 "
                                      "pattern that the denoise averages).");
constexpr ParamSpec kSteps =
    ParamSpec::integer("steps", 8).range(1, 64).doc("Depth samples on each side of a slice.");
constexpr ParamSpec kMaxRadiusPx = ParamSpec::real("max_radius_px", 512.0)
                                       .range(1.0, 8192.0)
                                       .units("px")
                                       .doc("Cap on the search's screen radius (close-ups).");
constexpr ParamSpec kResolution =
    ParamSpec::choice("resolution", "full|half|quarter", "quarter")
        .doc(
            "Computed pixels: every pixel, every other or every fourth in x and y, then a "
            "depth-aware upsample.");
constexpr ParamSpec kDenoise = ParamSpec::boolean("denoise", true)
                                   .doc("Depth-aware 5x5 blur of the per-pixel rotation noise.");
constexpr ParamSpec kIntensity =
    ParamSpec::real("intensity", 1.0).range(0.0, 16.0).doc("Scale of the light added.");
constexpr ParamSpec kApply = ParamSpec::choice("apply", "add|none", "add")
                                 .doc("add: color plus the bounce; none: only the gi pass.");
constexpr ParamSpec kFallback =
    ParamSpec::choice("fallback", "environment|none", "environment")
        .doc(
            "What the arcs the march leaves open (the sky, beyond the radius, off screen) see: "
            "the environment input's surfaces, or nothing (as without that input).");
constexpr ParamSpec kReshade =
    ParamSpec::choice("reshade", "auto|on|off", "auto")
        .doc(
            "Re-shade each lit sample's sun response and sky light for the receiver's view, as "
            "ssr re-shades its hits (a polished floor mirrors the horizon onto what stands on "
            "it, darker as the camera sees it). auto: on where the sun's irradiance is known "
            "(param or header posthaste:sunIrradiance), else off with a note; off: samples give "
            "the colour the camera saw.");
constexpr ParamSpec kSunIrradiance = ParamSpec::vec3("sun_irradiance", 0.0, 0.0, 0.0)
                                         .at_least(0.0)
                                         .doc("reshade: the sun's colour times illuminance.")
                                         .from_header("posthaste:sunIrradiance")
                                         .only_when("reshade", "auto|on");
constexpr ParamSpec kSunDirection =
    ParamSpec::vec3("sun_direction", 0.4, 0.75, 0.3)
        .doc("reshade: world direction towards the sun (picks the sky).")
        .from_header("posthaste:sunDirection")
        .only_when("reshade", "auto|on");
constexpr ParamSpec kSkyScale =
    ParamSpec::real("sky_scale", 1.0)
        .range(0.0, 1e6)
        .doc("reshade: the renderer's sky-light scale (a scene's sky_ambient).")
        .from_header("posthaste:skyAmbient")
        .only_when("reshade", "auto|on");
constexpr ParamSpec kReflectedSun =
    ParamSpec::boolean("reflected_sun", true)
        .doc(
            "reshade: trace the sun's light that the frame's glossy planes reflect (a polished "
            "floor's or a mirror's highlight) toward its mirror image, one ray per computed "
            "pixel and plane, instead of leaving it to the slices' few samples.")
        .only_when("reshade", "auto|on");
constexpr ParamSpec kRoughness = ParamSpec(kMaterialRoughness).only_when("reshade", "auto|on");
constexpr ParamSpec kMetallic = ParamSpec(kMaterialMetallic).only_when("reshade", "auto|on");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 0).range(0, 2147483647).doc("Slice rotation pattern.");
constexpr ParamSpec kParams[] = {
    kRadius,    kSlices,   kSteps,   kMaxRadiusPx,   kResolution,   kDenoise,   kIntensity,
    kApply,     kFallback, kReshade, kSunIrradiance, kSunDirection, kSkyScale,  kReflectedSun,
    kRoughness, kMetallic, kSeed,    kMaskPass,      kMaskChannel,  kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image",
     "color,depth,normal,albedo",
     false,
     "The lit beauty (no indirect light in it), depth, world normals, albedo and the camera."},
    {"environment",
     "color,depth",
     true,
     "Optional: a latitude-longitude probe from near the camera (render's projection latlong) "
     "with color and depth (distance, +inf for the sky): what the screen does not show."},
    kMaskPort};

constexpr Binding<shading::SsgiParams> kFields[] = {
    bind<&shading::SsgiParams::radius>(kRadius),
    bind<&shading::SsgiParams::slices>(kSlices),
    bind<&shading::SsgiParams::steps>(kSteps),
    bind<&shading::SsgiParams::max_radius_px>(kMaxRadiusPx),
    bind<&shading::SsgiParams::seed>(kSeed),
    bind<&shading::SsgiParams::sun_irradiance>(kSunIrradiance),
    bind<&shading::SsgiParams::sky_scale>(kSkyScale),
    bind<&shading::SsgiParams::reflected_sun>(kReflectedSun),
};

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Pass &color_pass = in.pass(pass::kColor, ctx.where());
    const Image &depth_in = in.image(pass::kDepth, ctx.where());
    const Image &normal_in = in.image(pass::kNormal, ctx.where());
    const Image &albedo_in = in.image(pass::kAlbedo, ctx.where());
    const Camera camera = in.pixel_camera();  // NDC spans the data window
    const shading::CameraRays rays(camera.require_world_to_camera(ctx.where()),
                                   camera.require_world_to_ndc(ctx.where()));
    // Non-finite depth, normals and albedo are read as the sky and as 0 where ssgi and its
    // resolve read them (not scanned whole first: 58 MB at 1080p).
    const Image &depth = depth_in, &normal = normal_in, &albedo = albedo_in;
    const Image *material = in.has(pass::kMaterial) ? &in.image(pass::kMaterial) : nullptr;
    const float intensity = ctx.get_float(kIntensity);
    const int w = depth.width(), h = depth.height();
    // apply: add, into a new colour pass.
    const bool adding = ctx.get_choice(kApply) == 0;
    const Image &in_color = *color_pass.image;
    Image color = adding ? Image::uninitialized(w, h, in_color.channels()) : Image();
    Image gi;
    if (!(intensity > 0.0f)) {
        gi = Image(w, h, 3);
        if (adding) {
            parallel_for(0, h, [&](int y) {
                shading::ssgi_add_row(in_color.pixel(0, y),
                                      gi.pixel(0, y),
                                      w,
                                      in_color.channels(),
                                      color.pixel(0, y));
            });
        }
    } else {
        shading::SsgiParams p = fill(ctx, kFields, HeaderSource::of(in));
        const int reshade_mode = ctx.get_choice(kReshade);  // 0 auto, 1 on, 2 off
        bool reshade = reshade_mode != 2 && p.sun_irradiance != glm::vec3(0.0f);
        if (reshade_mode == 1 && !reshade) {
            throw_param(ctx.where(),
                        kSunIrradiance.name,
                        "reshade on needs the sun's irradiance (give sun_irradiance, or a frame "
                        "whose header has posthaste:sunIrradiance)");
        }
        if (reshade_mode == 0 && !reshade) {
            ctx.state().note_once(ctx.node().describe() +
                                  ": the sun's irradiance is not known (no sun_irradiance, no "
                                  "header posthaste:sunIrradiance): samples keep the colour the "
                                  "camera saw (reshade off)");
        }
        const glm::vec3 sun_dir = sun_direction(ctx, kSunDirection, in);
        p.sun_direction = sun_dir / glm::length(sun_dir);
        check_sun_irradiance(ctx, kSunIrradiance, p.sun_irradiance);
        // The samples' material and the sun's visibility, for the re-shading.
        // Read at the computed pixels only, which ssgi makes finite as it reads them.
        Image material_const;
        shading::SsgiSurfaces surfaces;
        if (reshade) {
            surfaces.albedo = &albedo;
            surfaces.material = &material_or_constant(ctx, "image", material_const);
            if (in.has("shadow")) {
                surfaces.shadow = &in.image("shadow", ctx.where());
            }
        }
        p.stride = std::array{1, 2, 4}[std::size_t(ctx.get_choice(kResolution))];
        shading::SsgiEnvironment env;
        Image env_color_s, env_depth_s;
        if (ctx.has_input("environment") && ctx.get_choice(kFallback) == 0) {
            const Frame &e = ctx.input("environment");
            const std::string where = ctx.where() + ": input \"environment\"";
            const Image &ec = e.image(pass::kColor, where), &ed = e.image(pass::kDepth, where);
            if (ed.width() != ec.width() || ed.height() != ec.height()) {
                throw_runtime(where,
                              ": pass \"depth\" is ",
                              ed.width(),
                              "x",
                              ed.height(),
                              ", pass \"color\" ",
                              ec.width(),
                              "x",
                              ec.height());
            }
            env.radiance = &finite_view(ec, 0.0f, env_color_s);
            env.distance =
                &finite_view(ed, std::numeric_limits<float>::infinity(), env_depth_s, true);
        }
        const Image light = shading::ssgi(depth,
                                          normal,
                                          *color_pass.image,
                                          rays,
                                          p,
                                          env.radiance ? &env : nullptr,
                                          surfaces.material ? &surfaces : nullptr);
        shading::SsgiApply apply{&albedo, material, intensity};
        if (adding) {
            // The sum made row by row in the resolve, while each row of gi is in cache.
            apply.color = &in_color;
            apply.sum = &color;
        }
        gi = shading::ssgi_resolve(light, depth, normal, p.stride, ctx.get_bool(kDenoise), &apply);
    }
    if (adding) {
        ctx.output().set(pass::kColor,
                         std::make_shared<const Image>(std::move(color)),
                         color_pass.channels,
                         color_pass.storage);
    }
    ctx.output().set("gi", std::make_shared<const Image>(std::move(gi)), {"R", "G", "B"});
}

void plan(PlanContext &ctx)
{
    ctx.inputs[0].camera = true;
    plan_material(ctx);
    ctx.inputs[0].add_optional("shadow");  // the sun's visibility at the samples, where given
}

}  // namespace

extern const NodeType kSsgi{
    {"ssgi",
     "Screen-space diffuse global illumination: one bounce of the beauty's light from the "
     "surfaces the depth pass shows; pass \"gi\".",
     kInputs,
     kParams,
     "gi",
     /*sink=*/false,
     /*keeps_specular=*/false,
     /*maskable=*/true},
    &execute,
    &plan,
    nullptr,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kSsgi, kFields, problems); }};

}  // namespace posthaste::nodes
