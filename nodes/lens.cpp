// nodes/lens.cpp: lens distortion and its exact inverse, lateral chromatic aberration, natural
// (cos^4) and artistic vignetting, and an ST-map of the warp (src/filter/lens.h).
// `direction: distort` images the input through the lens (each output pixel reads the input at
// the undistorted position, found by Newton's method); `undistort` removes a lens's distortion
// (each output pixel reads the input at distort(position)). Every pass is warped the same way:
// the `filtered` passes (color, albedo) with `filter`, the others (depth, normals, ids, motion...)
// with nearest neighbour, their values unchanged (motion vectors are not re-projected). Outside
// the input's data window reads 0 (depth +inf). The data window becomes the input's moved by the
// lens (it grows for pincushion, shrinks for barrel), within the display window widened by half
// its size on every side. Chromatic aberration, vignetting: color pass only. Non-finite values
// read as 0 (NaN and -inf depth as the sky, +inf).

#include "filter/lens.h"

#include <cmath>
#include <limits>
#include <mutex>

#include "core/passes.h"
#include "core/sanitize.h"
#include "filter/depth_resample.h"
#include "io/source_file.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kDirection =
    ParamSpec::choice("direction", "distort|undistort", "distort")
        .doc("distort: add the lens's distortion; undistort: remove it.");
constexpr ParamSpec kK1 = ParamSpec::real("k1", 0.0).range(-10.0, 10.0).doc("Radial r^2 term.");
constexpr ParamSpec kK2 = ParamSpec::real("k2", 0.0).range(-10.0, 10.0).doc("Radial r^4 term.");
constexpr ParamSpec kK3 = ParamSpec::real("k3", 0.0).range(-10.0, 10.0).doc("Radial r^6 term.");
constexpr ParamSpec kP1 = ParamSpec::real("p1", 0.0).range(-1.0, 1.0).doc("Tangential p1.");
constexpr ParamSpec kP2 = ParamSpec::real("p2", 0.0).range(-1.0, 1.0).doc("Tangential p2.");
constexpr ParamSpec kNormalize =
    ParamSpec::choice("normalize", "half_width|focal_length", "half_width")
        .doc(
            "The unit of the coefficients: half the display width, or the focal length in "
            "pixels from the header (OpenCV's calibrations).");
constexpr ParamSpec kCenterX =
    ParamSpec::real("center_x", 0.0)
        .units("px")
        .doc("Optical centre's offset from the display window's centre.");
constexpr ParamSpec kCenterY =
    ParamSpec::real("center_y", 0.0)
        .units("px")
        .doc("Optical centre's offset from the display window's centre (down).");
constexpr ParamSpec kChromatic = ParamSpec::real("chromatic_aberration", 0.0)
                                     .range(-0.1, 0.1)
                                     .doc(
                                         "Lateral: red read at (1 + a), blue at (1 - a) times "
                                         "green's distance from the centre.");
constexpr ParamSpec kNatural =
    ParamSpec::real("natural_vignetting", 0.0)
        .range(0.0, 1.0)
        .doc("Mix of cos^4 of the field angle (the header's focal length and sensor width).");
constexpr ParamSpec kVignette = ParamSpec::real("vignette", 0.0)
                                    .range(0.0, 1.0)
                                    .doc("Artistic vignette: darkening at the edge.");
constexpr ParamSpec kVignetteRadius = ParamSpec::real("vignette_radius", 0.75)
                                          .range(0.0, 2.0)
                                          .doc("Where it starts, in half-diagonals.");
constexpr ParamSpec kVignetteSoftness =
    ParamSpec::real("vignette_softness", 0.5).range(1e-3, 2.0).doc("Its ramp, in half-diagonals.");
constexpr ParamSpec kFilter = ParamSpec::choice("filter", "nearest|bilinear|bicubic", "bicubic")
                                  .doc("Resampling of the filtered passes (bicubic: Catmull-Rom).");
constexpr ParamSpec kFiltered =
    ParamSpec::string("filtered", "color,albedo")
        .doc("Passes resampled with `filter`; others take the nearest.");
constexpr ParamSpec kStmap = ParamSpec::boolean("stmap", false)
                                 .doc(
                                     "Also output pass \"stmap\": where each pixel reads the input "
                                     "(Nuke's STMap convention).");
constexpr ParamSpec kParams[] = {kDirection,
                                 kK1,
                                 kK2,
                                 kK3,
                                 kP1,
                                 kP2,
                                 kNormalize,
                                 kCenterX,
                                 kCenterY,
                                 kChromatic,
                                 kNatural,
                                 kVignette,
                                 kVignetteRadius,
                                 kVignetteSoftness,
                                 kFilter,
                                 kFiltered,
                                 kStmap};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to put through the lens."}};

struct Built {
    std::array<double, 12> key;
    std::shared_ptr<const filter::LensMap> map;
};

struct LensCache {
    std::unique_ptr<std::mutex> mutex = std::make_unique<std::mutex>();
    mutable std::vector<Built> built;
};

constexpr Binding<filter::Distortion> kDistortionFields[] = {
    bind<&filter::Distortion::k1>(kK1),
    bind<&filter::Distortion::k2>(kK2),
    bind<&filter::Distortion::k3>(kK3),
    bind<&filter::Distortion::p1>(kP1),
    bind<&filter::Distortion::p2>(kP2),
};
constexpr Binding<filter::LensGeometry> kGeometryFields[] = {
    bind<&filter::LensGeometry::undistort>(kDirection, "undistort"),
};

filter::LensGeometry geometry(NodeContext &ctx, const Frame &frame)
{
    filter::LensGeometry g = fill(ctx.params(), kGeometryFields);
    g.distortion = fill(ctx.params(), kDistortionFields);
    const Rect &d = frame.display_window;
    // Derived: the display window's centre, moved by the parameters' offset.
    const glm::dvec2 offset(ctx.get_real(kCenterX), ctx.get_real(kCenterY));
    g.centre = glm::dvec2(0.5 * (d.x0 + d.x1), 0.5 * (d.y0 + d.y1)) + offset;
    if (ctx.get_string(kNormalize) == "focal_length") {
        const std::string who = ctx.where() + ": param \"normalize\"";
        g.unit = double(frame.camera.require_focal_length_mm(who)) /
                 double(frame.camera.require_sensor_width_mm(who)) * d.width();
    } else {
        g.unit = 0.5 * d.width();
    }
    return g;
}

std::shared_ptr<const filter::LensMap> lens_map(NodeContext &ctx,
                                                const Frame &frame,
                                                const filter::LensGeometry &g)
{
    const LensCache &cache = ctx.state().get_or_create<LensCache>([] { return LensCache{}; });
    const Rect &dw = frame.data_window, &disp = frame.display_window;
    const std::array<double, 12> key = {g.centre.x,
                                        g.centre.y,
                                        g.unit,
                                        double(dw.x0),
                                        double(dw.y0),
                                        double(dw.x1),
                                        double(dw.y1),
                                        double(disp.x0),
                                        double(disp.y0),
                                        double(disp.x1),
                                        double(disp.y1),
                                        g.undistort ? 1.0 : 0.0};
    std::lock_guard lock(*cache.mutex);
    for (const Built &b : cache.built) {
        if (b.key == key) {
            return b.map;
        }
    }
    const Rect limit = disp.expand(std::max(disp.width(), disp.height()) / 2);
    Built b{key,
            std::make_shared<const filter::LensMap>(
                filter::build_lens_map(g, dw, limit, ctx.where() + ": params \"k1\"..\"p2\""))};
    if (cache.built.size() >= 4) {
        cache.built.erase(cache.built.begin());
    }
    cache.built.push_back(b);
    return b.map;
}

float smoothstep(float a, float b, float x)
{
    const float t = std::clamp((x - a) / (b - a), 0.0f, 1.0f);
    return t * t * (3.0f - 2.0f * t);
}

void execute(NodeContext &ctx)
{
    const Frame &frame = ctx.input("image");
    const filter::LensGeometry g = geometry(ctx, frame);
    const double ca = ctx.get_real(kChromatic), natural = ctx.get_real(kNatural),
                 vignette = ctx.get_real(kVignette);
    const bool stmap = ctx.get_bool(kStmap);
    if (g.distortion.identity() && ca == 0.0 && natural == 0.0 && vignette == 0.0 && !stmap) {
        return;  // nothing to do: the output shares every pass
    }
    // The natural vignetting's field angle: tan = r px * (sensor / display width) / focal.
    double mm_per_px = 0.0, focal_mm = 1.0;
    if (natural > 0.0) {
        const std::string who = ctx.where() + ": param \"natural_vignetting\"";
        focal_mm = frame.camera.require_focal_length_mm(who);
        mm_per_px = frame.camera.require_sensor_width_mm(who) / frame.display_window.width();
    }
    const std::shared_ptr<const filter::LensMap> map = lens_map(ctx, frame, g);
    const Rect out_window = map->window;
    const int w = out_window.width(), h = out_window.height();
    const auto filter = filter::Resample(ctx.get_choice(kFilter));  // the choices' order
    const std::vector<std::string> filtered = split_list(ctx.get_string(kFiltered));
    // The optical centre relative to the input data window (where the map's coordinates live).
    const float cx = float(g.centre.x - frame.data_window.x0),
                cy = float(g.centre.y - frame.data_window.y0);
    const Rect &disp = frame.display_window;
    const double half_diag = 0.5 * std::hypot(disp.width(), disp.height());

    // Every pass is replaced below, in place: each keeps its file origin, so a write puts it
    // back in its own part, view and pixel type (clearing the passes first sent them all out
    // under new names: a stereo file's right eye as "color@right.R", float colour as half).
    Frame &out = ctx.output();
    out.data_window = out_window;
    if (frame.source && out_window != frame.data_window) {
        out.source = regridded_source(*frame.source, out_window);  // the parts follow the window
    }
    for (const auto &[name, in_pass] : frame.passes()) {
        // A view's pass ("depth@right") is its pass's for `filtered` and the depth rules.
        const std::string base = name.substr(0, name.find('@'));
        const bool is_filtered =
            std::find(filtered.begin(), filtered.end(), base) != filtered.end();
        // The project's non-finite policy for nodes that move pixels: NaN and infinities read
        // as 0, in depth NaN and -inf as the sky (+inf).
        Image storage;
        const bool depth = pass::is_depth_pass(base);
        const Image &src = finite_view(
            *in_pass.image, depth ? std::numeric_limits<float>::infinity() : 0.0f, storage, depth);
        const bool is_color = base == pass::kColor;
        const float outside = depth ? std::numeric_limits<float>::infinity() : 0.0f;
        // A filtered depth is filtered split from its sky and guarded after
        // (filter/depth_resample.h).
        const bool guard = depth && is_filtered && filter != filter::Resample::Nearest;
        Image split, range;
        if (guard) {
            split = filter::sky_split(src);
            range = filter::depth_range(src, filter == filter::Resample::Bicubic ? 2 : 1);
        }
        const int nc = src.channels();
        std::vector<char> alpha(std::size_t(nc), 0);  // the vignettes leave alpha alone
        for (int c = 0; c < nc && c < int(in_pass.channels.size()); ++c) {
            alpha[std::size_t(c)] = in_pass.channels[std::size_t(c)] == "A";
        }
        Image dst = Image::uninitialized(w, h, nc);
        parallel_for(0, h, [&](int y) {
            const float *rsx = map->sx.data() + std::size_t(y) * std::size_t(w);
            const float *rsy = map->sy.data() + std::size_t(y) * std::size_t(w);
            float *d = dst.pixel(0, y);
            if (!is_filtered) {
                const std::int32_t *near = map->nearest.data() + std::size_t(y) * std::size_t(w);
                for (int x = 0; x < w; ++x) {
                    const float *s =
                        near[x] < 0 ? nullptr : src.data() + std::size_t(near[x]) * std::size_t(nc);
                    for (int c = 0; c < nc; ++c) {
                        d[x * nc + c] = s ? s[c] : outside;
                    }
                }
                return;
            }
            auto resample = [&](const float *xs, const float *ys, float *row) {
                filter::resample_row(src, xs, ys, w, filter, outside, row);
            };
            if (guard) {
                std::vector<float> sums(std::size_t(w) * std::size_t(split.channels()));
                filter::resample_row(split,
                                     rsx,
                                     rsy,
                                     w,
                                     filter,
                                     std::numeric_limits<float>::quiet_NaN(),
                                     sums.data());
                filter::guard_depth_row(src,
                                        range,
                                        map->nearest.data() + std::size_t(y) * std::size_t(w),
                                        w,
                                        sums.data(),
                                        d);
                return;
            }
            resample(rsx, rsy, d);
            if (is_color && ca != 0.0) {
                // Red and blue read at their own magnification about the centre.
                const std::size_t n = static_cast<std::size_t>(w);
                std::vector<float> xs(n), ys(n), tmp(n * static_cast<std::size_t>(nc));
                for (int c : {0, 2}) {
                    const float m = float(c == 0 ? 1.0 + ca : 1.0 - ca);
                    for (int x = 0; x < w; ++x) {
                        xs[std::size_t(x)] = cx + m * (rsx[x] - cx);
                        ys[std::size_t(x)] = cy + m * (rsy[x] - cy);
                    }
                    resample(xs.data(), ys.data(), tmp.data());
                    for (int x = 0; x < w; ++x) {
                        d[x * nc + c] = tmp[std::size_t(x * nc + c)];
                    }
                }
            }
            if (is_color && (natural > 0.0 || vignette > 0.0)) {
                const float radius = float(ctx.get_real(kVignetteRadius));
                const float softness = float(ctx.get_real(kVignetteSoftness));
                for (int x = 0; x < w; ++x) {
                    const double px = out_window.x0 + x + 0.5 - g.centre.x;
                    const double py = out_window.y0 + y + 0.5 - g.centre.y;
                    const double r = std::hypot(px, py);
                    float gain = 1.0f;
                    if (natural > 0.0) {
                        const double t = r * mm_per_px / focal_mm;
                        const double cos4 = 1.0 / ((1.0 + t * t) * (1.0 + t * t));
                        gain *= float(1.0 - natural + natural * cos4);
                    }
                    if (vignette > 0.0) {
                        gain *=
                            1.0f - float(vignette) *
                                       smoothstep(radius, radius + softness, float(r / half_diag));
                    }
                    for (int c = 0; c < nc; ++c) {
                        if (!alpha[std::size_t(c)]) {
                            d[x * nc + c] *= gain;  // light falls off; coverage does not
                        }
                    }
                }
            }
        });
        out.set(
            name, std::make_shared<const Image>(std::move(dst)), in_pass.channels, in_pass.storage);
    }
    if (stmap) {
        // Nuke's STMap: s, t in 0..1 across the input's display window, t measured upward.
        Image st = Image::uninitialized(w, h, 2);
        const Rect &dw = frame.data_window;
        parallel_for(0, h, [&](int y) {
            for (int x = 0; x < w; ++x) {
                const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
                st.at(x, y, 0) = float((map->sx[i] + dw.x0 - disp.x0) / disp.width());
                st.at(x, y, 1) = float(1.0 - (map->sy[i] + dw.y0 - disp.y0) / disp.height());
            }
        });
        out.set("stmap", std::make_shared<const Image>(std::move(st)), {"R", "G"});
    }
}

void plan(PlanContext &ctx)
{
    // The focal length and sensor width, which a solved camera gives.
    if (ctx.params.get_string(kNormalize) == "focal_length" ||
        ctx.params.get_real(kNatural) > 0.0) {
        ctx.inputs[0].camera = true;
    }
}

}  // namespace

extern const NodeType kLens{
    {"lens",
     "Lens: Brown-Conrady distortion and its exact inverse, chromatic aberration, vignetting, "
     "ST-map.",
     kInputs,
     kParams,
     "stmap"},
    &execute,
    &plan,
    nullptr,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kLens, kDistortionFields, problems);
        audit(kLens, kGeometryFields, problems);
    }};

}  // namespace posthaste::nodes
