// nodes/motion_blur.cpp: blur color along screen motion with a tile-max reconstruction filter
// (src/shading/motion_blur.h: McGuire et al. 2012, Guertin et al. 2014; departures noted there).
// Reads color and depth, plus the motion pass (pixels from the previous frame, x right, y down)
// or, with source "camera" or no motion pass in the input, motion reprojected from depth and
// the previous frame's camera (prevWorldToNDC). The shutter is centred on the frame: each pixel
// blurs over +-shutter/2 x motion. Jitter is hashed from (x, y): the output is thread-count
// independent, and zero motion returns the input bit for bit.

#include "shading/motion_blur.h"

#include <limits>

#include "core/sanitize.h"
#include "nodes/node.h"
#include "shading/reproject.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kShutter =
    ParamSpec::real("shutter", 0.5)
        .range(0.0, 2.0)
        .doc("Shutter open time as a fraction of the frame interval, centred on the frame.")
        .from_header(attr::kShutter);
constexpr ParamSpec kSamples =
    ParamSpec::integer("samples", 16)
        .range(1, 256)
        .doc(
            "Most samples along the neighbourhood's motion per pixel (fewer for short motion; "
            "about "
            "half as many more along a pixel's own motion where it differs).");
constexpr ParamSpec kMaxRadius = ParamSpec::real("max_radius", 64.0)
                                     .range(0.0, 4096.0)
                                     .units("px")
                                     .doc("Longest blur half-extent; longer motion is clamped.");
constexpr ParamSpec kTileSize = ParamSpec::integer("tile_size", 16)
                                    .range(2, 256)
                                    .units("px")
                                    .doc("Tile of the tile-max / neighbour-max reduction.");
constexpr ParamSpec kSoftZ = ParamSpec::real("soft_z", 0.05)
                                 .range(1e-4, 10.0)
                                 .doc("Depth ramp of the in-front test, as a fraction of depth.");
constexpr ParamSpec kTileJitter =
    ParamSpec::real("tile_jitter", 0.25)
        .range(0.0, 1.0)
        .doc("Jitter of the neighbour-max lookup, in tiles (hides tile seams as noise).");
constexpr ParamSpec kCoherence = ParamSpec::real("coherence", 0.1)
                                     .range(0.0, 1.0)
                                     .doc(
                                         "Tiles whose reachable motion vectors differ by at most "
                                         "this fraction of the longest take "
                                         "the cheaper uniform path (0: never).");
constexpr ParamSpec kGroupTolerance =
    ParamSpec::real("group_tolerance", 0.5)
        .range(0.0, 4.0)
        .units("px")
        .doc(
            "Eight adjacent pixels share their sample positions where the paths they sample "
            "agree within this many pixels (a sample moves by at most this much; much faster). "
            "0: every pixel samples on its own.");
constexpr ParamSpec kMotionPass = ParamSpec::string("motion_pass", "motion")
                                      .doc(
                                          "Pass holding the motion (pixels from the previous frame "
                                          "to this one, x right, y down).");
constexpr ParamSpec kSource =
    ParamSpec::choice("source", "motion|camera", "motion")
        .doc(
            "motion: the motion pass (falls back to camera when the input has none); camera: "
            "reproject depth through the previous frame's camera (static world).");
constexpr ParamSpec kMethod = ParamSpec::choice("method", "reconstruct|uniform", "reconstruct")
                                  .doc(
                                      "reconstruct: tile-max reconstruction with depth; "
                                      "uniform: average along each pixel's own motion.");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 0).range(0, 2147483647).doc("Seed of the per-pixel jitter.");
constexpr ParamSpec kParams[] = {kShutter,
                                 kSamples,
                                 kMaxRadius,
                                 kTileSize,
                                 kSoftZ,
                                 kTileJitter,
                                 kCoherence,
                                 kGroupTolerance,
                                 kMotionPass,
                                 kSource,
                                 kMethod,
                                 kSeed};
constexpr PortSpec kInputs[] = {
    {"image", "color,depth", false, "Color and depth; the motion pass unless source is camera."},
};

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    // NaN or Inf in a gathered input would spread over its blur footprint: read finite views
    // (no copy unless such values exist). NaN depth reads as the sky, bad motion as still.
    Image color_storage, depth_storage, motion_storage;
    const Image &color = finite_view(ctx.input_pass("image", pass::kColor), 0.0f, color_storage);
    const Image &depth = finite_view(ctx.input_pass("image", pass::kDepth),
                                     std::numeric_limits<float>::infinity(),
                                     depth_storage,
                                     /*allow_positive_inf=*/true);
    const std::string &motion_pass = ctx.get_string(kMotionPass);
    Image reprojected;
    const Image *motion = nullptr;
    if (ctx.get_choice(kSource) == 0 && in.has(motion_pass)) {
        motion = &finite_view(ctx.input_pass("image", motion_pass), 0.0f, motion_storage);
        if (motion->channels() < 2) {
            throw_runtime(ctx.where(),
                          ": motion pass \"",
                          motion_pass,
                          "\" has ",
                          motion->channels(),
                          " channel(s), expected 2");
        }
    } else {
        reprojected = shading::camera_motion(depth, in.pixel_camera(), ctx.where());
        motion = &reprojected;
    }
    if (color.channels() > 4) {
        throw_runtime(ctx.where(), ": color has ", color.channels(), " channels, expected 1-4");
    }
    for (const Image *p : {&depth, motion}) {
        if (p->width() != color.width() || p->height() != color.height()) {
            throw_runtime(ctx.where(),
                          ": passes differ in size: color is ",
                          color.width(),
                          "x",
                          color.height(),
                          ", another is ",
                          p->width(),
                          "x",
                          p->height());
        }
    }
    shading::MotionBlurOptions o;
    o.method = ctx.get_choice(kMethod) == 0 ? shading::BlurMethod::Reconstruct
                                            : shading::BlurMethod::Uniform;
    o.shutter = ctx.get_float(kShutter);
    if (!ctx.params().given(kShutter) && in.camera.shutter) {
        o.shutter = *in.camera.shutter;
    }
    o.samples = ctx.get_int(kSamples);
    o.max_radius = ctx.get_float(kMaxRadius);
    o.tile = ctx.get_int(kTileSize);
    o.soft_z = ctx.get_float(kSoftZ);
    o.tile_jitter = ctx.get_float(kTileJitter);
    o.coherence = ctx.get_float(kCoherence);
    o.group_tolerance = ctx.get_float(kGroupTolerance);
    o.seed = std::uint32_t(ctx.get_int(kSeed));
    Image out = shading::motion_blur(color, *motion, depth, o);
    const Pass &cp = in.pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

void plan(PlanContext &ctx)
{
    if (ctx.params.get_choice(kSource) == 0) {
        ctx.inputs[0].add(ctx.params.get_string(kMotionPass));
    }
}

}  // namespace

extern const NodeType kMotionBlur{{"motion_blur",
                                   "Blur color along screen motion (tile-max "
                                   "reconstruction, or camera-only from depth).",
                                   kInputs,
                                   kParams,
                                   "color"},
                                  &execute,
                                  &plan};

}  // namespace posthaste::nodes
