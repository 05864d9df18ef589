// nodes/motion_blur.cpp: blur color along screen motion with a tile-max reconstruction filter
// (src/shading/motion_blur/motion_blur.h: McGuire et al. 2012, Guertin et al. 2014; departures
// noted there). Reads color and depth, plus the motion pass (pixels from the previous frame, x
// right, y down) or, with source "camera" or no motion pass in the input, motion reprojected from
// depth and the previous frame's camera (prevWorldToNDC). The shutter is centred on the frame: each
// pixel blurs over +-shutter/2 x motion. Jitter is hashed from (x, y): the output is thread-count
// independent, and zero motion returns the input bit for bit.

#include "shading/motion_blur/motion_blur.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/node.h"
#include "nodes/split_params.h"
#include "shading/lighting/lighting_split.h"
#include "shading/motion_blur/reproject.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kShutter =
    ParamSpec::real("shutter", 0.5)
        .range(0.0, 2.0)
        .doc("Shutter open time as a fraction of the frame interval, centred on the frame.")
        .from_header(attr::kShutter);
constexpr ParamSpec kSamples =
    ParamSpec::integer("samples", 32)
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
                                 .doc("Depth ramp of the in-front test, as a fraction of depth.")
                                 .only_when("method", "reconstruct");
constexpr ParamSpec kTileJitter =
    ParamSpec::real("tile_jitter", 0.25)
        .range(0.0, 1.0)
        .doc("Jitter of the neighbour-max lookup, in tiles (hides tile seams as noise).");
constexpr ParamSpec kCoherence = ParamSpec::real("coherence", 0.1)
                                     .range(0.0, 1.0)
                                     .doc(
                                         "Tiles whose reachable motion vectors differ by at most "
                                         "this fraction of the longest take "
                                         "the cheaper uniform path (0: never).")
                                     .only_when("method", "reconstruct");
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
constexpr ParamSpec kSpecular =
    ParamSpec::choice("specular", "auto|off", "auto")
        .doc(
            "auto: where the input has the specular and specular_motion passes (asked for where "
            "a source can give them), blur the specular share along specular_motion and the rest "
            "of color along diffuse_motion where the input has it and motion_pass is not "
            "given, else along the motion pass (source motion only); off: blur color as one.");
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
                                 kSpecular,
                                 kSpecularKnee,
                                 kSeed,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image", "color,depth", false, "Color and depth; the motion pass unless source is camera."},
    kMaskPort};

constexpr Binding<shading::MotionBlurOptions> kFields[] = {
    bind<&shading::MotionBlurOptions::method>(kMethod),
    bind<&shading::MotionBlurOptions::shutter>(kShutter),
    bind<&shading::MotionBlurOptions::samples>(kSamples),
    bind<&shading::MotionBlurOptions::max_radius>(kMaxRadius),
    bind<&shading::MotionBlurOptions::tile>(kTileSize),
    bind<&shading::MotionBlurOptions::soft_z>(kSoftZ),
    bind<&shading::MotionBlurOptions::tile_jitter>(kTileJitter),
    bind<&shading::MotionBlurOptions::coherence>(kCoherence),
    bind<&shading::MotionBlurOptions::group_tolerance>(kGroupTolerance),
    bind<&shading::MotionBlurOptions::seed>(kSeed),
};

void check_size(const NodeContext &ctx, const Image &color, const Image &p, const char *name)
{
    if (p.width() != color.width() || p.height() != color.height()) {
        throw_runtime(ctx.where(),
                      ": pass \"",
                      name,
                      "\" is ",
                      p.width(),
                      "x",
                      p.height(),
                      ", color is ",
                      color.width(),
                      "x",
                      color.height());
    }
}

// The lighting split: color less its specular share blurred along the surface motion, plus the
// specular share blurred along its own (a highlight on a rolling ball moves with the ball's
// centre, not with its turning surface); shading/lighting/lighting_split.h. Written as color plus
// what each blur changed, so a still frame keeps its bits.
Image blur_split(NodeContext &ctx,
                 const Image &color,
                 const Image &motion,
                 const Image &depth,
                 const shading::MotionBlurOptions &o,
                 bool rest_along_diffuse)
{
    Image diffuse_motion_storage;
    const Image &spec = ctx.input_pass("image", pass::kSpecular);
    // Read only where a highlight is lifted and around it, non-finite components as still
    // (finite_view's reading, without its scan of the whole pass).
    const Image &spec_motion = ctx.input_pass("image", pass::kSpecularMotion);
    check_size(ctx, color, spec, pass::kSpecular);
    check_size(ctx, color, spec_motion, pass::kSpecularMotion);
    const Image *rest_motion = &motion;
    if (rest_along_diffuse) {
        rest_motion = &finite_view(
            ctx.input_pass("image", pass::kDiffuseMotion), 0.0f, diffuse_motion_storage);
        check_size(ctx, color, *rest_motion, pass::kDiffuseMotion);
        if (rest_motion->channels() < 2) {
            throw_runtime(ctx.where(),
                          ": pass \"diffuse_motion\" has ",
                          rest_motion->channels(),
                          " channel(s), expected 2");
        }
    }
    if (spec.channels() < 3 || spec_motion.channels() < 2 || color.channels() < 3) {
        throw_runtime(ctx.where(),
                      ": the lighting split needs RGB color and specular and a 2-channel "
                      "specular_motion (have ",
                      color.channels(),
                      ", ",
                      spec.channels(),
                      ", ",
                      spec_motion.channels(),
                      "; specular: off blurs color as one)");
    }
    const int w = color.width(), h = color.height();
    // Where the specular share moves as the rest does (flat faces), one blur of the two is the
    // same sum: only the pixels whose shares part ways (balls) keep their specular share apart.
    // A parting pixel spreads at most max_radius; what lands there is gathered from as far
    // again, plus the tiles of the neighbour-max lookup.
    const int reach = 2 * (int(std::ceil(o.max_radius)) + 2 * o.tile);
    const float knee = ctx.get_float(kSpecularKnee);
    const auto parts_at = [&](int x, int y) {
        const float *a = spec_motion.pixel(x, y), *b = rest_motion->pixel(x, y);
        return std::abs(finite_or_zero(a[0]) - b[0]) > 1e-3f ||
               std::abs(finite_or_zero(a[1]) - b[1]) > 1e-3f;
    };
    // The knee first: most pixels hold no highlight, and then their motions are not read.
    const shading::SplitRegion region =
        shading::find_split(w, h, reach, [&](int y, std::uint8_t *row) {
            shading::mark_highlights(spec, knee, y, row, parts_at);
        });
    if (region.empty()) {
        return shading::motion_blur(color, *rest_motion, depth, o);
    }
    const Rect &crop = region.crop;
    const Image share = shading::share_color(spec, region, knee);
    // The other pixels hold no share but keep their motion, so that both blurs see the same
    // coverage (what passes in front of what, for how long); those whose share parts ways below
    // the knee lend the share's blur their specular_motion, so that the share's image stays one
    // surface around its highlight.
    Image share_motion = Image::uninitialized(crop.width(), crop.height(), 2);
    Image share_depth = Image::uninitialized(crop.width(), crop.height(), 1);
    parallel_for(0, crop.height(), [&](int j) {
        const int y = crop.y0 + j;
        for (int i = 0; i < crop.width(); ++i) {
            const int x = crop.x0 + i;
            float *d = share_motion.pixel(i, j);
            if (parts_at(x, y)) {
                const float *m = spec_motion.pixel(x, y);
                d[0] = finite_or_zero(m[0]);
                d[1] = finite_or_zero(m[1]);
            } else {
                const float *m = rest_motion->pixel(x, y);
                d[0] = m[0];
                d[1] = m[1];
            }
            *share_depth.pixel(i, j) = depth.at(x, y, 0);
        }
    });
    shading::MotionBlurOptions rest_options = o;
    rest_options.subtract = &share;
    rest_options.subtract_x0 = crop.x0;
    rest_options.subtract_y0 = crop.y0;
    Image out = shading::motion_blur(color, *rest_motion, depth, rest_options);
    shading::MotionBlurOptions share_options = o;
    share_options.skip_empty = true;
    const Image share_blurred =
        shading::motion_blur(share, share_motion, share_depth, share_options);
    shading::compose_split(color, share, share_blurred, region, /*rest_still=*/false, out);
    return out;
}

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
    const bool split = ctx.get_choice(kSpecular) == 0 && ctx.get_choice(kSource) == 0 &&
                       in.has(motion_pass) && in.has(pass::kSpecular) &&
                       in.has(pass::kSpecularMotion);
    // The split blurs the rest along diffuse_motion, unless the graph names another motion pass.
    const bool rest_along_diffuse =
        split && in.has(pass::kDiffuseMotion) && motion_pass == kMotionPass.default_text;
    Image reprojected;
    const Image *motion = nullptr;
    if (rest_along_diffuse) {
        // The split blurs the rest along diffuse_motion (checked there): motion is not read.
        motion = &ctx.input_pass("image", motion_pass);
    } else if (ctx.get_choice(kSource) == 0 && in.has(motion_pass)) {
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
        // Source camera, or no motion pass in the input: motion reprojected from depth (said
        // once).
        const bool fallback = ctx.get_choice(kSource) == 0;
        if (fallback && ctx.params().given(kMotionPass)) {
            // A pass named in the graph that the frame lacks is a typo, not a camera-only frame
            // (it fell back with a note, and the result changed silently).
            (void)ctx.input_pass("image", motion_pass);  // the one-line "no pass" error
        }
        const std::string who = fallback ? ctx.where() + " (no pass \"" + motion_pass +
                                               "\": motion reprojected from depth)"
                                         : ctx.where();
        if (fallback) {
            ctx.state().note_once(str_cat(ctx.node().describe(),
                                          ": no pass \"",
                                          motion_pass,
                                          "\" in the input: motion reprojected from depth through "
                                          "the previous frame's camera (a still world)"));
        }
        reprojected = shading::camera_motion(depth, in.pixel_camera(), who);
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
    const shading::MotionBlurOptions o = fill(ctx, kFields, HeaderSource::of(in));
    Image out = split ? blur_split(ctx, color, *motion, depth, o, rest_along_diffuse)
                      : shading::motion_blur(color, *motion, depth, o);
    const Pass &cp = in.pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

void plan(PlanContext &ctx)
{
    if (ctx.params.get_choice(kSource) == 1) {
        ctx.inputs[0].camera = true;  // camera-only motion reprojects depth through it
    }
    if (ctx.params.get_choice(kSource) == 0) {
        // Without it, motion is reprojected from depth through the header's camera.
        ctx.inputs[0].add_optional(ctx.params.get_string(kMotionPass));
        if (ctx.params.get_choice(kSpecular) == 0) {
            ctx.inputs[0].add_optional(pass::kSpecular);
            ctx.inputs[0].add_optional(pass::kSpecularMotion);
            if (ctx.params.get_string(kMotionPass) == kMotionPass.default_text) {
                ctx.inputs[0].add_optional(pass::kDiffuseMotion);
            }
        }
    }
}

}  // namespace

extern const NodeType kMotionBlur{
    {"motion_blur",
     "Blur color along screen motion (tile-max "
     "reconstruction, or camera-only from depth).",
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
    [](std::vector<std::string> &problems) { audit(kMotionBlur, kFields, problems); }};

}  // namespace posthaste::nodes
