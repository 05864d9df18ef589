// nodes/ssr.cpp: screen-space reflections from the colour, depth, normal, albedo and material
// passes and the camera (src/shading/ssr/ssr.h): glossy pixels' GGX rays marched through the depth
// pass, what they meet on screen replacing the sky the renderer reflected; estimates what
// `render` with truth "reflections" computes exactly. Non-finite depth reads as the sky,
// non-finite normals and materials leave their pixel alone, non-finite colour reads as black.

#include "shading/ssr/ssr.h"

#include <cmath>
#include <optional>
#include <string>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/material_params.h"
#include "nodes/node.h"
#include "nodes/sun_params.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kRays = ParamSpec::integer("rays", 4).range(1, 64).doc(
    "GGX rays per pixel at roughness 0.35 and above; ceil(rays roughness / 0.35) "
    "below (one on a mirror).");
constexpr ParamSpec kSteps =
    ParamSpec::integer("steps", 16).range(1, 512).doc("Depth samples along each ray.");
constexpr ParamSpec kRefine =
    ParamSpec::integer("refine", 5).range(0, 16).doc("Bisection steps after a hit.");
constexpr ParamSpec kThickness = ParamSpec::real("thickness", 0.5)
                                     .range(1e-4, 1e4)
                                     .units("scene units")
                                     .doc("How far a surface is taken to extend behind its depth.");
constexpr ParamSpec kMaxDistance = ParamSpec::real("max_distance", 60.0)
                                       .range(1e-3, 1e6)
                                       .units("scene units")
                                       .doc("How far a reflected ray may travel.");
constexpr ParamSpec kEdgeFade =
    ParamSpec::real("edge_fade", 0.02)
        .range(0.0, 0.5)
        .doc("Hits within this fraction of the smaller image side from an edge fade to the sky.");
constexpr ParamSpec kMaxRoughness =
    ParamSpec::real("max_roughness", 0.78)
        .range(0.0, 1.0)
        .doc("Rougher surfaces are left alone (the renderer's glossy cut-off is 0.78).");
constexpr ParamSpec kSkyScale = ParamSpec::real("sky_scale", 1.0)
                                    .range(0.0, 1e6)
                                    .doc("The renderer's sky-light scale (a scene's sky_ambient).")
                                    .from_header("posthaste:skyAmbient");
constexpr ParamSpec kSunDirection = ParamSpec::vec3("sun_direction", 0.4, 0.75, 0.3)
                                        .doc("World direction towards the sun (picks the sky).")
                                        .from_header("posthaste:sunDirection");
constexpr ParamSpec kOffscreen =
    ParamSpec::choice("offscreen", "sky|extend", "sky")
        .doc(
            "A ray leaving the screen in front of the last surface it passed: sees the sky, or "
            "that surface (taken to go on past the edge).");
constexpr ParamSpec kDenoise =
    ParamSpec::integer("denoise", 3)
        .range(0, 8)
        .units("px")
        .doc("Radius of the resolve that averages neighbours' rays on the same surface (0: off).");
constexpr ParamSpec kResolution =
    ParamSpec::choice("resolution", "auto|full|half|quarter", "auto")
        .doc(
            "half: rays from every other pixel in x and y (a quarter of the rays), quarter: from "
            "every fourth (a sixteenth); the resolve fills the others from traced neighbours on "
            "the same surface. auto: quarter from 1280 pixels wide, half from 480, full "
            "below.");
constexpr ParamSpec kIntensity =
    ParamSpec::real("intensity", 1.0)
        .range(0.0, 1.0)
        .doc("Share of the change applied (0: the colour unchanged, nothing traced).");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 0).range(0, 2147483647).doc("Ray jitter pattern.");
constexpr ParamSpec kEnvironmentPosition =
    ParamSpec::vec3("environment_position", 0.0, 0.0, 0.0)
        .units("scene units")
        .doc(
            "Where the environment input was taken (a reflection probe's position), for its "
            "depth pass.")
        .from_header("posthaste:probePosition");
constexpr ParamSpec kParallax =
    ParamSpec::boolean("parallax", true)
        .doc(
            "With an environment input that has a depth pass (distances from its position): a ray "
            "sees the probe's surface where it crosses it; off: everything in it infinitely far.");
constexpr ParamSpec kSunIrradiance =
    ParamSpec::vec3("sun_irradiance", 0.0, 0.0, 0.0)
        .at_least(0.0)
        .doc(
            "The sun's colour times illuminance, to re-shade a hit's sun response and sky light "
            "as the reflected ray sees them (0: hits keep the colour the camera saw).")
        .from_header("posthaste:sunIrradiance");
constexpr ParamSpec kBrdf =
    ParamSpec::choice("brdf", "posthaste|ggx", "posthaste")
        .doc(
            "The colour pass's specular term, which weighs the reflections: posthaste's (Schlick "
            "at n.v times the gloss (1 - roughness)^2, the bundled renderer's), or a physically "
            "based GGX lobe's directional albedo (a production renderer's: Cycles, Arnold...).");
constexpr ParamSpec kParams[] = {kRays,
                                 kSteps,
                                 kRefine,
                                 kThickness,
                                 kMaxDistance,
                                 kEdgeFade,
                                 kMaxRoughness,
                                 kSkyScale,
                                 kSunDirection,
                                 kOffscreen,
                                 kDenoise,
                                 kResolution,
                                 kIntensity,
                                 kSeed,
                                 kEnvironmentPosition,
                                 kParallax,
                                 kSunIrradiance,
                                 kBrdf,
                                 kMaterialRoughness,
                                 kMaterialMetallic,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image",
     "color,depth,normal,albedo",
     false,
     "Colour, depth, world normals, albedo, material (else roughness and metallic) and camera "
     "matrices."},
    {"environment",
     "color",
     true,
     "Optional: what rays the screen does not answer see instead of the sky: a "
     "latitude-longitude map (render's projection latlong, a renderer's panorama or HDRI; +y "
     "up, the middle column looking down -z), with an optional depth pass of distances from "
     "environment_position."},
    {"world",
     "color",
     true,
     "Optional: what the colour pass's glossy surfaces reflect already, which the reflections "
     "replace: a renderer's world as a latitude-longitude panorama (the layout of "
     "environment), looked up in the mirror direction. Without it, the sky model "
     "(sun_direction, sky_scale): the bundled renderer's."},
    kMaskPort};

constexpr Binding<shading::SsrParams> kFields[] = {
    bind<&shading::SsrParams::rays>(kRays),
    bind<&shading::SsrParams::steps>(kSteps),
    bind<&shading::SsrParams::refine>(kRefine),
    bind<&shading::SsrParams::thickness>(kThickness),
    bind<&shading::SsrParams::max_distance>(kMaxDistance),
    bind<&shading::SsrParams::edge_fade>(kEdgeFade),
    bind<&shading::SsrParams::max_roughness>(kMaxRoughness),
    bind<&shading::SsrParams::seed>(kSeed),
    bind<&shading::SsrParams::intensity>(kIntensity),
    bind<&shading::SsrParams::extend>(kOffscreen, "extend"),
    bind<&shading::SsrParams::denoise>(kDenoise),
    bind<&shading::SsrParams::sun_irradiance>(kSunIrradiance),
    bind<&shading::SsrParams::ggx>(kBrdf, "ggx"),
};
/// The sky model's scale: bound only where the sky is seen (execute).
constexpr Binding<shading::SsrParams> kSkyFields[] = {
    bind<&shading::SsrParams::sky_scale>(kSkyScale),
};
constexpr Binding<shading::Probe> kProbeFields[] = {
    bind<&shading::Probe::position>(kEnvironmentPosition),
    bind<&shading::Probe::max_distance>(kMaxDistance),
    bind<&shading::Probe::thickness>(kThickness),
    bind<&shading::Probe::march_steps>(kSteps),
    bind<&shading::Probe::refine_steps>(kRefine),
};

/// The traced grid's stride for `resolution` on a frame `width` pixels wide. auto traces at
/// least 240 columns, and quarter resolution only from 1280: fewer cells leave each one's few
/// rays, meeting a sharp highlight, as sparse bright samples that the resolve spreads, and
/// blur what is reflected (docs/ACCURACY.md, "Reflections": quarter removes 65 % of the
/// glossy scene's error at 1920x1080, 52 % at 960x540, where half removes 60 %).
int ssr_stride(const std::string &resolution, int width)
{
    if (resolution == "auto") {
        return width >= 1280 ? 4 : width >= 480 ? 2 : 1;
    }
    return resolution == "quarter" ? 4 : resolution == "half" ? 2 : 1;
}

/// The environment input sanitised into `probe` (its colour kept in `color_s`, its distances
/// resampled into `cube`).
void environment_probe(NodeContext &ctx,
                       shading::Probe &probe,
                       Image &color_s,
                       std::optional<shading::DistanceCube> &cube)
{
    const Frame &env = ctx.input("environment");
    const std::string where = ctx.where() + ": input \"environment\"";
    const Image &color = env.image("color", where);
    if (color.channels() < 3) {
        throw_runtime(
            where, ": expected an RGB(A) color pass, got ", color.channels(), " channels");
    }
    probe.radiance = &finite_view(color, 0.0f, color_s);
    if (!ctx.get_bool(kParallax) || !env.has("depth")) {
        return;
    }
    const Image &depth = env.image("depth", where);
    if (depth.width() != color.width() || depth.height() != color.height()) {
        throw_runtime(where,
                      ": pass \"depth\" is ",
                      depth.width(),
                      "x",
                      depth.height(),
                      ", pass \"color\" ",
                      color.width(),
                      "x",
                      color.height());
    }
    if (!ctx.params().given(kEnvironmentPosition) &&
        !env.attributes.find_pv(std::string(kEnvironmentPosition.header))) {
        throw_runtime(where,
                      ": has a depth pass but no position (param \"environment_position\" or "
                      "header posthaste:probePosition; or parallax false)");
    }
    fill_into(
        probe, ctx, std::span<const Binding<shading::Probe>>(kProbeFields), HeaderSource::of(env));
    if (!std::isfinite(probe.position.x) || !std::isfinite(probe.position.y) ||
        !std::isfinite(probe.position.z)) {
        throw_runtime(where, ": param \"environment_position\" must be finite");
    }
    // Distances: NaN and -inf read as the sky (no parallax there).
    Image depth_s;
    cube.emplace(finite_view(depth, std::numeric_limits<float>::infinity(), depth_s, true));
    probe.distance = &*cube;
}

void plan(PlanContext &ctx)
{
    ctx.inputs[0].camera = true;
    // The sun's visibility at the hits, for their re-shading, where the frame has it.
    ctx.inputs[0].add_optional("shadow");
    plan_material(ctx);
    if (ctx.connected.size() > 1 && ctx.connected[1] && ctx.params.get_bool(kParallax)) {
        ctx.inputs[1].add_optional("depth");  // the probe's distances, where it has them
    }
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Pass &color_pass = in.pass("color", ctx.where());
    if (ctx.get_float(kIntensity) == 0.0f) {
        ctx.output().set("color", color_pass.image, color_pass.channels, color_pass.storage);
        return;
    }
    const Image &color_in = *color_pass.image;
    const Image &depth_in = in.image("depth", ctx.where());
    const Image &normal_in = in.image("normal", ctx.where());
    const Image &albedo_in = in.image("albedo", ctx.where());
    Image material_const;
    const Image &material_in = material_or_constant(ctx, "image", material_const);
    if (color_in.channels() < 3 || normal_in.channels() < 3 || albedo_in.channels() < 3 ||
        material_in.channels() < 2) {
        throw_runtime(ctx.where(),
                      ": expected RGB color, albedo and normal and a two-channel material pass");
    }
    const Camera camera = in.pixel_camera();  // NDC spans the data window
    shading::SsrInputs si;
    si.world_to_camera = camera.require_world_to_camera(ctx.where());
    si.world_to_ndc = camera.require_world_to_ndc(ctx.where());
    Image color_s, depth_s, normal_s, albedo_s, material_s;
    const float inf = std::numeric_limits<float>::infinity();
    si.color = &finite_view(color_in, 0.0f, color_s);
    si.depth = &finite_view(depth_in, inf, depth_s, true);
    si.normal = &finite_view(normal_in, 0.0f, normal_s);
    si.albedo = &finite_view(albedo_in, 0.0f, albedo_s);
    si.material = &finite_view(material_in, 1.0f, material_s);  // rough: left alone

    shading::SsrParams p = fill(ctx, kFields, HeaderSource::of(in));
    const std::string &resolution = ctx.get_string(kResolution);
    p.stride = ssr_stride(resolution, depth_in.width());  // derived from the image's width
    check_sun_irradiance(ctx, kSunIrradiance, p.sun_irradiance);
    // The sky model is seen by the rays an environment input does not answer, as what the
    // colour reflects already (without a world input) and in re-shaded hits; a renderer's frame
    // with its world and environment connected uses none of it, and says nothing of it.
    // (Values the graph gives are checked whether or not they are used.)
    if (!ctx.has_input("environment") || !ctx.has_input("world") ||
        p.sun_irradiance != glm::vec3(0.0f) || ctx.params().given(kSunDirection) ||
        ctx.params().given(kSkyScale)) {
        // sky_scale, from the graph or the header, is held to its range by the parameter's rules.
        fill_into(
            p, ctx, std::span<const Binding<shading::SsrParams>>(kSkyFields), HeaderSource::of(in));
        const glm::vec3 sun_dir = sun_direction(ctx, kSunDirection, in);
        p.sun_direction = sun_dir / glm::length(sun_dir);
    }
    Image shadow_s;
    if (p.sun_irradiance != glm::vec3(0.0f) && in.has("shadow")) {
        si.shadow = &finite_view(in.image("shadow", ctx.where()), 0.0f, shadow_s);
    }
    shading::Probe probe;
    Image env_color_s;
    std::optional<shading::DistanceCube> env_cube;
    if (ctx.has_input("environment")) {
        environment_probe(ctx, probe, env_color_s, env_cube);
        si.environment = &probe;
    }
    Image world_s;
    if (ctx.has_input("world")) {
        const std::string where = ctx.where() + ": input \"world\"";
        const Image &world = ctx.input("world").image("color", where);
        if (world.channels() < 3) {
            throw_runtime(
                where, ": expected an RGB(A) color pass, got ", world.channels(), " channels");
        }
        si.world = &finite_view(world, 0.0f, world_s);
    }
    Image out = shading::ssr(si, p);
    ctx.output().set("color",
                     std::make_shared<const Image>(std::move(out)),
                     color_pass.channels,
                     color_pass.storage);
}

}  // namespace

extern const NodeType kSsr{
    {"ssr",
     "Screen-space reflections of glossy surfaces from colour, depth, normals, albedo, material "
     "and the camera.",
     kInputs,
     kParams,
     "color",
     /*sink=*/false,
     /*keeps_specular=*/false,
     /*maskable=*/true},
    &execute,
    &plan,
    nullptr,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kSsr, kFields, problems);
        audit(kSsr, kSkyFields, problems);
        audit(kSsr, kProbeFields, problems);
    }};

}  // namespace posthaste::nodes
