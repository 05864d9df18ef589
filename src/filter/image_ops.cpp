// The image operations over ImageBufAlgo (see image_ops.h).

#include "filter/image_ops.h"

#include <OpenImageIO/filter.h>
#include <OpenImageIO/imagebufalgo.h>

#include <cmath>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "filter/fir_kernels.h"

namespace posthaste::filter {
namespace {

/// Rows per ImageBufAlgo call: enough to amortise a call's set-up (filter construction, ROI
/// checks), small enough to balance two to sixteen threads on a 1080p frame.
constexpr int kBandRows = 16;

OIIO::ImageSpec spec_of(const Image &img, const Rect &window, const Rect &display)
{
    OIIO::ImageSpec s(img.width(), img.height(), img.channels(), OIIO::TypeDesc::FLOAT);
    s.x = window.x0;
    s.y = window.y0;
    s.full_x = display.x0;
    s.full_y = display.y0;
    s.full_width = display.width();
    s.full_height = display.height();
    return s;
}

/// An ImageBuf over the image's own pixels (no copy). ImageBufAlgo only reads a source, so
/// wrapping a const image is safe.
OIIO::ImageBuf wrap(const Image &img, const Rect &window, const Rect &display)
{
    return OIIO::ImageBuf(spec_of(img, window, display), const_cast<float *>(img.data()));
}

/// Run `op(dst_buf, band_roi)` over row bands of `dst` in parallel and throw the first error
/// ImageBufAlgo reported (outside the parallel loop).
template <typename Op>
void run_bands(Image &dst, const Rect &window, const Rect &display, const char *what, Op &&op)
{
    OIIO::ImageBuf out(spec_of(dst, window, display), dst.data());
    const int bands = (dst.height() + kBandRows - 1) / kBandRows;
    std::vector<std::string> errors(std::size_t(std::max(bands, 0)));
    parallel_for(0, bands, [&](int b) {
        const int y0 = window.y0 + b * kBandRows;
        const OIIO::ROI roi(
            window.x0, window.x1, y0, std::min(y0 + kBandRows, window.y1), 0, 1, 0, dst.channels());
        if (!op(out, roi)) {
            errors[std::size_t(b)] = out.geterror();
            if (errors[std::size_t(b)].empty()) {
                errors[std::size_t(b)] = "failed";
            }
        }
    });
    for (const std::string &e : errors) {
        if (!e.empty()) {
            throw_runtime("ImageBufAlgo::", what, ": ", e);
        }
    }
}

}  // namespace

Affine window_map(const Rect &from, const Rect &to)
{
    const double sx = double(to.width()) / double(from.width());
    const double sy = double(to.height()) / double(from.height());
    Affine m(1.0);
    m[0][0] = sx;
    m[1][1] = sy;
    m[2][0] = to.x0 - sx * from.x0;
    m[2][1] = to.y0 - sy * from.y0;
    return m;
}

Rect transformed_bounds(const Affine &m, const Rect &r)
{
    double x0 = HUGE_VAL, y0 = HUGE_VAL, x1 = -HUGE_VAL, y1 = -HUGE_VAL;
    for (const glm::dvec2 c : {glm::dvec2(r.x0, r.y0),
                               glm::dvec2(r.x1, r.y0),
                               glm::dvec2(r.x0, r.y1),
                               glm::dvec2(r.x1, r.y1)}) {
        const glm::dvec3 p = m * glm::dvec3(c, 1.0);
        x0 = std::min(x0, p.x);
        y0 = std::min(y0, p.y);
        x1 = std::max(x1, p.x);
        y1 = std::max(y1, p.y);
    }
    auto snap = [](double v) {
        const double n = std::round(v);
        return std::abs(v - n) < 1e-6 ? n : v;
    };
    // Clamp before converting, so an absurd transform cannot overflow an int.
    auto to_int = [](double v) { return int(std::clamp(v, -1e9, 1e9)); };
    return {to_int(std::floor(snap(x0))),
            to_int(std::floor(snap(y0))),
            to_int(std::ceil(snap(x1))),
            to_int(std::ceil(snap(y1)))};
}

bool is_filter_name(const std::string &name)
{
    for (int i = 0, n = OIIO::Filter2D::num_filters(); i < n; ++i) {
        if (name == OIIO::Filter2D::get_filterdesc(i).name) {
            return true;
        }
    }
    return false;
}

bool is_separable_filter(const std::string &name)
{
    for (int i = 0, n = OIIO::Filter2D::num_filters(); i < n; ++i) {
        if (name == OIIO::Filter2D::get_filterdesc(i).name) {
            return OIIO::Filter2D::get_filterdesc(i).separable != 0;
        }
    }
    return false;
}

double filter_width(const std::string &name)
{
    for (int i = 0, n = OIIO::Filter2D::num_filters(); i < n; ++i) {
        if (name == OIIO::Filter2D::get_filterdesc(i).name) {
            return OIIO::Filter2D::get_filterdesc(i).width;
        }
    }
    return 0.0;
}

Image resize_filtered(const Image &src,
                      const Rect &src_window,
                      const Rect &src_display,
                      const Rect &dst_window,
                      const Rect &dst_display,
                      const std::string &filter)
{
    const OIIO::ImageBuf in = wrap(src, src_window, src_display);
    Image dst = Image::uninitialized(dst_window.width(), dst_window.height(), src.channels());
    run_bands(dst, dst_window, dst_display, "resize", [&](OIIO::ImageBuf &out, OIIO::ROI roi) {
        return OIIO::ImageBufAlgo::resize(out, in, filter, 0.0f, roi, 1);
    });
    return dst;
}

Image warp_filtered(const Image &src,
                    const Rect &src_window,
                    const Affine &to_output,
                    const Rect &dst_window,
                    const std::string &filter,
                    bool extend_edges)
{
    const OIIO::ImageBuf in = wrap(src, src_window, src_window);
    // OpenImageIO's matrices act on row vectors (p' = p M): the transpose of glm's column form.
    const float m[3][3] = {{float(to_output[0][0]), float(to_output[0][1]), 0.0f},
                           {float(to_output[1][0]), float(to_output[1][1]), 0.0f},
                           {float(to_output[2][0]), float(to_output[2][1]), 1.0f}};
    Image dst = Image::uninitialized(dst_window.width(), dst_window.height(), src.channels());
    run_bands(dst, dst_window, dst_window, "warp", [&](OIIO::ImageBuf &out, OIIO::ROI roi) {
        return OIIO::ImageBufAlgo::warp(
            out,
            in,
            m,
            filter,
            0.0f,
            false,
            extend_edges ? OIIO::ImageBuf::WrapClamp : OIIO::ImageBuf::WrapBlack,
            roi,
            1);
    });
    return dst;
}

void nearest_sources(const Affine &to_input,
                     const Rect &src_window,
                     const Rect &dst_window,
                     int y,
                     std::int32_t *out)
{
    for (int x = 0; x < dst_window.width(); ++x) {
        const glm::dvec3 p =
            to_input * glm::dvec3(dst_window.x0 + x + 0.5, dst_window.y0 + y + 0.5, 1.0);
        const double fx = std::floor(p.x), fy = std::floor(p.y);
        out[x] =
            fx >= src_window.x0 && fx < src_window.x1 && fy >= src_window.y0 && fy < src_window.y1
                ? std::int32_t((int(fy) - src_window.y0) * src_window.width() +
                               (int(fx) - src_window.x0))
                : -1;
    }
}

Image sample_nearest(const Image &src,
                     const Rect &src_window,
                     const Affine &to_input,
                     const Rect &dst_window,
                     float outside)
{
    const int w = dst_window.width(), nc = src.channels();
    Image dst = Image::uninitialized(w, dst_window.height(), nc);
    parallel_for(0, dst_window.height(), [&](int y) {
        std::vector<std::int32_t> near(static_cast<std::size_t>(w));
        nearest_sources(to_input, src_window, dst_window, y, near.data());
        float *d = dst.pixel(0, y);
        for (int x = 0; x < w; ++x, d += nc) {
            if (near[std::size_t(x)] >= 0) {
                const float *s = src.data() + std::size_t(near[std::size_t(x)]) * std::size_t(nc);
                std::copy(s, s + nc, d);
            } else {
                std::fill(d, d + nc, outside);
            }
        }
    });
    return dst;
}

Image gaussian_blur(const Image &src, double sigma_x, double sigma_y, int c0, int c1)
{
    if (c1 < 0) {
        c1 = src.channels();
    }
    const std::vector<float> kx = gaussian_kernel(sigma_x), ky = gaussian_kernel(sigma_y);
    const int rx = int(kx.size() / 2), ry = int(ky.size() / 2);
    const int w = src.width(), h = src.height(), nc = src.channels();
    const std::size_t n = std::size_t(w) * std::size_t(nc);
    // Along x: each row padded with its edge pixels, filtered with stride nc (each channel on
    // its own) into `rows`, whose spare rows at the end give the column pass its kFirPad floats.
    const int spare = int((kFirPad + n - 1) / n);
    Image rows_image = Image::uninitialized(w, h + spare, nc);
    float *const rows = rows_image.data();
    parallel_for(0, h, [&](int y) {
        std::vector<float> padded(n + std::size_t(2 * rx * nc) + kFirPad, 0.0f);
        const float *s = src.pixel(0, y);
        for (int x = -rx; x < w + rx; ++x) {
            const float *p = s + std::size_t(std::clamp(x, 0, w - 1)) * std::size_t(nc);
            std::copy(p, p + nc, padded.data() + std::size_t(x + rx) * std::size_t(nc));
        }
        std::vector<float> out(n + kFirPad);
        fir_row(padded.data(), kx.data(), int(kx.size()), nc, int(n), out.data());
        std::copy(out.begin(), out.begin() + std::ptrdiff_t(n), rows + std::size_t(y) * n);
    });
    // Along y: the rows above and below clamped to the image.
    Image dst = Image::uninitialized(w, h, nc);
    parallel_for(0, h, [&](int y) {
        std::vector<const float *> taps(ky.size());
        for (int i = -ry; i <= ry; ++i) {
            taps[std::size_t(i + ry)] = rows + std::size_t(std::clamp(y + i, 0, h - 1)) * n;
        }
        std::vector<float> out(n + kFirPad);
        fir_columns(taps.data(), ky.data(), int(ky.size()), int(n), out.data());
        float *d = dst.pixel(0, y);
        if (c0 == 0 && c1 == nc) {
            std::copy(out.begin(), out.begin() + std::ptrdiff_t(n), d);
            return;
        }
        const float *s = src.pixel(0, y);
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < nc; ++c) {
                const std::size_t i = std::size_t(x) * std::size_t(nc) + std::size_t(c);
                d[i] = c >= c0 && c < c1 ? out[i] : s[i];
            }
        }
    });
    return dst;
}

}  // namespace posthaste::filter
