// nodes/dof.cpp: depth of field from color + depth: thin-lens circle of confusion (signed, px),
// tile max CoC with dilation, then a near/far separated gather (src/shading/dof/dof_gather.h;
// Jimenez 2014, Abadie 2018). Lens values come from the frame header (aperture, focus, focalLength,
// sensorWidth) unless a parameter overrides them. Jitter is hashed from (x / 8, y): the output does
// not depend on the thread count. A CoC under 3/4 px behind the focus plane (1/2 px in front)
// blurs by a 4-neighbour stencil of the disc's variance; when no pixel's CoC reaches 1/16 px the
// color pass is passed on untouched
// (same bits). method "simple" is the baseline: a disc of each pixel's own
// CoC, no depth test.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/node.h"
#include "nodes/split_params.h"
#include "shading/dof/dof_gather.h"
#include "shading/lighting/lighting_split.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kFstop =
    ParamSpec::real("fstop", 5.6)
        .at_least(0.0)
        .doc(
            "f-number N (aperture diameter = focal length / N); where neither the graph nor the "
            "header gives one (Blender writes none), the default stands in and a note says so.")
        .from_header(attr::kAperture);
constexpr ParamSpec kFocus = ParamSpec::real("focus_distance", 0.0)
                                 .at_least(0.0)
                                 .units("m")
                                 .doc("Distance of the plane in focus.")
                                 .from_header_only(attr::kFocus);
constexpr ParamSpec kFocal = ParamSpec::real("focal_length_mm", 0.0)
                                 .at_least(0.0)
                                 .units("mm")
                                 .doc("Focal length.")
                                 .from_header_only(attr::kFocalLength);
constexpr ParamSpec kSensor = ParamSpec::real("sensor_width_mm", 0.0)
                                  .at_least(0.0)
                                  .units("mm")
                                  .doc("Sensor width (maps to the image width).")
                                  .from_header_only(attr::kSensorWidth);
constexpr ParamSpec kMaxCoc =
    ParamSpec::real("max_coc", 64.0)
        .range(0.0, 4096.0)
        .units("px")
        .doc("Largest circle of confusion (diameter); larger ones are clamped. 0: no blur.");
constexpr ParamSpec kSamples =
    ParamSpec::integer("samples", 64)
        .range(1, 1024)
        .doc("Most samples per pixel (quality); pixels with a smaller CoC take fewer.");
constexpr ParamSpec kBlades =
    ParamSpec::integer("blades", 0)
        .range(0, 16)
        .doc("Aperture blades: 0 for a round disc, 3..16 for a regular polygon.");
constexpr ParamSpec kRotation = ParamSpec::real("rotation_deg", 0.0)
                                    .range(-360.0, 360.0)
                                    .units("deg")
                                    .doc("Rotation of the polygonal aperture.");
constexpr ParamSpec kMethod = ParamSpec::choice("method", "gather|simple", "gather")
                                  .doc(
                                      "gather: near/far separated gather; simple: baseline disc "
                                      "blur of each pixel's own CoC.");
constexpr ParamSpec kResolution =
    ParamSpec::choice("resolution", "full|half", "full")
        .doc(
            "full: gather every pixel at full resolution; half: gather blurs of 3 px radius and "
            "more at "
            "half resolution and composite at full (faster, noisier highlights).")
        .only_when("method", "gather");
constexpr ParamSpec kSpecular =
    ParamSpec::choice("specular", "auto|off", "auto")
        .doc(
            "auto: where the input has the specular and specular_depth passes (asked for where a "
            "source can give them), blur the specular share by the CoC of specular_depth (a "
            "highlight's image lies behind its surface) and the rest of color by depth's (the "
            "full-resolution gather only); off: blur color as one.");
constexpr ParamSpec kParams[] = {kFstop,
                                 kFocus,
                                 kFocal,
                                 kSensor,
                                 kMaxCoc,
                                 kSamples,
                                 kBlades,
                                 kRotation,
                                 kMethod,
                                 kResolution,
                                 kSpecular,
                                 kSpecularKnee,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image", "color,depth", false, "Color (premultiplied RGBA) and depth (Z, metres)."},
    kMaskPort};

constexpr Binding<shading::DofLens> kLensFields[] = {
    bind<&shading::DofLens::fstop>(kFstop),
    bind<&shading::DofLens::focus_m>(kFocus),
    bind<&shading::DofLens::focal_mm>(kFocal),
    bind<&shading::DofLens::sensor_mm>(kSensor),
};
constexpr Binding<shading::DofSettings> kFields[] = {
    bind<&shading::DofSettings::max_coc_px>(kMaxCoc),
    bind<&shading::DofSettings::samples>(kSamples),
    bind<&shading::DofSettings::blades>(kBlades),
    bind<&shading::DofSettings::rotation_deg>(kRotation),
    bind<&shading::DofSettings::method>(kMethod),
    bind<&shading::DofSettings::half_res>(kResolution, "half"),
};

shading::DofLens lens_of(NodeContext &ctx, const Frame &in)
{
    // The data window's camera: its sensor spans the pass images (the display window's sensor
    // width, given or from the header, scaled by data width / display width).
    const Camera cam = in.pixel_camera();
    shading::DofLens l = fill(ctx, kLensFields, HeaderSource{&cam, &in.attributes});
    if (ctx.params().given(kSensor) && !in.display_window.empty()) {
        l.sensor_mm =
            float(double(l.sensor_mm) * double(in.width()) / double(in.display_window.width()));
    }
    const std::string who = ctx.where();
    if (!(l.fstop > 0.0f) || !(l.focus_m > 0.0f) || !(l.focal_mm > 0.0f) || !(l.sensor_mm > 0.0f) ||
        !std::isfinite(l.fstop) || !std::isfinite(l.focus_m) || !std::isfinite(l.focal_mm) ||
        !std::isfinite(l.sensor_mm)) {
        throw_runtime(who,
                      ": lens values must be finite and > 0, got fstop ",
                      l.fstop,
                      ", focus_distance ",
                      l.focus_m,
                      " m, focal_length_mm ",
                      l.focal_mm,
                      ", sensor_width_mm ",
                      l.sensor_mm);
    }
    return l;
}

// The lighting split: a highlight's image lies behind the surface that shows it (a ball's
// convex mirror puts the sun's image R/2 behind its surface), so a thin lens focuses it at
// specular_depth, not at the surface. Color less the specular share is blurred by the CoC of
// depth, the share by that of specular_depth (shading/lighting/lighting_split.h). Only the pixels
// whose two depths differ keep their share apart; the share's blur runs over their box plus what
// can reach it, and only on the tiles its gather can carry something into. False when no pixel's
// depths differ (the caller blurs color as one).
bool blur_split(NodeContext &ctx,
                const Image &color,
                const Image &depth,
                const shading::DofLens &lens,
                const shading::DofSettings &s,
                Image &out)
{
    if (!(s.max_coc_px >= 0.5f)) {
        return false;  // nothing is blurred
    }
    // Read as color and depth are (finite_view): a specular of 3e38 overflowed the share's blur.
    Image spec_storage, spec_depth_storage;
    const Image &spec = finite_view(ctx.input_pass("image", pass::kSpecular), 0.0f, spec_storage);
    const Image &spec_depth = finite_view(ctx.input_pass("image", pass::kSpecularDepth),
                                          std::numeric_limits<float>::infinity(),
                                          spec_depth_storage,
                                          /*allow_positive_inf=*/true);
    const int w = color.width(), h = color.height();
    if (spec.width() != w || spec.height() != h || spec_depth.width() != w ||
        spec_depth.height() != h || spec.channels() < 3 || color.channels() < 3) {
        throw_runtime(ctx.where(),
                      ": the lighting split needs RGB color and specular and a specular_depth of "
                      "color's size (",
                      w,
                      "x",
                      h,
                      ")");
    }
    // A lifted pixel spreads at most the largest CoC radius (half of max_coc, a diameter); what
    // lands there is gathered from as far again, plus two tiles of the CoC field's neighbour
    // maximum. (Twice this, as before, gave the same bits on the camera stack's 16 frames at
    // 1080p but one, which moved by one half-float step in one pixel.)
    const int reach = int(std::ceil(s.max_coc_px)) + 32;
    const float knee = ctx.get_float(kSpecularKnee);
    const auto parts_at = [&](int x, int y) {
        const float za = depth.at(x, y, 0), zb = spec_depth.at(x, y, 0);
        // A share whose depth is not a positive finite depth (NaN, sky) stays with the rest.
        return za > 0.0f && zb > 0.0f && std::isfinite(za) && std::isfinite(zb) &&
               std::abs(za - zb) > 1e-4f * za;
    };
    // The knee first: most pixels hold no highlight, and then their depths are not compared.
    const shading::SplitRegion region = shading::find_split(
        w,
        h,
        reach,
        [&](int y, std::uint8_t *row) { shading::mark_highlights(spec, knee, y, row, parts_at); },
        shading::kDofCropAlign);
    if (region.empty()) {
        return false;
    }
    const Rect &crop = region.crop;
    const Image share = shading::share_color(spec, region, knee);
    // The other pixels hold no share but keep their depth: both blurs see the same occluders.
    // Those whose share parts ways below the knee lend the share's blur their specular_depth:
    // the share's image stays one surface around its highlight.
    Image share_depth = Image::uninitialized(crop.width(), crop.height(), 1);
    parallel_for(0, crop.height(), [&](int j) {
        const int y = crop.y0 + j;
        for (int i = 0; i < crop.width(); ++i) {
            const int x = crop.x0 + i;
            *share_depth.pixel(i, j) = parts_at(x, y) ? spec_depth.at(x, y, 0) : depth.at(x, y, 0);
        }
    });
    shading::DofSettings rest_settings = s;
    rest_settings.subtract = &share;
    rest_settings.subtract_x0 = crop.x0;
    rest_settings.subtract_y0 = crop.y0;
    const bool rest_still = !shading::apply_dof(color, depth, lens, rest_settings, out);
    shading::DofSettings share_settings = s;
    share_settings.skip_empty = true;
    share_settings.jitter_x0 = crop.x0;
    share_settings.jitter_y0 = crop.y0;
    Image share_blurred;
    // The share is the crop's image: its sensor is the crop's share of the frame's, or every
    // CoC in pixels would shrink by crop width / frame width.
    shading::DofLens share_lens = lens;
    share_lens.sensor_mm = lens.sensor_mm * float(crop.width()) / float(w);
    if (!shading::apply_dof(share, share_depth, share_lens, share_settings, share_blurred)) {
        if (rest_still) {
            return false;  // neither share is blurred: color as it is
        }
        share_blurred = share;
    }
    if (rest_still) {
        out = color;
    }
    shading::compose_split(color, share, share_blurred, region, rest_still, out);
    return true;
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    // Non-finite input never spreads over a blur footprint nor reaches the output: NaN/Inf color
    // reads as 0, NaN/-inf depth as the sky (+inf); no copy when everything is finite.
    Image color_storage, depth_storage;
    const Image &color = finite_view(ctx.input_pass("image", pass::kColor), 0.0f, color_storage);
    const Image &depth = finite_view(ctx.input_pass("image", pass::kDepth),
                                     std::numeric_limits<float>::infinity(),
                                     depth_storage,
                                     /*allow_positive_inf=*/true);
    if (depth.width() != color.width() || depth.height() != color.height()) {
        throw_runtime(ctx.where(),
                      ": depth is ",
                      depth.width(),
                      "x",
                      depth.height(),
                      " but color is ",
                      color.width(),
                      "x",
                      color.height());
    }
    const shading::DofLens lens = lens_of(ctx, in);
    const shading::DofSettings s = fill(ctx.params(), kFields);
    Image out;
    // The split is the full-resolution gather's (measured: the half-resolution gather's sharp
    // highlights came out worse split, and the seeds' simple method is kept as it was).
    if (ctx.get_choice(kSpecular) == 0 && s.method == shading::DofMethod::Gather && !s.half_res &&
        in.has(pass::kSpecular) && in.has(pass::kSpecularDepth)) {
        if (blur_split(ctx, color, depth, lens, s, out)) {
            const Pass &cp = in.pass(pass::kColor, ctx.where());
            ctx.output().set(pass::kColor,
                             std::make_shared<const Image>(std::move(out)),
                             cp.channels,
                             cp.storage);
            return;
        }
    }
    if (!shading::apply_dof(color, depth, lens, s, out)) {
        if (&color == &color_storage) {  // in focus, but non-finite values were replaced
            const Pass &cp = in.pass(pass::kColor, ctx.where());
            ctx.output().set(pass::kColor,
                             std::make_shared<const Image>(std::move(color_storage)),
                             cp.channels,
                             cp.storage);
        }
        return;  // everything in focus: the output frame already shares the input's color
    }
    const Pass &cp = in.pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

void plan(PlanContext &ctx)
{
    // The lens values a solved camera gives (focal length, sensor width) where the header has
    // none, unless the graph gives both.
    ctx.inputs[0].camera = !(ctx.params.given(kFocal) && ctx.params.given(kSensor));
    // The lighting split, where a source can give its passes (blur_split).
    if (ctx.params.get_choice(kSpecular) == 0 && ctx.params.get_choice(kMethod) == 0 &&
        ctx.params.get_choice(kResolution) == 0) {
        ctx.inputs[0].add_optional(pass::kSpecular);
        ctx.inputs[0].add_optional(pass::kSpecularDepth);
    }
}

void check(CheckContext &ctx)
{
    // A lens value given must be a lens value: 0 once meant "the header's", which is now what
    // leaving it out means.
    for (const ParamSpec *s : {&kFstop, &kFocus, &kFocal, &kSensor}) {
        if (ctx.params.given(*s) && !(ctx.params.get_real(*s) > 0.0)) {
            throw_param(
                ctx, *s, str_cat("must be > 0 (leave it out for the header's ", s->header, ")"));
        }
    }
    const int blades = ctx.params.get_int(kBlades);
    if (blades == 1 || blades == 2) {
        throw_param_expected(ctx, kBlades, "0 or 3..16", blades);
    }
}

}  // namespace

extern const NodeType kDof{{"dof",
                            "Depth of field: thin-lens CoC, near/far gather with bokeh.",
                            kInputs,
                            kParams,
                            "color",
                            /*sink=*/false,
                            /*keeps_specular=*/true,
                            /*maskable=*/true},
                           &execute,
                           &plan,
                           &check,
                           nullptr,
                           [](std::vector<std::string> &problems) {
                               audit(kDof, kLensFields, problems);
                               audit(kDof, kFields, problems);
                           }};

}  // namespace posthaste::nodes
