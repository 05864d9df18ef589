// nodes/ao.cpp: screen-space ambient occlusion from the depth and normal passes and the camera
// (src/shading/ao/gtao.h: GTAO, Jimenez et al. 2016, with a hard world radius so that it estimates
// what `render` with truth "ao" computes exactly; `method: bitmask`, the same slices with a
// visibility bitmask of finite thickness after Therrien et al. 2023; `method: trace`,
// src/shading/ao/ao_trace.h: rays marched through the depth pass, a slow reference for what the
// depth pass can show). Outputs pass "ao" (1 channel); `apply: multiply` also darkens color by
// it, an approximation (the beauty's direct light is darkened too; a renderer's separate
// indirect pass would be the right target). Non-finite depth reads as the sky (AO 1), a
// non-finite normal as facing the camera.

#include <cmath>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/node.h"
#include "shading/ao/ao_trace.h"
#include "shading/ao/gtao.h"
#include "shading/camera_rays.h"
#include "shading/lighting/occluder_thickness.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kRadius = ParamSpec::real("radius", 1.0)
                                  .range(1e-4, 1e4)
                                  .units("scene units")
                                  .doc("Occluders farther than this from the point do not count.");
constexpr ParamSpec kSlices = ParamSpec::integer("slices", 2)
                                  .range(1, 16)
                                  .doc("gtao, bitmask: slice directions per pixel.")
                                  .only_when("method", "gtao|bitmask");
constexpr ParamSpec kSteps = ParamSpec::integer("steps", 4)
                                 .range(1, 64)
                                 .doc("gtao, bitmask: depth samples on each side of a slice.")
                                 .only_when("method", "gtao|bitmask");
constexpr ParamSpec kDenoise = ParamSpec::boolean("denoise", true)
                                   .doc("Depth-aware 5x5 blur of the per-pixel rotation noise.");
constexpr ParamSpec kIntensity = ParamSpec::real("intensity", 1.0)
                                     .range(0.0, 8.0)
                                     .doc("Exponent on the AO (0: no occlusion at all).");
constexpr ParamSpec kMaxRadiusPx =
    ParamSpec::real("max_radius_px", 256.0)
        .range(1.0, 4096.0)
        .units("px")
        .doc("gtao, bitmask: cap on the search's screen radius (close-ups).")
        .only_when("method", "gtao|bitmask");
constexpr ParamSpec kApply = ParamSpec::choice("apply", "none|multiply", "none")
                                 .doc("none: only the ao pass; multiply: color RGB times ao too.");
constexpr ParamSpec kResolution =
    ParamSpec::choice("resolution", "full|half", "half")
        .doc("half: every other pixel, then a depth-aware upsample (a quarter of the work).");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 0).range(0, 2147483647).doc("Slice rotation pattern.");
constexpr ParamSpec kMethod =
    ParamSpec::choice("method", "gtao|bitmask|trace", "gtao")
        .doc(
            "gtao: horizons in slices; bitmask: the same slices, a sample hiding only "
            "`thickness` behind it; trace: rays marched through the depth pass (slow reference).");
constexpr ParamSpec kRays = ParamSpec::integer("rays", 64)
                                .range(1, 1024)
                                .doc("trace: rays per pixel (a square grid).")
                                .only_when("method", "trace");
constexpr ParamSpec kRaySteps = ParamSpec::integer("ray_steps", 24)
                                    .range(1, 256)
                                    .doc("trace: depth samples along a ray.")
                                    .only_when("method", "trace");
constexpr ParamSpec kThickness =
    ParamSpec::real("thickness", 1.0)
        .range(1e-4, 1e6)
        .units("scene units")
        .doc("bitmask, trace: how far a surface extends behind the depth pass (camera depth).")
        .only_when("method", "bitmask|trace");
constexpr ParamSpec kOccluders =
    ParamSpec::choice("occluders", "extent|constant", "constant")
        .doc(
            "bitmask, trace: how far a surface extends behind the depth pass: as deep as it is "
            "wide on screen (a pole as thin as it looks), up to thickness; or thickness "
            "everywhere.")
        .only_when("method", "bitmask|trace");
constexpr ParamSpec kCrossings =
    ParamSpec::choice("crossings", "all|reachable", "reachable")
        .doc(
            "gtao, bitmask: where a sample lies just beyond the radius, the straight surface "
            "from the last sample inside is an occluder (all); reachable: only where the nearer "
            "of the two reaches back to the farther's depth (each surface reaching back as far "
            "as its widest run of pixels on screen), so a jump to an object standing clear of "
            "the surface behind it is not taken for a surface.")
        .only_when("method", "gtao|bitmask");
constexpr ParamSpec kParams[] = {kRadius,
                                 kSlices,
                                 kSteps,
                                 kDenoise,
                                 kIntensity,
                                 kMaxRadiusPx,
                                 kApply,
                                 kResolution,
                                 kSeed,
                                 kMethod,
                                 kRays,
                                 kRaySteps,
                                 kThickness,
                                 kOccluders,
                                 kCrossings,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image", "depth,normal", false, "Depth, world normals and camera matrices."}, kMaskPort};

constexpr Binding<shading::GtaoParams> kGtaoFields[] = {
    bind<&shading::GtaoParams::radius>(kRadius),
    bind<&shading::GtaoParams::slices>(kSlices),
    bind<&shading::GtaoParams::steps>(kSteps),
    bind<&shading::GtaoParams::max_radius_px>(kMaxRadiusPx),
    bind<&shading::GtaoParams::seed>(kSeed),
};
constexpr Binding<shading::AoTraceParams> kTraceFields[] = {
    bind<&shading::AoTraceParams::radius>(kRadius),
    bind<&shading::AoTraceParams::rays>(kRays),
    bind<&shading::AoTraceParams::steps>(kRaySteps),
    bind<&shading::AoTraceParams::thickness>(kThickness),
    bind<&shading::AoTraceParams::seed>(kSeed),
};

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Image &depth_in = in.image("depth", ctx.where());
    const Image &normal_in = in.image("normal", ctx.where());
    const Camera camera = in.pixel_camera();  // NDC spans the data window
    const shading::CameraRays rays(camera.require_world_to_camera(ctx.where()),
                                   camera.require_world_to_ndc(ctx.where()));
    Image depth_storage, normal_storage;
    const Image &depth =
        finite_view(depth_in, std::numeric_limits<float>::infinity(), depth_storage, true);
    const Image &normal = finite_view(normal_in, 0.0f, normal_storage);
    const float intensity = ctx.get_float(kIntensity);
    Image ao;
    if (intensity == 0.0f) {
        ao = Image(depth.width(), depth.height(), 1);
        ao.fill(1.0f);
    } else {
        const int stride = ctx.get_string(kResolution) == "half" ? 2 : 1;
        const std::string method = ctx.get_string(kMethod);
        const bool extent = method != "gtao" && ctx.get_string(kOccluders) == "extent";
        const bool reachable = method != "trace" && ctx.get_string(kCrossings) == "reachable";
        const shading::AoTraceParams trace = fill(ctx.params(), kTraceFields);
        // How deep each surface is (shading/lighting/occluder_thickness.h; the narrowest of
        // its runs on screen): the bitmask's and the trace's occluders, at most `thickness`. How
        // far back it reaches (its widest run): the gate of GTAO's radius crossings, at most
        // twice the radius (the farthest a crossing's pair lies). GTAO and the bitmask read both
        // on their own grid (half resolution: a quarter of the work, and maps that stay in
        // cache); the trace at every pixel.
        const int map_stride = method == "trace" ? 1 : stride;
        Image occluder, reach;
        if (extent) {
            occluder =
                shading::occluder_thickness(depth, normal, rays, trace.thickness, map_stride);
        }
        if (reachable) {
            reach = shading::occluder_thickness(depth,
                                                normal,
                                                rays,
                                                2.0f * trace.radius,
                                                map_stride,
                                                shading::SurfaceExtent::widest);
        }
        if (method == "trace") {
            shading::AoTraceParams p = trace;
            p.stride = stride;
            p.occluder = extent ? &occluder : nullptr;
            ao = shading::ao_trace(depth, normal, rays, p);
        } else {
            shading::GtaoParams p = fill(ctx.params(), kGtaoFields);
            p.stride = stride;
            if (method == "bitmask") {
                p.thickness = trace.thickness;  // 0 for horizons
            }
            p.thickness_map = extent ? &occluder : nullptr;
            p.reach_map = reachable ? &reach : nullptr;
            p.map_stride = map_stride;
            ao = shading::gtao(depth, normal, rays, p);
        }
        const Image ao_depth = shading::gtao_depth(depth, stride);
        if (ctx.get_bool(kDenoise)) {
            ao = shading::gtao_denoise(ao, ao_depth);
        }
        ao = shading::gtao_upsample(ao, ao_depth, depth, stride);
        parallel_for(0, ao.height(), [&](int y) {
            for (int x = 0; x < ao.width(); ++x) {
                const float v = std::clamp(ao.at(x, y, 0), 0.0f, 1.0f);
                ao.at(x, y, 0) = intensity == 1.0f ? v : std::pow(v, intensity);
            }
        });
    }
    if (ctx.get_string(kApply) == "multiply") {
        const Pass &c = in.pass("color", ctx.where());
        Image color = *c.image;
        const int nc = color.channels();
        parallel_for(0, color.height(), [&](int y) {
            for (int x = 0; x < color.width(); ++x) {
                float *px = color.pixel(x, y);
                for (int k = 0; k < std::min(nc, 3); ++k) {
                    px[k] *= ao.at(x, y, 0);
                }
            }
        });
        ctx.output().set(
            "color", std::make_shared<const Image>(std::move(color)), c.channels, c.storage);
    }
    ctx.output().set(pass::kAo, std::make_shared<const Image>(std::move(ao)), {"Y"});
}

void plan(PlanContext &ctx)
{
    ctx.inputs[0].camera = true;
    if (ctx.params.get_string(kApply) == "multiply") {
        ctx.inputs[0].add("color");
    }
}

}  // namespace

extern const NodeType kAo{
    {"ao",
     "Screen-space ambient occlusion (GTAO) from depth, normals and the camera; pass \"ao\".",
     kInputs,
     kParams,
     "ao",
     /*sink=*/false,
     /*keeps_specular=*/false,
     /*maskable=*/true},
    &execute,
    &plan,
    nullptr,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kAo, kGtaoFields, problems);
        audit(kAo, kTraceFields, problems);
    }};

}  // namespace posthaste::nodes
