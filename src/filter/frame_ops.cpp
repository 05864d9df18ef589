// Geometric operations on a whole frame (see frame_ops.h).

#include "filter/frame_ops.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "core/parallel.h"
#include "core/passes.h"
#include "core/sanitize.h"
#include "filter/depth_resample.h"
#include "filter/lens.h"

namespace posthaste::filter {
namespace {

/// Pixels of `r` -> its NDC ([0,1]^2 across the rectangle).
Affine to_ndc(const Rect &r)
{
    Affine m(1.0);
    m[0][0] = 1.0 / r.width();
    m[1][1] = 1.0 / r.height();
    m[2][0] = -double(r.x0) / r.width();
    m[2][1] = -double(r.y0) / r.height();
    return m;
}

/// The pass's name without its "@view" suffix.
std::string base_name(const std::string &name)
{
    return name.substr(0, name.find('@'));
}

bool is_vector_pass(const std::string &base)
{
    return base == pass::kMotion || base == pass::kMotionNext;
}

/// How far from a pixel a filter's support reaches, in input pixels, for a map whose linear part
/// is `m`: half the filter's width, widened by the map's strongest minification, plus the pixel.
int support_radius(const std::string &filter, const glm::dmat2 &m)
{
    // The point samplers read the 2x2 or 4x4 pixels around the point, unwidened.
    if (filter == "bilinear" || filter == "bicubic") {
        return filter == "bilinear" ? 1 : 2;
    }
    // The smaller singular value of m: its strongest minification.
    const double t = m[0][0] * m[0][0] + m[0][1] * m[0][1] + m[1][0] * m[1][0] + m[1][1] * m[1][1];
    const double det = std::abs(m[0][0] * m[1][1] - m[0][1] * m[1][0]);
    const double smin =
        std::sqrt(std::max(0.5 * (t - std::sqrt(std::max(t * t - 4.0 * det * det, 0.0))), 0.0));
    const double widen = std::max(1.0, 1.0 / smin);
    return int(std::min(std::ceil(0.5 * filter_width(filter) * widen) + 1.0, 1e6));
}

/// `src` (covering `src_window`) resampled at to_input(output pixel centre) over `dst_window`
/// with the lens node's bilinear or Catmull-Rom resampling (filter::resample_row).
Image warp_resampled(const Image &src,
                     const Rect &src_window,
                     const Affine &to_input,
                     const Rect &dst_window,
                     Resample filter,
                     float outside)
{
    const int w = dst_window.width();
    Image dst = Image::uninitialized(w, dst_window.height(), src.channels());
    parallel_for(0, dst_window.height(), [&](int y) {
        const std::size_t n = static_cast<std::size_t>(w);
        std::vector<float> xs(n), ys(n);
        for (int x = 0; x < w; ++x) {
            const glm::dvec3 p =
                to_input * glm::dvec3(dst_window.x0 + x + 0.5, dst_window.y0 + y + 0.5, 1.0);
            xs[std::size_t(x)] = float(p.x - src_window.x0);
            ys[std::size_t(x)] = float(p.y - src_window.y0);
        }
        resample_row(src, xs.data(), ys.data(), w, filter, outside, dst.pixel(0, y));
    });
    return dst;
}

}  // namespace

Camera moved_camera(const Camera &camera,
                    const Affine &to_output,
                    const Rect &display,
                    const Rect &new_display)
{
    const Affine a = to_ndc(new_display) * to_output * glm::inverse(to_ndc(display));
    bool identity = true;
    for (int c = 0; c < 3; ++c) {
        for (int r = 0; r < 3; ++r) {
            identity = identity && std::abs(a[c][r] - (c == r ? 1.0 : 0.0)) < 1e-12;
        }
    }
    if (identity) {
        return camera;
    }
    // u' = a00 u + a01 v + a02 after the divide is x' = a00 x + a01 y + a02 w on clip
    // coordinates: a 4x4 acting on the clip-space result (glm, column vectors).
    glm::mat4 remap(1.0f);
    remap[0][0] = float(a[0][0]);
    remap[1][0] = float(a[1][0]);
    remap[3][0] = float(a[2][0]);
    remap[0][1] = float(a[0][1]);
    remap[1][1] = float(a[1][1]);
    remap[3][1] = float(a[2][1]);
    Camera c = camera;
    if (c.world_to_ndc) {
        c.world_to_ndc = remap * *c.world_to_ndc;
    }
    if (c.prev_world_to_ndc) {
        c.prev_world_to_ndc = remap * *c.prev_world_to_ndc;
    }
    // The sensor spans the display window: it shrinks as the image is magnified in NDC.
    const double sx = std::hypot(a[0][0], a[0][1]), sy = std::hypot(a[1][0], a[1][1]);
    if (c.sensor_width_mm && sx > 0.0) {
        *c.sensor_width_mm = float(*c.sensor_width_mm / sx);
    }
    if (c.sensor_height_mm && sy > 0.0) {
        *c.sensor_height_mm = float(*c.sensor_height_mm / sy);
    }
    return c;
}

void warp_frame(const Frame &in, const FrameWarp &w, Frame &out)
{
    const Affine to_input = glm::inverse(w.to_output);
    const glm::dmat2 linear(
        w.to_output[0][0], w.to_output[0][1], w.to_output[1][0], w.to_output[1][1]);
    out.camera = moved_camera(in.camera, w.to_output, in.display_window, w.display);
    for (const auto &[view, camera] : in.view_cameras) {
        out.view_cameras[view] = moved_camera(camera, w.to_output, in.display_window, w.display);
    }
    out.data_window = w.window;
    out.display_window = w.display;
    for (const auto &[name, pass] : in.passes()) {
        const std::string base = base_name(name);
        const bool depth = pass::is_depth_pass(base);
        const float outside = depth ? std::numeric_limits<float>::infinity() : 0.0f;
        Image storage;
        const Image &src = finite_view(*pass.image, outside, storage, depth);
        const bool filtered =
            w.filter != "nearest" &&
            std::find(w.filtered.begin(), w.filtered.end(), base) != w.filtered.end();
        // A filtered depth is filtered split from its sky and guarded after (depth_resample.h).
        const bool guard = depth && filtered;
        Image split;
        if (guard) {
            split = sky_split(src);
        }
        const Image &fsrc = guard ? split : src;
        Image dst;
        if (!filtered) {
            dst = sample_nearest(src, in.data_window, to_input, w.window, outside);
        } else if (w.filter == "bicubic" || w.filter == "bilinear") {
            dst = warp_resampled(fsrc,
                                 in.data_window,
                                 to_input,
                                 w.window,
                                 w.filter == "bicubic" ? Resample::Bicubic : Resample::Bilinear,
                                 guard ? std::numeric_limits<float>::quiet_NaN() : outside);
        } else if (w.resize) {
            dst = resize_filtered(
                fsrc, in.data_window, in.display_window, w.window, w.display, w.filter);
        } else {
            dst = warp_filtered(fsrc, in.data_window, w.to_output, w.window, w.filter, guard);
        }
        if (guard) {
            const Image range = depth_range(src, support_radius(w.filter, linear));
            Image guarded =
                Image::uninitialized(w.window.width(), w.window.height(), src.channels());
            parallel_for(0, w.window.height(), [&](int y) {
                std::vector<std::int32_t> near(static_cast<std::size_t>(w.window.width()));
                nearest_sources(to_input, in.data_window, w.window, y, near.data());
                guard_depth_row(src,
                                range,
                                near.data(),
                                w.window.width(),
                                dst.pixel(0, y),
                                guarded.pixel(0, y));
            });
            dst = std::move(guarded);
        }
        if (is_vector_pass(base) && dst.channels() >= 2) {
            const int nc = dst.channels();
            parallel_for(0, dst.height(), [&](int y) {
                float *p = dst.pixel(0, y);
                for (int x = 0; x < dst.width(); ++x, p += nc) {
                    const glm::dvec2 v = linear * glm::dvec2(p[0], p[1]);
                    p[0] = float(v.x);
                    p[1] = float(v.y);
                }
            });
        }
        out.set(name, std::make_shared<const Image>(std::move(dst)), pass.channels, pass.storage);
    }
}

void cut_data_window(const Frame &in, const Rect &window, Frame &out, int dx, int dy)
{
    out.data_window = window.offset(dx, dy);
    for (const auto &[name, pass] : in.passes()) {
        const bool depth = pass::is_depth_pass(base_name(name));
        const float fill = depth ? std::numeric_limits<float>::infinity() : 0.0f;
        Image cut = place_in_window(*pass.image,
                                    in.data_window,
                                    window,
                                    std::vector<float>(std::size_t(pass.image->channels()), fill));
        // The same values, fewer of them: an untouched pass stays untouched, so a write puts the
        // file's own samples back (ids beyond 2^24, alias-decoded channels) cut to the window.
        Pass kept = pass;
        kept.image = std::make_shared<const Image>(std::move(cut));
        if (pass.untouched()) {
            kept.as_read = kept.image;
        }
        out.set_pass(name, std::move(kept));
    }
}

}  // namespace posthaste::filter
