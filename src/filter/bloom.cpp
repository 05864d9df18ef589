// Bloom by FFT convolution and by a fitted downsample/upsample pyramid (see bloom.h).

#include "filter/bloom.h"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

#include "core/error.h"
#include "core/parallel.h"

namespace posthaste::filter {
namespace {

// FFTW's planner is not thread-safe; executing a plan on new arrays is. Plans are made once per
// size with FFTW_ESTIMATE (no timing, so the same plan, and the same bits, on every run) and kept
// for the life of the process.
std::mutex g_plan_mutex;

struct RealPlans {
    fftwf_plan forward = nullptr;   // real (h x w) -> complex (h x (w/2 + 1))
    fftwf_plan backward = nullptr;  // and back (unnormalised)
};

const RealPlans &real_plans(int w, int h)
{
    static std::map<std::pair<int, int>, RealPlans> plans;
    std::lock_guard lock(g_plan_mutex);
    RealPlans &p = plans[{w, h}];
    if (!p.forward) {
        const std::size_t n = std::size_t(w) * std::size_t(h);
        const std::size_t nc = std::size_t(w / 2 + 1) * std::size_t(h);
        float *r = fftwf_alloc_real(n);
        fftwf_complex *c = fftwf_alloc_complex(nc);
        p.forward = fftwf_plan_dft_r2c_2d(h, w, r, c, FFTW_ESTIMATE);
        p.backward = fftwf_plan_dft_c2r_2d(h, w, c, r, FFTW_ESTIMATE);
        fftwf_free(r);
        fftwf_free(c);
        if (!p.forward || !p.backward) {
            throw_runtime("bloom: FFTW could not plan a ", w, "x", h, " transform");
        }
    }
    return p;
}

template <typename T>
struct FftwFree {
    void operator()(T *p) const { fftwf_free(p); }
};
using RealBuffer = std::unique_ptr<float[], FftwFree<float>>;
using ComplexBuffer = std::unique_ptr<fftwf_complex[], FftwFree<fftwf_complex>>;

RealBuffer alloc_real(std::size_t n)
{
    RealBuffer b(fftwf_alloc_real(n));
    if (!b) {
        throw_runtime("bloom: out of memory for a ", n, "-value FFT buffer");
    }
    return b;
}

ComplexBuffer alloc_complex(std::size_t n)
{
    ComplexBuffer b(fftwf_alloc_complex(n));
    if (!b) {
        throw_runtime("bloom: out of memory for a ", n, "-value FFT buffer");
    }
    return b;
}

/// The smallest n' >= n whose prime factors are 2, 3, 5 and 7 (FFTW's fast sizes).
int fft_size(int n)
{
    for (int m = std::max(n, 1);; ++m) {
        int r = m;
        for (int f : {2, 3, 5, 7}) {
            while (r % f == 0) {
                r /= f;
            }
        }
        if (r == 1) {
            return m;
        }
    }
}

float finite_or_zero(float v)
{
    return std::isfinite(v) ? v : 0.0f;
}

// ---- the built-in PSF ----------------------------------------------------------------------

constexpr int kApertureGrid = 256;  // the diffraction pattern's FFT size
constexpr int kApertureCells = 64;  // the aperture's diameter in grid cells
constexpr double kWavelengthUm[3] = {0.610, 0.550, 0.465};

/// |FT(aperture)|^2 on the kApertureGrid^2 grid, centred (fft-shifted), summing to 1.
std::vector<double> diffraction_pattern(int blades, double rotation_deg)
{
    const int m = kApertureGrid;
    const double rad = kApertureCells * 0.5;
    const double rot = rotation_deg * std::numbers::pi / 180.0;
    // Inside a regular polygon with `blades` sides inscribed in the circle of radius `rad`
    // (apothem rad cos(pi / n)), or inside the circle.
    auto inside = [&](double x, double y) {
        const double r = std::hypot(x, y);
        if (blades < 3) {
            return r <= rad;
        }
        const double sector = 2.0 * std::numbers::pi / blades;
        double a = std::atan2(y, x) - rot;
        a -= sector * std::floor(a / sector);
        const double apothem = rad * std::cos(std::numbers::pi / blades);
        return r * std::cos(a - sector * 0.5) <= apothem;
    };
    fftwf_complex *buf = fftwf_alloc_complex(std::size_t(m) * std::size_t(m));
    if (!buf) {
        throw_runtime("bloom: out of memory for the aperture's FFT");
    }
    constexpr int kSuper = 4;
    for (int y = 0; y < m; ++y) {
        for (int x = 0; x < m; ++x) {
            int hits = 0;
            for (int sy = 0; sy < kSuper; ++sy) {
                for (int sx = 0; sx < kSuper; ++sx) {
                    const double px = x - m / 2 + (sx + 0.5) / kSuper;
                    const double py = y - m / 2 + (sy + 0.5) / kSuper;
                    hits += inside(px, py);
                }
            }
            buf[y * m + x][0] = float(hits) / float(kSuper * kSuper);
            buf[y * m + x][1] = 0.0f;
        }
    }
    {
        std::lock_guard lock(g_plan_mutex);
        fftwf_plan plan = fftwf_plan_dft_2d(m, m, buf, buf, FFTW_FORWARD, FFTW_ESTIMATE);
        fftwf_execute(plan);
        fftwf_destroy_plan(plan);
    }
    std::vector<double> pattern(std::size_t(m) * std::size_t(m));
    double sum = 0.0;
    for (int y = 0; y < m; ++y) {
        for (int x = 0; x < m; ++x) {
            const fftwf_complex &v = buf[((y + m / 2) % m) * m + (x + m / 2) % m];
            const double e = double(v[0]) * v[0] + double(v[1]) * v[1];
            pattern[std::size_t(y * m + x)] = e;
            sum += e;
        }
    }
    fftwf_free(buf);
    for (double &v : pattern) {
        v /= sum;
    }
    return pattern;
}

/// The diffraction pattern resampled onto the pixel grid at `cell_px` pixels per grid cell.
std::vector<double> pattern_on_pixels(const std::vector<double> &pattern,
                                      double cell_px,
                                      int radius)
{
    const int m = kApertureGrid, size = 2 * radius + 1;
    std::vector<double> out(std::size_t(size) * std::size_t(size), 0.0);
    auto put = [&](int x, int y, double v) {
        if (x >= -radius && x <= radius && y >= -radius && y <= radius) {
            out[std::size_t((y + radius) * size + x + radius)] += v;
        }
    };
    if (!(cell_px > 0.0)) {
        put(0, 0, 1.0);
        return out;
    }
    if (cell_px <= 1.0) {
        // Cells smaller than pixels: splat each cell's energy bilinearly.
        for (int v = 0; v < m; ++v) {
            for (int u = 0; u < m; ++u) {
                const double e = pattern[std::size_t(v * m + u)];
                const double x = (u - m / 2) * cell_px, y = (v - m / 2) * cell_px;
                const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
                const double fx = x - x0, fy = y - y0;
                put(x0, y0, e * (1 - fx) * (1 - fy));
                put(x0 + 1, y0, e * fx * (1 - fy));
                put(x0, y0 + 1, e * (1 - fx) * fy);
                put(x0 + 1, y0 + 1, e * fx * fy);
            }
        }
    } else {
        // Cells larger than pixels: sample the pattern bilinearly at each pixel.
        const int reach = std::min(radius, int((m / 2 - 1) * cell_px));
        for (int y = -reach; y <= reach; ++y) {
            for (int x = -reach; x <= reach; ++x) {
                const double u = x / cell_px + m / 2, v = y / cell_px + m / 2;
                const int u0 = int(std::floor(u)), v0 = int(std::floor(v));
                if (u0 < 0 || v0 < 0 || u0 + 1 >= m || v0 + 1 >= m) {
                    continue;
                }
                const double fu = u - u0, fv = v - v0;
                auto p = [&](int a, int b) { return pattern[std::size_t(b * m + a)]; };
                put(x,
                    y,
                    p(u0, v0) * (1 - fu) * (1 - fv) + p(u0 + 1, v0) * fu * (1 - fv) +
                        p(u0, v0 + 1) * (1 - fu) * fv + p(u0 + 1, v0 + 1) * fu * fv);
            }
        }
    }
    double sum = 0.0;
    for (double v : out) {
        sum += v;
    }
    if (!(sum > 0.0)) {
        std::fill(out.begin(), out.end(), 0.0);
        out[std::size_t(radius * size + radius)] = 1.0;
    } else {
        for (double &v : out) {
            v /= sum;
        }
    }
    return out;
}

/// The scattering tail on the pixel grid, truncated at `radius`, summing to 1.
std::vector<double> tail_on_pixels(double r0, double falloff, int radius)
{
    const int size = 2 * radius + 1;
    std::vector<double> out(std::size_t(size) * std::size_t(size), 0.0);
    double sum = 0.0;
    // Each pixel's value is the kernel averaged over the pixel (4 x 4 samples) where it curves
    // (near the centre), so a tail narrower than a pixel still sums correctly; one sample
    // elsewhere.
    const double near = 4.0 + 4.0 * r0;
    for (int y = -radius; y <= radius; ++y) {
        for (int x = -radius; x <= radius; ++x) {
            if (double(x) * x + double(y) * y > double(radius) * radius) {
                continue;
            }
            const int sub = double(x) * x + double(y) * y <= near * near ? 4 : 1;
            double k = 0.0;
            for (int sy = 0; sy < sub; ++sy) {
                for (int sx = 0; sx < sub; ++sx) {
                    const double px = x + (sx + 0.5) / sub - 0.5, py = y + (sy + 0.5) / sub - 0.5;
                    k += std::pow(1.0 + (px * px + py * py) / (r0 * r0), -falloff);
                }
            }
            k /= sub * sub;
            out[std::size_t((y + radius) * size + x + radius)] = k;
            sum += k;
        }
    }
    for (double &v : out) {
        v /= sum;
    }
    return out;
}

// ---- the pyramid ---------------------------------------------------------------------------
//
// Levels hold NC channels interleaved (3 for an image's RGB, 1 for the fit's impulse responses).
// The loops keep the edge clamping out of their interiors so that they vectorise.

template <int NC>
struct Plane {
    int w = 0, h = 0;
    std::vector<float> v;
    Plane() = default;
    Plane(int w_, int h_) : w(w_), h(h_), v(std::size_t(w_) * std::size_t(h_) * NC, 0.0f) {}
    float *row(int y) { return v.data() + std::size_t(y) * std::size_t(w) * NC; }
    const float *row(int y) const { return v.data() + std::size_t(y) * std::size_t(w) * NC; }
};

/// Rows of `w` pixels, `stride` floats apart, of which the first NC are read.
struct View {
    const float *data;
    int w, h, stride;
    const float *row(int y) const
    {
        return data + std::size_t(y) * std::size_t(w) * std::size_t(stride);
    }
};

template <int NC>
View view_of(const Plane<NC> &p)
{
    return {p.v.data(), p.w, p.h, NC};
}

/// Rows [0, n) in parallel, in blocks, each row written by one task.
void for_rows(int n, const std::function<void(int)> &fn)
{
    constexpr int kBlock = 16;
    parallel_for(0, (n + kBlock - 1) / kBlock, [&](int b) {
        for (int y = b * kBlock; y < std::min(n, (b + 1) * kBlock); ++y) {
            fn(y);
        }
    });
}

// Downsample by 2 with the separable [1 3 3 1] / 8 filter (coarse pixel x is centred between
// fine pixels 2x and 2x + 1), edges clamped.
template <int NC>
Plane<NC> downsample(const View &in)
{
    const int w = in.w, h = in.h, w2 = (w + 1) / 2, h2 = (h + 1) / 2, st = in.stride;
    Plane<NC> tmp(w2, h), out(w2, h2);
    // Interior columns: 2x - 1 >= 0 and 2x + 2 <= w - 1.
    const int lo = std::min(1, w2), hi = std::max(lo, std::min(w2, (w - 3) / 2 + 1));
    for_rows(h, [&](int y) {
        const float *s = in.row(y);
        float *d = tmp.row(y);
        auto clamped = [&](int x) {
            for (int c = 0; c < NC; ++c) {
                auto tap = [&](int i) {
                    return s[std::size_t(std::clamp(i, 0, w - 1)) * std::size_t(st) +
                             std::size_t(c)];
                };
                d[x * NC + c] = 0.125f * (tap(2 * x - 1) + tap(2 * x + 2)) +
                                0.375f * (tap(2 * x) + tap(2 * x + 1));
            }
        };
        for (int x = 0; x < lo; ++x) {
            clamped(x);
        }
        for (int x = lo; x < hi; ++x) {
            const float *p = s + std::size_t(2 * x - 1) * std::size_t(st);
            for (int c = 0; c < NC; ++c) {
                d[x * NC + c] =
                    0.125f * (p[c] + p[3 * st + c]) + 0.375f * (p[st + c] + p[2 * st + c]);
            }
        }
        for (int x = hi; x < w2; ++x) {
            clamped(x);
        }
    });
    const int n = w2 * NC;
    for_rows(h2, [&](int y) {
        auto r = [&](int i) { return tmp.row(std::clamp(i, 0, h - 1)); };
        const float *a = r(2 * y - 1), *b = r(2 * y), *c = r(2 * y + 1), *e = r(2 * y + 2);
        float *d = out.row(y);
        for (int i = 0; i < n; ++i) {
            d[i] = 0.125f * (a[i] + e[i]) + 0.375f * (b[i] + c[i]);
        }
    });
    return out;
}

/// One coarse row brought to `wf` pixels: fine pixel 2j + 1/2 -/+ 1/2 takes 3/4 of coarse pixel
/// j and 1/4 of its neighbour on that side (edges clamped).
template <int NC>
void upsample_row(const float *s, int wc, float *d, int wf)
{
    auto coarse = [&](int j, int c) { return s[std::clamp(j, 0, wc - 1) * NC + c]; };
    auto edge = [&](int x) {
        const int j = x >> 1, k = (x & 1) ? j + 1 : j - 1;
        for (int c = 0; c < NC; ++c) {
            d[x * NC + c] = 0.75f * coarse(j, c) + 0.25f * coarse(k, c);
        }
    };
    // Interior coarse pixels j in [1, wc - 2] whose both fine pixels exist.
    const int jhi = std::min(wc - 1, wf / 2);
    for (int x = 0; x < std::min(2, wf); ++x) {
        edge(x);
    }
    for (int j = 1; j < jhi; ++j) {
        for (int c = 0; c < NC; ++c) {
            const float m = 0.75f * s[j * NC + c];
            d[(2 * j) * NC + c] = m + 0.25f * s[(j - 1) * NC + c];
            d[(2 * j + 1) * NC + c] = m + 0.25f * s[(j + 1) * NC + c];
        }
    }
    for (int x = std::max(2, 2 * std::max(jhi, 1)); x < wf; ++x) {
        edge(x);
    }
}

/// fine = scale * fine + up(coarse).
template <int NC>
void upsample_add(const Plane<NC> &coarse, Plane<NC> &fine, float scale)
{
    Plane<NC> tmp(fine.w, coarse.h);
    for_rows(coarse.h,
             [&](int y) { upsample_row<NC>(coarse.row(y), coarse.w, tmp.row(y), fine.w); });
    const int n = fine.w * NC;
    for_rows(fine.h, [&](int y) {
        const int j = y >> 1, k = (y & 1) ? j + 1 : j - 1;
        const float *a = tmp.row(std::clamp(j, 0, coarse.h - 1));
        const float *b = tmp.row(std::clamp(k, 0, coarse.h - 1));
        float *d = fine.row(y);
        for (int i = 0; i < n; ++i) {
            d[i] = scale * d[i] + 0.75f * a[i] + 0.25f * b[i];
        }
    });
}

/// Number of coarse levels for a tail of radius R pixels: the coarsest level's pixels are at
/// most R / 2 wide.
int pyramid_levels(int radius)
{
    int n = 0;
    while ((2 << n) <= std::max(radius, 1)) {
        ++n;
    }
    return std::max(n, 1);
}

/// The coarse levels 1..n-1 of `levels` mixed onto level 1: sum_{i >= 1} weights[i] up(level i).
template <int NC>
Plane<NC> mix_coarse(std::vector<Plane<NC>> &levels, const std::vector<float> &weights)
{
    const int n = int(levels.size());
    Plane<NC> acc = std::move(levels[std::size_t(n - 1)]);
    for (float &v : acc.v) {
        v *= weights[std::size_t(n - 1)];
    }
    for (int i = n - 2; i >= 1; --i) {
        Plane<NC> next = std::move(levels[std::size_t(i)]);
        upsample_add(acc, next, weights[std::size_t(i)]);
        acc = std::move(next);
    }
    return acc;
}

/// Solve the small symmetric system G w = b for w >= 0 (an active set: solve, drop the most
/// negative weight, repeat).
std::vector<double> nonnegative_solve(const std::vector<double> &g, const std::vector<double> &b)
{
    const int n = int(b.size());
    std::vector<bool> active(std::size_t(n), true);
    std::vector<double> w(std::size_t(n), 0.0);
    for (int iter = 0; iter < n; ++iter) {
        std::vector<int> idx;
        for (int i = 0; i < n; ++i) {
            if (active[std::size_t(i)]) {
                idx.push_back(i);
            }
        }
        const int k = int(idx.size());
        // Gaussian elimination with partial pivoting on the active rows and columns.
        std::vector<double> a(std::size_t(k) * std::size_t(k + 1));
        double trace = 0.0;
        for (int r = 0; r < k; ++r) {
            trace += g[std::size_t(idx[std::size_t(r)] * n + idx[std::size_t(r)])];
        }
        for (int r = 0; r < k; ++r) {
            for (int c = 0; c < k; ++c) {
                a[std::size_t(r * (k + 1) + c)] =
                    g[std::size_t(idx[std::size_t(r)] * n + idx[std::size_t(c)])] +
                    (r == c ? 1e-12 * trace : 0.0);
            }
            a[std::size_t(r * (k + 1) + k)] = b[std::size_t(idx[std::size_t(r)])];
        }
        for (int col = 0; col < k; ++col) {
            int piv = col;
            for (int r = col + 1; r < k; ++r) {
                if (std::abs(a[std::size_t(r * (k + 1) + col)]) >
                    std::abs(a[std::size_t(piv * (k + 1) + col)])) {
                    piv = r;
                }
            }
            for (int c = 0; c <= k; ++c) {
                std::swap(a[std::size_t(col * (k + 1) + c)], a[std::size_t(piv * (k + 1) + c)]);
            }
            const double d = a[std::size_t(col * (k + 1) + col)];
            for (int r = col + 1; r < k; ++r) {
                const double f = a[std::size_t(r * (k + 1) + col)] / d;
                for (int c = col; c <= k; ++c) {
                    a[std::size_t(r * (k + 1) + c)] -= f * a[std::size_t(col * (k + 1) + c)];
                }
            }
        }
        std::vector<double> x(std::size_t(k), 0.0);
        for (int r = k - 1; r >= 0; --r) {
            double s = a[std::size_t(r * (k + 1) + k)];
            for (int c = r + 1; c < k; ++c) {
                s -= a[std::size_t(r * (k + 1) + c)] * x[std::size_t(c)];
            }
            x[std::size_t(r)] = s / a[std::size_t(r * (k + 1) + r)];
        }
        int worst = -1;
        for (int r = 0; r < k; ++r) {
            if (x[std::size_t(r)] < 0.0 &&
                (worst < 0 || x[std::size_t(r)] < x[std::size_t(worst)])) {
                worst = r;
            }
        }
        std::fill(w.begin(), w.end(), 0.0);
        if (worst < 0) {
            for (int r = 0; r < k; ++r) {
                w[std::size_t(idx[std::size_t(r)])] = x[std::size_t(r)];
            }
            return w;
        }
        active[std::size_t(idx[std::size_t(worst)])] = false;
    }
    return w;
}

}  // namespace

int bloom_radius_px(const BloomPsfParams &p, int display_width)
{
    return std::max(1, int(std::lround(p.radius * std::max(display_width, 1))));
}

Psf tail_psf(const BloomPsfParams &p, int display_width)
{
    Psf psf;
    psf.radius = bloom_radius_px(p, display_width);
    const double r0 = std::max(p.size * display_width, 1e-3);
    const std::vector<double> tail = tail_on_pixels(r0, p.falloff, psf.radius);
    for (auto &plane : psf.planes) {
        plane.assign(tail.begin(), tail.end());
    }
    return psf;
}

Psf builtin_psf(const BloomPsfParams &p, int display_width)
{
    Psf psf = tail_psf(p, display_width);
    std::vector<double> pattern;
    if (p.diffraction_scale > 0.0) {
        pattern = diffraction_pattern(p.blades, p.blade_rotation);
    }
    for (int c = 0; c < 3; ++c) {
        // One grid cell of the pattern is lambda N (aperture cells / grid) on the sensor.
        const double cell_px = p.diffraction_scale * kWavelengthUm[c] * p.fstop *
                               (double(kApertureCells) / kApertureGrid) / p.pixel_pitch_um;
        const std::vector<double> core = pattern.empty()
                                             ? pattern_on_pixels({}, 0.0, psf.radius)
                                             : pattern_on_pixels(pattern, cell_px, psf.radius);
        auto &plane = psf.planes[std::size_t(c)];
        double sum = 0.0;
        std::vector<double> mixed(plane.size());
        for (std::size_t i = 0; i < plane.size(); ++i) {
            mixed[i] = (1.0 - p.intensity) * core[i] + p.intensity * double(plane[i]);
            sum += mixed[i];
        }
        for (std::size_t i = 0; i < plane.size(); ++i) {
            plane[i] = float(mixed[i] / sum);
        }
    }
    return psf;
}

Psf psf_from_image(const Image &image, int max_radius, const std::string &who)
{
    const int cx = image.width() / 2, cy = image.height() / 2;
    const int radius = std::max({cx, image.width() - 1 - cx, cy, image.height() - 1 - cy, 0});
    if (radius > max_radius) {
        throw_usage(who,
                    ": the PSF image is ",
                    image.width(),
                    "x",
                    image.height(),
                    "; its radius (",
                    radius,
                    " px) exceeds ",
                    max_radius);
    }
    Psf psf;
    psf.radius = radius;
    const int size = psf.size();
    for (int c = 0; c < 3; ++c) {
        const int src = image.channels() >= 3 ? c : 0;
        std::vector<double> plane(std::size_t(size) * std::size_t(size), 0.0);
        double sum = 0.0;
        for (int y = 0; y < image.height(); ++y) {
            for (int x = 0; x < image.width(); ++x) {
                const float v = image.at(x, y, src);
                const double e = std::isfinite(v) && v > 0.0f ? double(v) : 0.0;
                plane[std::size_t((y - cy + radius) * size + (x - cx + radius))] = e;
                sum += e;
            }
        }
        if (!(sum > 0.0) || !std::isfinite(sum)) {
            throw_usage(who, ": the PSF image's channel ", c, " sums to ", sum, ", not > 0");
        }
        auto &out = psf.planes[std::size_t(c)];
        out.resize(plane.size());
        for (std::size_t i = 0; i < plane.size(); ++i) {
            out[i] = float(plane[i] / sum);
        }
    }
    return psf;
}

struct FftKernel::Impl {
    int width = 0, height = 0, radius = 0, pw = 0, ph = 0;
    std::array<ComplexBuffer, 3> spectra;
};

FftKernel::FftKernel(const Psf &psf, int width, int height) : impl_(std::make_unique<Impl>())
{
    Impl &k = *impl_;
    k.width = width;
    k.height = height;
    k.radius = psf.radius;
    const int r = psf.radius;
    k.pw = fft_size(width + 2 * r);
    k.ph = fft_size(height + 2 * r);
    const RealPlans &plans = real_plans(k.pw, k.ph);
    const std::size_t n = std::size_t(k.pw) * std::size_t(k.ph);
    const std::size_t nc = std::size_t(k.pw / 2 + 1) * std::size_t(k.ph);
    for (auto &s : k.spectra) {
        s = alloc_complex(nc);
    }
    parallel_for(0, 3, [&](int c) {
        RealBuffer real = alloc_real(n);
        // The kernel, wrapped so that its centre sits at (0, 0), and scaled by 1 / n for the
        // unnormalised inverse transform.
        std::fill(real.get(), real.get() + n, 0.0f);
        const int size = psf.size();
        const float scale = 1.0f / float(n);
        for (int dy = -r; dy <= r; ++dy) {
            for (int dx = -r; dx <= r; ++dx) {
                real[std::size_t(((dy + k.ph) % k.ph) * k.pw + (dx + k.pw) % k.pw)] =
                    psf.planes[std::size_t(c)][std::size_t((dy + r) * size + dx + r)] * scale;
            }
        }
        fftwf_execute_dft_r2c(plans.forward, real.get(), k.spectra[std::size_t(c)].get());
    });
}

FftKernel::~FftKernel() = default;

int FftKernel::width() const
{
    return impl_->width;
}

int FftKernel::height() const
{
    return impl_->height;
}

Image FftKernel::apply(const Image &in) const
{
    const Impl &k = *impl_;
    if (in.channels() < 3) {
        throw_runtime("bloom: the image has ", in.channels(), " channels; it needs 3 or more");
    }
    if (in.width() != k.width || in.height() != k.height) {
        throw_runtime("bloom: the image is ",
                      in.width(),
                      "x",
                      in.height(),
                      "; the kernel was prepared for ",
                      k.width,
                      "x",
                      k.height);
    }
    const int w = k.width, h = k.height, r = k.radius, pw = k.pw, ph = k.ph;
    const RealPlans &plans = real_plans(pw, ph);
    const std::size_t n = std::size_t(pw) * std::size_t(ph);
    const std::size_t nc = std::size_t(pw / 2 + 1) * std::size_t(ph);
    Image out = in;
    parallel_for(0, 3, [&](int c) {
        RealBuffer real = alloc_real(n);
        ComplexBuffer spectrum = alloc_complex(nc);
        // The image, extended by its edge pixels over the padding.
        for (int py = 0; py < ph; ++py) {
            const float *src = in.pixel(0, std::clamp(py - r, 0, h - 1)) + c;
            const int stride = in.channels();
            float *row = real.get() + std::size_t(py) * std::size_t(pw);
            const float left = finite_or_zero(src[0]);
            const float right = finite_or_zero(src[std::size_t(w - 1) * std::size_t(stride)]);
            for (int px = 0; px < r; ++px) {
                row[px] = left;
            }
            for (int x = 0; x < w; ++x) {
                row[r + x] = finite_or_zero(src[std::size_t(x) * std::size_t(stride)]);
            }
            for (int px = r + w; px < pw; ++px) {
                row[px] = right;
            }
        }
        fftwf_execute_dft_r2c(plans.forward, real.get(), spectrum.get());
        const fftwf_complex *kf = k.spectra[std::size_t(c)].get();
        for (std::size_t i = 0; i < nc; ++i) {
            const float a = spectrum[i][0], b = spectrum[i][1];
            spectrum[i][0] = a * kf[i][0] - b * kf[i][1];
            spectrum[i][1] = a * kf[i][1] + b * kf[i][0];
        }
        fftwf_execute_dft_c2r(plans.backward, spectrum.get(), real.get());
        for (int y = 0; y < h; ++y) {
            const float *row = real.get() + std::size_t(y + r) * std::size_t(pw) + std::size_t(r);
            for (int x = 0; x < w; ++x) {
                out.at(x, y, c) = row[x];
            }
        }
    });
    return out;
}

Image bloom_fft(const Image &in, const Psf &psf)
{
    return FftKernel(psf, in.width(), in.height()).apply(in);
}

PyramidFit fit_pyramid(const Psf &tail, int levels)
{
    const int r = tail.radius;
    if (levels <= 0) {
        levels = pyramid_levels(r);
    }
    const int n = levels + 1;
    // Every step of the chain is separable, so a level's response to an impulse is the outer
    // product k(x) k(y) of its response on a one-row image: fit with those.
    int canvas = 16;
    while (canvas < 2 * r + (8 << levels)) {
        canvas *= 2;
    }
    std::vector<double> gram(std::size_t(n) * std::size_t(n), 0.0), rhs(std::size_t(n), 0.0);
    double tail_energy = 0.0;
    // The chain is not shift-invariant: average the fit over impulses at two phases of the
    // coarsest grid.
    const int phases[2] = {0, (1 << levels) / 2 + 1};
    for (int phase : phases) {
        const int c0 = canvas / 2 + phase;
        // levels[0] is the impulse itself; only level i is non-zero when its response is taken.
        std::vector<Plane<1>> chain;
        chain.emplace_back(canvas, 1);
        chain[0].v[std::size_t(c0)] = 1.0f;
        for (int i = 1; i < n; ++i) {
            chain.push_back(downsample<1>(view_of(chain.back())));
        }
        std::vector<std::vector<double>> k(static_cast<std::size_t>(n));
        for (int i = 0; i < n; ++i) {
            Plane<1> up = chain[std::size_t(i)];
            for (int j = i - 1; j >= 0; --j) {
                Plane<1> finer(chain[std::size_t(j)].w, chain[std::size_t(j)].h);
                upsample_add(up, finer, 0.0f);
                up = std::move(finer);
            }
            k[std::size_t(i)].assign(up.v.begin(), up.v.end());
        }
        for (int a = 0; a < n; ++a) {
            for (int b = 0; b < n; ++b) {
                double s = 0.0;
                for (int x = 0; x < canvas; ++x) {
                    s += k[std::size_t(a)][std::size_t(x)] * k[std::size_t(b)][std::size_t(x)];
                }
                gram[std::size_t(a * n + b)] += s * s;
            }
            const std::vector<double> &ka = k[std::size_t(a)];
            double s = 0.0;
            for (int dy = -r; dy <= r; ++dy) {
                double row = 0.0;
                for (int dx = -r; dx <= r; ++dx) {
                    row += ka[std::size_t(c0 + dx)] * tail.at(0, dx, dy);
                }
                s += row * ka[std::size_t(c0 + dy)];
            }
            rhs[std::size_t(a)] += s;
        }
        for (float v : tail.planes[0]) {
            tail_energy += double(v) * v;
        }
    }
    std::vector<double> w = nonnegative_solve(gram, rhs);
    double total = 0.0;
    for (double v : w) {
        total += v;
    }
    PyramidFit fit;
    fit.weights.resize(std::size_t(n));
    for (int i = 0; i < n; ++i) {
        fit.weights[std::size_t(i)] = float(total > 0.0 ? w[std::size_t(i)] / total : i == 0);
    }
    // Residual of the normalised mix: |G w|^2 - 2 b.w + |t|^2 over both phases.
    double quad = 0.0, lin = 0.0;
    for (int a = 0; a < n; ++a) {
        lin += double(fit.weights[std::size_t(a)]) * rhs[std::size_t(a)];
        for (int b = 0; b < n; ++b) {
            quad += double(fit.weights[std::size_t(a)]) * fit.weights[std::size_t(b)] *
                    gram[std::size_t(a * n + b)];
        }
    }
    fit.residual = std::sqrt(std::max(0.0, quad - 2.0 * lin + tail_energy) / tail_energy);
    return fit;
}

Image bloom_pyramid(const Image &in, const PyramidFit &fit, double intensity)
{
    const int nc = in.channels();
    if (nc < 3) {
        throw_runtime("bloom: the image has ", nc, " channels; it needs 3 or more");
    }
    const int w = in.width(), h = in.height();
    const int n = int(fit.weights.size());
    std::vector<float> weights = fit.weights;
    for (float &v : weights) {
        v *= float(intensity);
    }
    const float w0 = weights[0] + float(1.0 - intensity);
    // Level 0 is the image itself, read in place; levels 1.. hold RGB.
    std::vector<Plane<3>> levels(1);
    for (int i = 1; i < n; ++i) {
        levels.push_back(
            downsample<3>(i == 1 ? View{in.data(), w, h, nc} : view_of(levels.back())));
    }
    Image out = Image::uninitialized(w, h, nc);
    if (n == 1) {
        for (std::size_t i = 0; i < in.value_count(); ++i) {
            out.data()[i] = (i % std::size_t(nc)) < 3 ? w0 * in.data()[i] : in.data()[i];
        }
        return out;
    }
    const Plane<3> acc = mix_coarse(levels, weights);
    // The last step writes the image: out = w0 in + up(acc), the other channels copied.
    Plane<3> tmp(w, acc.h);
    for_rows(acc.h, [&](int y) { upsample_row<3>(acc.row(y), acc.w, tmp.row(y), w); });
    for_rows(h, [&](int y) {
        const int j = y >> 1, k = (y & 1) ? j + 1 : j - 1;
        const float *a = tmp.row(std::clamp(j, 0, acc.h - 1));
        const float *b = tmp.row(std::clamp(k, 0, acc.h - 1));
        const float *s = in.pixel(0, y);
        float *d = out.pixel(0, y);
        if (nc == 4) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < 3; ++c) {
                    d[4 * x + c] = w0 * s[4 * x + c] + 0.75f * a[3 * x + c] + 0.25f * b[3 * x + c];
                }
                d[4 * x + 3] = s[4 * x + 3];
            }
            return;
        }
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < nc; ++c) {
                const std::size_t i = std::size_t(x) * std::size_t(nc) + std::size_t(c);
                d[i] = c < 3 ? w0 * s[i] + 0.75f * a[3 * x + c] + 0.25f * b[3 * x + c] : s[i];
            }
        }
    });
    return out;
}

}  // namespace posthaste::filter
