// nodes/dof.cpp: depth of field from color + depth: thin-lens circle of confusion (signed, px),
// tile max CoC with dilation, then a near/far separated gather (src/shading/dof_gather.h; Jimenez
// 2014, Abadie 2018). Lens values come from the frame header (aperture, focus, focalLength,
// sensorWidth) unless a parameter overrides them. Jitter is hashed from (x / 8, y): the output does
// not depend on the thread count. When no pixel's CoC reaches half a pixel the color pass is
// passed on untouched (same bits). method "simple" is the baseline: a disc of each pixel's own
// CoC, no depth test.

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/sanitize.h"
#include "nodes/node.h"
#include "shading/dof_gather.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kFstop = ParamSpec::real("fstop", 0.0)
                                 .at_least(0.0)
                                 .doc("f-number N (aperture diameter = focal length / N).")
                                 .from_header_only(attr::kAperture);
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
                                 kSpecular};
constexpr PortSpec kInputs[] = {
    {"image", "color,depth", false, "Color (premultiplied RGBA) and depth (Z, metres)."}};

shading::DofLens lens_of(NodeContext &ctx, const Frame &in)
{
    // The data window's camera: its sensor spans the pass images (the display window's sensor
    // width, given or from the header, scaled by data width / display width).
    const Camera cam = in.pixel_camera();
    const double window_scale =
        in.display_window.empty() ? 1.0 : double(in.width()) / double(in.display_window.width());
    const std::string who = ctx.where();
    shading::DofLens l;
    const double fstop = ctx.get_real(kFstop), focus = ctx.get_real(kFocus);
    const double focal = ctx.get_real(kFocal), sensor = ctx.get_real(kSensor);
    const NodeParams &p = ctx.params();
    l.fstop = p.given(kFstop) ? float(fstop) : cam.require_fstop(who);
    l.focus_m = p.given(kFocus) ? float(focus) : cam.require_focus_distance(who);
    l.focal_mm = p.given(kFocal) ? float(focal) : cam.require_focal_length_mm(who);
    l.sensor_mm =
        p.given(kSensor) ? float(sensor * window_scale) : cam.require_sensor_width_mm(who);
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
// depth, the share by that of specular_depth, and the two added (color plus what each blur
// changed). Only the pixels whose two depths differ keep their share apart; the second blur runs
// over their box plus what can reach it. False when no pixel's depths differ (the caller blurs
// color as one).
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
    Image spec_storage, spec_depth_storage;
    const Image &spec = finite_view(ctx.input_pass("image", pass::kSpecular), 0.0f, spec_storage);
    const Image &spec_depth = finite_view(ctx.input_pass("image", pass::kSpecularDepth),
                                          std::numeric_limits<float>::infinity(),
                                          spec_depth_storage,
                                          /*allow_positive_inf=*/true);
    const int w = color.width(), h = color.height(), cc = color.channels();
    if (spec.width() != w || spec.height() != h || spec_depth.width() != w ||
        spec_depth.height() != h || spec.channels() < 3 || cc < 3) {
        throw_runtime(ctx.where(),
                      ": the lighting split needs RGB color and specular and a specular_depth of "
                      "color's size (",
                      w,
                      "x",
                      h,
                      ")");
    }
    const auto parts_ways = [&](int x, int y) {
        const float a = depth.at(x, y, 0), b = spec_depth.at(x, y, 0);
        // A share whose depth is not a positive finite depth stays with the rest.
        return a > 0.0f && b > 0.0f && std::isfinite(a) && std::isfinite(b) &&
               std::abs(a - b) > 1e-4f * a;
    };
    std::vector<int> first(std::size_t(h), w), last(std::size_t(h), -1);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            if (parts_ways(x, y)) {
                first[std::size_t(y)] = std::min(first[std::size_t(y)], x);
                last[std::size_t(y)] = x;
            }
        }
    });
    Rect box{w, h, 0, 0};
    for (int y = 0; y < h; ++y) {
        if (last[std::size_t(y)] >= 0) {
            box = Rect{std::min(box.x0, first[std::size_t(y)]),
                       std::min(box.y0, y),
                       std::max(box.x1, last[std::size_t(y)] + 1),
                       y + 1};
        }
    }
    if (box.x1 <= box.x0) {
        return false;
    }
    // A parting pixel spreads at most the largest CoC; what lands there is gathered from as far
    // again, plus the tiles of the gather's neighbour maximum.
    const int reach = 2 * (int(std::ceil(s.max_coc_px)) + 32);
    const Rect crop{std::max(0, box.x0 - reach),
                    std::max(0, box.y0 - reach),
                    std::min(w, box.x1 + reach),
                    std::min(h, box.y1 + reach)};
    const int cw = crop.x1 - crop.x0, ch = crop.y1 - crop.y0;
    Image rest = color;  // color less the parting specular share
    Image share = Image::uninitialized(cw, ch, 4);
    Image share_depth = Image::uninitialized(cw, ch, 1);
    parallel_for(0, ch, [&](int j) {
        const int y = crop.y0 + j;
        for (int i = 0; i < cw; ++i) {
            const int x = crop.x0 + i;
            const bool parts =
                x >= first[std::size_t(y)] && x <= last[std::size_t(y)] && parts_ways(x, y);
            const float *sp = spec.pixel(x, y);
            float *r = rest.pixel(x, y), *d = share.pixel(i, j);
            for (int k = 0; k < 3; ++k) {
                d[k] = parts ? sp[k] : 0.0f;
                r[k] = parts ? r[k] - sp[k] : r[k];
            }
            d[3] = 0.0f;
            // The other pixels hold no share but keep their depth: both blurs see the same
            // occluders.
            *share_depth.pixel(i, j) = parts ? spec_depth.at(x, y, 0) : depth.at(x, y, 0);
        }
    });
    Image rest_blurred, share_blurred;
    if (!shading::apply_dof(rest, depth, lens, s, rest_blurred)) {
        rest_blurred = rest;
    }
    if (!shading::apply_dof(share, share_depth, lens, s, share_blurred)) {
        share_blurred = share;
    }
    out = std::move(rest_blurred);
    parallel_for(0, ch, [&](int j) {
        const int y = crop.y0 + j;
        for (int i = 0; i < cw; ++i) {
            const int x = crop.x0 + i;
            const float *c = color.pixel(x, y), *r0 = rest.pixel(x, y);
            const float *s0 = share.pixel(i, j), *s1 = share_blurred.pixel(i, j);
            float *q = out.pixel(x, y);
            for (int k = 0; k < cc; ++k) {
                q[k] = c[k] + (q[k] - r0[k]) + (k < 3 ? s1[k] - s0[k] : 0.0f);
            }
        }
    });
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
    shading::DofSettings s;
    s.max_coc_px = ctx.get_float(kMaxCoc);
    s.samples = ctx.get_int(kSamples);
    s.blades = ctx.get_int(kBlades);
    s.rotation_deg = ctx.get_float(kRotation);
    s.method =
        ctx.get_choice(kMethod) == 0 ? shading::DofMethod::Gather : shading::DofMethod::Simple;
    s.half_res = ctx.get_choice(kResolution) == 1;
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
            throw_usage(ctx.node.json_path,
                        "/params/",
                        s->name,
                        ": ",
                        ctx.node.describe(),
                        ": param \"",
                        s->name,
                        "\" must be > 0 (leave it out for the header's ",
                        s->header,
                        ")");
        }
    }
    const int blades = ctx.params.get_int(kBlades);
    if (blades == 1 || blades == 2) {
        throw_usage(ctx.node.json_path,
                    "/params/blades: ",
                    ctx.node.describe(),
                    ": param \"blades\": expected 0 or 3..16, got ",
                    blades);
    }
}

}  // namespace

extern const NodeType kDof{{"dof",
                            "Depth of field: thin-lens CoC, near/far gather with bokeh.",
                            kInputs,
                            kParams,
                            "color",
                            /*sink=*/false,
                            /*keeps_specular=*/true},
                           &execute,
                           &plan,
                           &check};

}  // namespace posthaste::nodes
