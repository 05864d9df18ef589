// Lens distortion and the resampling map (see lens.h).

#include "filter/lens.h"

#include <algorithm>
#include <cmath>
#include <glm/mat2x2.hpp>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "filter/lens_kernels.h"

namespace posthaste::filter {

glm::dvec2 Distortion::distort(glm::dvec2 u) const
{
    const double x = u.x, y = u.y, r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
            y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

glm::dmat2 Distortion::jacobian(glm::dvec2 u) const
{
    const double x = u.x, y = u.y, r2 = x * x + y * y;
    const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
    const double dradial = k1 + r2 * (2.0 * k2 + 3.0 * k3 * r2);  // d radial / d (r^2)
    // d radial / dx = dradial * 2x.
    const double dxdx = radial + x * dradial * 2.0 * x + 2.0 * p1 * y + p2 * 6.0 * x;
    const double dxdy = x * dradial * 2.0 * y + 2.0 * p1 * x + p2 * 2.0 * y;
    const double dydx = y * dradial * 2.0 * x + p1 * 2.0 * x + 2.0 * p2 * y;
    const double dydy = radial + y * dradial * 2.0 * y + p1 * 6.0 * y + 2.0 * p2 * x;
    return glm::dmat2(dxdx, dydx, dxdy, dydy);  // columns: d/dx, d/dy
}

std::optional<glm::dvec2> Distortion::undistort(glm::dvec2 d) const
{
    glm::dvec2 u = d;
    for (int i = 0; i < 50; ++i) {
        const glm::dvec2 err = distort(u) - d;
        if (std::abs(err.x) < 1e-12 && std::abs(err.y) < 1e-12) {
            return u;
        }
        const glm::dmat2 j = jacobian(u);
        const double det = glm::determinant(j);
        if (!(std::abs(det) > 1e-12)) {
            return std::nullopt;
        }
        u -= glm::inverse(j) * err;
        if (!std::isfinite(u.x) || !std::isfinite(u.y)) {
            return std::nullopt;
        }
    }
    const glm::dvec2 err = distort(u) - d;
    if (std::abs(err.x) < 1e-9 && std::abs(err.y) < 1e-9) {
        return u;
    }
    return std::nullopt;
}

namespace {

glm::dvec2 to_norm(const LensGeometry &g, glm::dvec2 p)
{
    return (p - g.centre) / g.unit;
}

glm::dvec2 to_pixels(const LensGeometry &g, glm::dvec2 n)
{
    return n * g.unit + g.centre;
}

/// Where an input point lands in the output (nullopt: it does not).
std::optional<glm::dvec2> forward(const LensGeometry &g, glm::dvec2 p)
{
    const glm::dvec2 n = to_norm(g, p);
    if (!g.undistort) {
        return to_pixels(g, g.distortion.distort(n));
    }
    const auto u = g.distortion.undistort(n);
    return u ? std::optional(to_pixels(g, *u)) : std::nullopt;
}

/// Where an output point reads the input.
std::optional<glm::dvec2> backward(const LensGeometry &g, glm::dvec2 p)
{
    const glm::dvec2 n = to_norm(g, p);
    if (g.undistort) {
        return to_pixels(g, g.distortion.distort(n));
    }
    const auto u = g.distortion.undistort(n);
    return u ? std::optional(to_pixels(g, *u)) : std::nullopt;
}

/// floor(v) as an int for |v| < 2^31, without a libm call (std::floor is one on baseline x86-64).
inline int floor_int(float v)
{
    const int t = int(v);
    return t - (float(t) > v ? 1 : 0);
}

float cubic_weight(float t)
{
    // Catmull-Rom (B = 0, C = 1/2).
    t = std::abs(t);
    if (t < 1.0f) {
        return 1.5f * t * t * t - 2.5f * t * t + 1.0f;
    }
    if (t < 2.0f) {
        return -0.5f * t * t * t + 2.5f * t * t - 4.0f * t + 2.0f;
    }
    return 0.0f;
}

}  // namespace

LensMap build_lens_map(const LensGeometry &g,
                       const Rect &input_window,
                       const Rect &limit,
                       const std::string &who)
{
    LensMap map;
    // The distortion must be one-to-one where it is used: over the undistorted side of the
    // mapping (the input for distort; for undistort, where the input's points come from).
    // Checked on a grid of about 64 x 64 points over the input window and, since a fold can be a
    // thin ring, along 32 rays from the centre to the farthest corner in 4096 steps.
    const Rect &in = input_window;
    auto check = [&](glm::dvec2 p) {
        if (g.undistort) {
            const auto u = g.distortion.undistort(to_norm(g, p));
            if (!u) {
                return;
            }
            p = to_pixels(g, *u);
        }
        const double det = glm::determinant(g.distortion.jacobian(to_norm(g, p)));
        if (!(det > 0.0)) {
            throw_usage(who,
                        ": the distortion folds over at pixel (",
                        int(std::floor(p.x)),
                        ", ",
                        int(std::floor(p.y)),
                        ") (Jacobian determinant ",
                        det,
                        "): it has no inverse there; reduce k1..k3, p1, p2");
        }
    };
    const double step_x = std::max(1.0, in.width() / 64.0),
                 step_y = std::max(1.0, in.height() / 64.0);
    for (double y = in.y0; y <= in.y1; y += step_y) {
        for (double x = in.x0; x <= in.x1; x += step_x) {
            check({x, y});
        }
    }
    double reach = 0.0;
    for (const glm::dvec2 corner : {glm::dvec2(in.x0, in.y0),
                                    glm::dvec2(in.x1, in.y0),
                                    glm::dvec2(in.x0, in.y1),
                                    glm::dvec2(in.x1, in.y1)}) {
        reach = std::max(reach, glm::length(corner - g.centre));
    }
    for (int k = 0; k < 32; ++k) {
        const double a = 2.0 * 3.14159265358979323846 * k / 32.0;
        const glm::dvec2 dir(std::cos(a), std::sin(a));
        for (int t = 1; t <= 4096; ++t) {
            const glm::dvec2 p = g.centre + dir * (reach * t / 4096.0);
            if (p.x >= in.x0 && p.x <= in.x1 && p.y >= in.y0 && p.y <= in.y1) {
                check(p);
            }
        }
    }
    // The output window: the input window's edges (every 2 px) moved by the lens.
    double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
    auto add = [&](double x, double y) {
        const auto q = forward(g, {x, y});
        if (q) {
            x0 = std::min(x0, q->x);
            y0 = std::min(y0, q->y);
            x1 = std::max(x1, q->x);
            y1 = std::max(y1, q->y);
        }
    };
    for (int x = in.x0; x <= in.x1; x += 2) {
        add(x, in.y0);
        add(x, in.y1);
    }
    for (int y = in.y0; y <= in.y1; y += 2) {
        add(in.x0, y);
        add(in.x1, y);
    }
    add(in.x1, in.y1);
    if (!(x1 > x0) || !(y1 > y0)) {
        throw_usage(who, ": the distortion moves the whole image out of reach");
    }
    map.window = Rect{int(std::floor(x0 + 1e-6)),
                      int(std::floor(y0 + 1e-6)),
                      int(std::ceil(x1 - 1e-6)),
                      int(std::ceil(y1 - 1e-6))}
                     .intersect(limit);
    if (map.window.empty()) {
        throw_usage(who, ": the distorted image lies outside the frame's limits");
    }
    const int w = map.window.width(), h = map.window.height();
    map.sx.resize(std::size_t(w) * std::size_t(h));
    map.sy.resize(map.sx.size());
    map.nearest.resize(map.sx.size());
    const float nan = std::numeric_limits<float>::quiet_NaN();
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const glm::dvec2 p(map.window.x0 + x + 0.5, map.window.y0 + y + 0.5);
            const auto s = backward(g, p);
            const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
            map.sx[i] = s ? float(s->x - in.x0) : nan;
            map.sy[i] = s ? float(s->y - in.y0) : nan;
            // The pixel `sample` with Resample::Nearest reads (same float coordinates).
            const int nx = s ? floor_int(map.sx[i]) : -1, ny = s ? floor_int(map.sy[i]) : -1;
            map.nearest[i] = nx >= 0 && ny >= 0 && nx < in.width() && ny < in.height()
                                 ? std::int32_t(ny * in.width() + nx)
                                 : -1;
        }
    });
    return map;
}

float sample(const Image &img, int c, float x, float y, Resample filter, float outside)
{
    if (!std::isfinite(x) || !std::isfinite(y)) {
        return outside;
    }
    auto at = [&](int i, int j) {
        return i < 0 || j < 0 || i >= img.width() || j >= img.height() ? outside : img.at(i, j, c);
    };
    switch (filter) {
        case Resample::Nearest:
            if (std::abs(x) > 1e9f || std::abs(y) > 1e9f) {
                return outside;
            }
            return at(floor_int(x), floor_int(y));
        case Resample::Bilinear: {
            const float fx = x - 0.5f, fy = y - 0.5f;
            const int i = int(std::floor(fx)), j = int(std::floor(fy));
            const float a = fx - float(i), b = fy - float(j);
            return (1 - a) * (1 - b) * at(i, j) + a * (1 - b) * at(i + 1, j) +
                   (1 - a) * b * at(i, j + 1) + a * b * at(i + 1, j + 1);
        }
        case Resample::Bicubic: {
            const float fx = x - 0.5f, fy = y - 0.5f;
            const int i = int(std::floor(fx)), j = int(std::floor(fy));
            const float a = fx - float(i), b = fy - float(j);
            float wx[4], wy[4];
            for (int k = 0; k < 4; ++k) {
                wx[k] = cubic_weight(a - float(k - 1));
                wy[k] = cubic_weight(b - float(k - 1));
            }
            float s = 0.0f;
            for (int m = 0; m < 4; ++m) {
                float row = 0.0f;
                for (int k = 0; k < 4; ++k) {
                    row += wx[k] * at(i + k - 1, j + m - 1);
                }
                s += wy[m] * row;
            }
            return s;
        }
    }
    return outside;
}

namespace {

/// The weighted sum of a taps x taps footprint at (i, j), N channels from c0 (N = 0: n).
template <int Taps, int N>
void footprint(
    const Image &img, int i, int j, int c0, int n, const float *wx, const float *wy, float *out)
{
    const int count = N > 0 ? N : n;
    const int nc = img.channels();
    float acc[64];
    std::fill(acc, acc + count, 0.0f);
    for (int m = 0; m < Taps; ++m) {
        float row[64];
        std::fill(row, row + count, 0.0f);
        const float *p = img.pixel(i, j + m) + c0;
        for (int k = 0; k < Taps; ++k) {
            for (int c = 0; c < count; ++c) {
                row[c] += wx[k] * p[k * nc + c];
            }
        }
        for (int c = 0; c < count; ++c) {
            acc[c] += wy[m] * row[c];
        }
    }
    std::copy(acc, acc + count, out);
}

}  // namespace

void sample_channels(
    const Image &img, int c0, int c1, float x, float y, Resample filter, float outside, float *out)
{
    const int n = c1 - c0;
    if (!std::isfinite(x) || !std::isfinite(y) || filter == Resample::Nearest ||
        std::abs(x) > 1e8f || std::abs(y) > 1e8f) {
        for (int c = c0; c < c1; ++c) {
            out[c - c0] = sample(img, c, x, y, filter, outside);
        }
        return;
    }
    const bool cubic = filter == Resample::Bicubic;
    const int taps = cubic ? 4 : 2;
    const float fx = x - 0.5f, fy = y - 0.5f;
    const int ix = floor_int(fx), iy = floor_int(fy);
    const int i = ix - (taps / 2 - 1), j = iy - (taps / 2 - 1);
    if (i + taps <= 0 || j + taps <= 0 || i >= img.width() || j >= img.height()) {
        std::fill(out, out + n, outside);  // every tap outside the image
        return;
    }
    if (i < 0 || j < 0 || i + taps > img.width() || j + taps > img.height()) {
        for (int c = c0; c < c1; ++c) {
            out[c - c0] = sample(img, c, x, y, filter, outside);
        }
        return;
    }
    const float a = fx - float(ix), b = fy - float(iy);
    float wx[4], wy[4];
    if (cubic) {
        // Catmull-Rom weights of the taps at -1, 0, 1, 2 for a fraction t.
        auto weights = [](float t, float *w) {
            const float t2 = t * t, t3 = t2 * t;
            w[0] = -0.5f * t3 + t2 - 0.5f * t;
            w[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
            w[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
            w[3] = 0.5f * t3 - 0.5f * t2;
        };
        weights(a, wx);
        weights(b, wy);
        if (n == 4) {
            footprint<4, 4>(img, i, j, c0, n, wx, wy, out);
        } else if (n == 1) {
            footprint<4, 1>(img, i, j, c0, n, wx, wy, out);
        } else {
            footprint<4, 0>(img, i, j, c0, n, wx, wy, out);
        }
        return;
    }
    wx[0] = 1.0f - a;
    wx[1] = a;
    wy[0] = 1.0f - b;
    wy[1] = b;
    if (n == 4) {
        footprint<2, 4>(img, i, j, c0, n, wx, wy, out);
    } else if (n == 1) {
        footprint<2, 1>(img, i, j, c0, n, wx, wy, out);
    } else {
        footprint<2, 0>(img, i, j, c0, n, wx, wy, out);
    }
}

void resample_row(const Image &img,
                  const float *xs,
                  const float *ys,
                  int n,
                  Resample filter,
                  float outside,
                  float *out)
{
    const int nc = img.channels();
    std::vector<std::uint8_t> edge(static_cast<std::size_t>(n), 1);
    if (nc == 4 && filter != Resample::Nearest) {
        lens_resample_rgba_row(img.data(),
                               img.width(),
                               img.height(),
                               xs,
                               ys,
                               n,
                               filter == Resample::Bicubic ? 4 : 2,
                               out,
                               edge.data());
    }
    for (int x = 0; x < n; ++x) {
        if (edge[std::size_t(x)]) {
            sample_channels(img, 0, nc, xs[x], ys[x], filter, outside, out + std::size_t(x) * nc);
        }
    }
}

}  // namespace posthaste::filter
