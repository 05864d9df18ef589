// Bloom's point-spread functions (the built-in diffraction pattern and tail, one read from an
// image) and the FFT convolution (see bloom.h); the pyramid is bloom_pyramid.cpp.

#include "filter/bloom.h"

#include <fftw3.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <mutex>
#include <numbers>

#include "core/error.h"
#include "core/parallel.h"
#include "core/sanitize.h"

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

}  // namespace posthaste::filter
