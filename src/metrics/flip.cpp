#include "metrics/flip.h"

#include <algorithm>
#include <cmath>
#include <glm/mat3x3.hpp>
#include <numbers>

#include "core/error.h"
#include "core/parallel.h"

namespace posthaste::metrics {
namespace flip {
namespace {

constexpr float kPi = std::numbers::pi_v<float>;

// Linear Rec.709 / sRGB primaries to CIE XYZ, D65 (exact rationals of the sRGB definition).
// glm is column-major: the constructor takes the matrix column by column.
const glm::mat3 kRgbToXyz(10135552.0f / 24577794.0f,
                          2613072.0f / 12288897.0f,
                          1425312.0f / 73733382.0f,
                          8788810.0f / 24577794.0f,
                          8788810.0f / 12288897.0f,
                          8788810.0f / 73733382.0f,
                          4435075.0f / 24577794.0f,
                          887015.0f / 12288897.0f,
                          70074185.0f / 73733382.0f);
const glm::mat3 kXyzToRgb = glm::inverse(kRgbToXyz);
// The reference white is RGB (1, 1, 1): D65 with Y = 1.
const glm::vec3 kWhite = kRgbToXyz * glm::vec3(1.0f);

}  // namespace

glm::vec3 linear_rgb_to_xyz(glm::vec3 rgb)
{
    return kRgbToXyz * rgb;
}

glm::vec3 xyz_to_linear_rgb(glm::vec3 xyz)
{
    return kXyzToRgb * xyz;
}

glm::vec3 xyz_to_ycxcz(glm::vec3 xyz)
{
    const glm::vec3 n = xyz / kWhite;
    return {116.0f * n.y - 16.0f, 500.0f * (n.x - n.y), 200.0f * (n.y - n.z)};
}

glm::vec3 ycxcz_to_xyz(glm::vec3 ycxcz)
{
    const float y = (ycxcz.x + 16.0f) / 116.0f;
    return glm::vec3(y + ycxcz.y / 500.0f, y, y - ycxcz.z / 200.0f) * kWhite;
}

glm::vec3 xyz_to_lab(glm::vec3 xyz)
{
    constexpr float delta = 6.0f / 29.0f;
    constexpr float delta3 = delta * delta * delta;
    const glm::vec3 n = xyz / kWhite;
    auto f = [&](float t) {
        return t > delta3 ? std::cbrt(t) : t / (3.0f * delta * delta) + 4.0f / 29.0f;
    };
    const glm::vec3 fn(f(n.x), f(n.y), f(n.z));
    return {116.0f * fn.y - 16.0f, 500.0f * (fn.x - fn.y), 200.0f * (fn.y - fn.z)};
}

glm::vec3 hunt_adjust(glm::vec3 lab)
{
    return {lab.x, 0.01f * lab.x * lab.y, 0.01f * lab.x * lab.z};
}

float hyab(glm::vec3 a, glm::vec3 b)
{
    const glm::vec3 d = a - b;
    return std::abs(d.x) + std::sqrt(d.y * d.y + d.z * d.z);
}

float max_color_distance()
{
    const glm::vec3 green = hunt_adjust(xyz_to_lab(linear_rgb_to_xyz({0.0f, 1.0f, 0.0f})));
    const glm::vec3 blue = hunt_adjust(xyz_to_lab(linear_rgb_to_xyz({0.0f, 0.0f, 1.0f})));
    return std::pow(hyab(green, blue), kQc);
}

float remap_color_difference(float power_hyab, float cmax)
{
    const float knee = kPc * cmax;
    if (power_hyab < knee) {
        return power_hyab * (kPt / knee);
    }
    return kPt + (power_hyab - knee) / (cmax - knee) * (1.0f - kPt);
}

float CsfKernel::at(int dx, int dy) const
{
    float v = 0.0f;
    for (std::size_t t = 0; t < weight.size(); ++t) {
        v += weight[t] * g[t][std::size_t(dx + radius)] * g[t][std::size_t(dy + radius)];
    }
    return v;
}

CsfKernel csf_kernel(int channel, float ppd)
{
    // (a1, b1, a2, b2) of the CSF Gaussians per channel, HPG 2020 Table 1 (a2 = 0: one term).
    struct Params {
        float a1, b1, a2, b2;
    };
    constexpr Params kParams[3] = {
        {1.0f, 0.0047f, 0.0f, 1e-5f},
        {1.0f, 0.0053f, 0.0f, 1e-5f},
        {34.1f, 0.04f, 13.5f, 0.025f},
    };
    if (channel < 0 || channel > 2) {
        throw_runtime("csf_kernel: channel ", channel, " is not 0, 1 or 2");
    }
    constexpr float b_max = 0.04f;
    CsfKernel k;
    k.radius = int(std::ceil(3.0f * std::sqrt(b_max / (2.0f * kPi * kPi)) * ppd));
    const Params &p = kParams[channel];
    const float terms[2][2] = {{p.a1, p.b1}, {p.a2, p.b2}};
    double total = 0.0;
    for (const auto &[a, b] : terms) {
        if (a == 0.0f) {
            continue;
        }
        std::vector<float> g(std::size_t(2 * k.radius + 1));
        double sum = 0.0;
        for (int i = -k.radius; i <= k.radius; ++i) {
            const float x_deg = float(i) / ppd;
            g[std::size_t(i + k.radius)] = std::exp(-kPi * kPi * x_deg * x_deg / b);
            sum += g[std::size_t(i + k.radius)];
        }
        // The continuous CSF is a * sqrt(pi / b) * exp(-pi^2 x^2 / b) in each dimension.
        const float w = a * std::sqrt(kPi / b);
        total += double(w) * sum * sum;
        k.weight.push_back(w);
        k.g.push_back(std::move(g));
    }
    for (float &w : k.weight) {
        w = float(double(w) / total);
    }
    return k;
}

FeatureKernels feature_kernels(float ppd)
{
    const float sd = 0.5f * kW * ppd;
    FeatureKernels k;
    k.radius = int(std::ceil(3.0f * sd));
    const std::size_t n = std::size_t(2 * k.radius + 1);
    k.g.resize(n);
    k.d1.resize(n);
    k.d2.resize(n);
    double g_sum = 0.0, d1_pos = 0.0, d1_neg = 0.0, d2_pos = 0.0, d2_neg = 0.0;
    for (int i = -k.radius; i <= k.radius; ++i) {
        const float x = float(i);
        const float g = std::exp(-(x * x) / (2.0f * sd * sd));
        const std::size_t j = std::size_t(i + k.radius);
        k.g[j] = g;
        k.d1[j] = -x * g;
        k.d2[j] = (x * x / (sd * sd) - 1.0f) * g;
        g_sum += g;
        (k.d1[j] > 0.0f ? d1_pos : d1_neg) += k.d1[j];
        (k.d2[j] > 0.0f ? d2_pos : d2_neg) += k.d2[j];
    }
    for (std::size_t j = 0; j < n; ++j) {
        k.g[j] = float(k.g[j] / g_sum);
        k.d1[j] = float(k.d1[j] / (k.d1[j] > 0.0f ? d1_pos : -d1_neg));
        k.d2[j] = float(k.d2[j] / (k.d2[j] > 0.0f ? d2_pos : -d2_neg));
    }
    return k;
}

namespace {
// ACES fit y = (k0 x^2 + k1 x) / (k3 x^2 + k4 x + k5), 0.6 pre-exposure folded in.
constexpr float kAces[5] = {
    0.6f * 0.6f * 2.51f, 0.6f * 0.03f, 0.6f * 0.6f * 2.43f, 0.6f * 0.59f, 0.14f};
}  // namespace

float tone_map_aces(float x)
{
    const float y =
        (kAces[0] * x * x + kAces[1] * x) / (kAces[2] * x * x + kAces[3] * x + kAces[4]);
    return std::clamp(y, 0.0f, 1.0f);
}

float tone_target_input()
{
    // Solve (k0 - t k3) x^2 + (k1 - t k4) x - t k5 = 0 for its positive root.
    const float t = kToneTarget;
    const double a = kAces[0] - t * kAces[2], b = kAces[1] - t * kAces[3], c = -t * kAces[4];
    return float((-b + std::sqrt(b * b - 4.0 * a * c)) / (2.0 * a));
}

}  // namespace flip

namespace {

using Plane = std::vector<float>;

struct Planes {
    int width = 0, height = 0;
    Plane c[3];
};

/// Clamp-to-edge 1D convolution along rows. Interior pixels accumulate tap by tap over the
/// row (a loop the compiler vectorises); the r pixels at each end clamp their reads.
void convolve_rows(const Plane &in, Plane &out, int w, int h, const std::vector<float> &k)
{
    const int r = int(k.size() / 2);
    out.resize(in.size());
    parallel_for(0, h, [&](int y) {
        const float *src = in.data() + std::size_t(y) * std::size_t(w);
        float *dst = out.data() + std::size_t(y) * std::size_t(w);
        const int x0 = std::min(r, w), x1 = std::max(w - r, x0);
        std::fill(dst + x0, dst + x1, 0.0f);
        for (int i = 0; i <= 2 * r; ++i) {
            const float wk = k[std::size_t(i)];
            const float *s = src + (i - r);
            for (int x = x0; x < x1; ++x) {
                dst[x] += wk * s[x];
            }
        }
        auto edge = [&](int x) {
            float sum = 0.0f;
            for (int i = 0; i <= 2 * r; ++i) {
                sum += k[std::size_t(i)] * src[std::clamp(x + i - r, 0, w - 1)];
            }
            dst[x] = sum;
        };
        for (int x = 0; x < x0; ++x) {
            edge(x);
        }
        for (int x = x1; x < w; ++x) {
            edge(x);
        }
    });
}

/// Clamp-to-edge 1D convolution along columns.
void convolve_cols(const Plane &in, Plane &out, int w, int h, const std::vector<float> &k)
{
    const int r = int(k.size() / 2);
    out.assign(in.size(), 0.0f);
    parallel_for(0, h, [&](int y) {
        float *dst = out.data() + std::size_t(y) * std::size_t(w);
        for (int i = 0; i <= 2 * r; ++i) {
            const int yy = std::clamp(y + i - r, 0, h - 1);
            const float *src = in.data() + std::size_t(yy) * std::size_t(w);
            const float wk = k[std::size_t(i)];
            for (int x = 0; x < w; ++x) {
                dst[x] += wk * src[x];
            }
        }
    });
}

/// One image after both pipelines: Hunt-adjusted L*a*b* of the CSF-filtered colors, and the
/// edge and point detector magnitudes.
struct Prepared {
    Planes lab;
    Plane edge, point;
};

void check_ppd(float ppd)
{
    if (!(ppd > 0.0f && ppd <= kMaxPixelsPerDegree)) {
        throw_usage(
            "flip: pixels per degree must lie in (0, ", kMaxPixelsPerDegree, "], got ", ppd);
    }
}

struct Kernels {
    flip::CsfKernel csf[3];
    flip::FeatureKernels feature;
    float cmax = 0.0f;

    explicit Kernels(float ppd)
        : csf{(check_ppd(ppd), flip::csf_kernel(0, ppd)),
              flip::csf_kernel(1, ppd),
              flip::csf_kernel(2, ppd)},
          feature(flip::feature_kernels(ppd)),
          cmax(flip::max_color_distance())
    {
    }
};

Prepared prepare(const Planes &ycxcz, const Kernels &k)
{
    const int w = ycxcz.width, h = ycxcz.height;
    const std::size_t n = std::size_t(w) * std::size_t(h);
    Prepared out;
    out.lab.width = w;
    out.lab.height = h;

    // Color: CSF filtering per opponent channel, then to Hunt-adjusted L*a*b*.
    Planes filtered;
    Plane tmp, term;
    for (int c = 0; c < 3; ++c) {
        const flip::CsfKernel &csf = k.csf[c];
        filtered.c[c].assign(n, 0.0f);
        for (std::size_t t = 0; t < csf.weight.size(); ++t) {
            convolve_rows(ycxcz.c[c], tmp, w, h, csf.g[t]);
            convolve_cols(tmp, term, w, h, csf.g[t]);
            const float wt = csf.weight[t];
            for (std::size_t i = 0; i < n; ++i) {
                filtered.c[c][i] += wt * term[i];
            }
        }
    }
    for (auto &p : out.lab.c) {
        p.resize(n);
    }
    parallel_for(0, h, [&](int y) {
        for (std::size_t i = std::size_t(y) * std::size_t(w), e = i + std::size_t(w); i < e; ++i) {
            const glm::vec3 o(filtered.c[0][i], filtered.c[1][i], filtered.c[2][i]);
            const glm::vec3 rgb = glm::clamp(
                flip::xyz_to_linear_rgb(flip::ycxcz_to_xyz(o)), glm::vec3(0.0f), glm::vec3(1.0f));
            const glm::vec3 lab = flip::hunt_adjust(flip::xyz_to_lab(flip::linear_rgb_to_xyz(rgb)));
            out.lab.c[0][i] = lab.x;
            out.lab.c[1][i] = lab.y;
            out.lab.c[2][i] = lab.z;
        }
    });

    // Features: edges and points of the normalised achromatic channel (Yy + 16) / 116.
    Plane gray(n);
    for (std::size_t i = 0; i < n; ++i) {
        gray[i] = (ycxcz.c[0][i] + 16.0f) / 116.0f;
    }
    const flip::FeatureKernels &f = k.feature;
    Plane rows_g, rows_d1, rows_d2, ex, ey;
    convolve_rows(gray, rows_g, w, h, f.g);
    convolve_rows(gray, rows_d1, w, h, f.d1);
    convolve_rows(gray, rows_d2, w, h, f.d2);
    out.edge.resize(n);
    out.point.resize(n);
    convolve_cols(rows_d1, ex, w, h, f.g);
    convolve_cols(rows_g, ey, w, h, f.d1);
    for (std::size_t i = 0; i < n; ++i) {
        out.edge[i] = std::sqrt(ex[i] * ex[i] + ey[i] * ey[i]);
    }
    convolve_cols(rows_d2, ex, w, h, f.g);
    convolve_cols(rows_g, ey, w, h, f.d2);
    for (std::size_t i = 0; i < n; ++i) {
        out.point[i] = std::sqrt(ex[i] * ex[i] + ey[i] * ey[i]);
    }
    return out;
}

/// Per-pixel LDR-FLIP of two prepared images into `error` (w * h floats).
void combine(const Prepared &ref, const Prepared &test, float cmax, Plane &error)
{
    const int w = ref.lab.width, h = ref.lab.height;
    error.resize(std::size_t(w) * std::size_t(h));
    const float inv_sqrt2 = 1.0f / std::sqrt(2.0f);
    parallel_for(0, h, [&](int y) {
        for (std::size_t i = std::size_t(y) * std::size_t(w), e = i + std::size_t(w); i < e; ++i) {
            const glm::vec3 a(ref.lab.c[0][i], ref.lab.c[1][i], ref.lab.c[2][i]);
            const glm::vec3 b(test.lab.c[0][i], test.lab.c[1][i], test.lab.c[2][i]);
            const float color =
                flip::remap_color_difference(std::pow(flip::hyab(a, b), flip::kQc), cmax);
            const float feature_raw = std::max(std::abs(ref.edge[i] - test.edge[i]),
                                               std::abs(ref.point[i] - test.point[i]));
            const float feature = std::pow(feature_raw * inv_sqrt2, flip::kQf);
            error[i] = std::pow(color, 1.0f - feature);
        }
    });
}

void check_inputs(const Image &reference, const Image &test, const char *who)
{
    if (reference.width() != test.width() || reference.height() != test.height()) {
        throw_runtime(who,
                      ": images differ in size: ",
                      reference.width(),
                      "x",
                      reference.height(),
                      " vs ",
                      test.width(),
                      "x",
                      test.height());
    }
    if (reference.channels() < 3 || test.channels() < 3) {
        throw_runtime(who,
                      ": expected RGB images (>= 3 channels), got ",
                      reference.channels(),
                      " and ",
                      test.channels(),
                      " channels");
    }
}

float sanitize(float v, float hi)
{
    return std::isnan(v) ? 0.0f : std::clamp(v, 0.0f, hi);
}

/// YyCxCz planes of an image: sRGB-decoded (scale <= 0) or exposed by `scale` and tone mapped.
Planes to_ycxcz(const Image &img, bool srgb, float scale)
{
    Planes out;
    out.width = img.width();
    out.height = img.height();
    const std::size_t n = img.pixel_count();
    for (auto &p : out.c) {
        p.resize(n);
    }
    parallel_for(0, img.height(), [&](int y) {
        for (int x = 0; x < img.width(); ++x) {
            const float *p = img.pixel(x, y);
            glm::vec3 rgb;
            for (int c = 0; c < 3; ++c) {
                rgb[c] = srgb ? flip::srgb_to_linear(sanitize(p[c], 1.0f))
                              : flip::tone_map_aces(scale * sanitize(p[c], 65536.0f));
            }
            const glm::vec3 o = flip::xyz_to_ycxcz(flip::linear_rgb_to_xyz(rgb));
            const std::size_t i = std::size_t(y) * std::size_t(img.width()) + std::size_t(x);
            out.c[0][i] = o.x;
            out.c[1][i] = o.y;
            out.c[2][i] = o.z;
        }
    });
    return out;
}

void finish(FlipResult &r, const Plane &error, int w, int h)
{
    r.error_map = Image::uninitialized(w, h, 1);
    std::copy(error.begin(), error.end(), r.error_map.data());
    std::vector<double> row_sums(std::size_t(h), 0.0);
    parallel_for(0, h, [&](int y) {
        double s = 0.0;
        for (int x = 0; x < w; ++x) {
            s += error[std::size_t(y) * std::size_t(w) + std::size_t(x)];
        }
        row_sums[std::size_t(y)] = s;
    });
    double total = 0.0;
    for (double s : row_sums) {
        total += s;
    }
    r.mean = error.empty() ? 0.0 : total / double(error.size());
    r.max = 0.0f;
    for (std::size_t i = 0; i < error.size(); ++i) {
        if (error[i] > r.max) {
            r.max = error[i];
            r.max_x = int(i % std::size_t(w));
            r.max_y = int(i / std::size_t(w));
        }
    }
}

}  // namespace

FlipResult flip_ldr(const Image &reference, const Image &test, const FlipOptions &options)
{
    check_inputs(reference, test, "flip");
    const Kernels k(options.pixels_per_degree);
    Plane error;
    combine(prepare(to_ycxcz(reference, true, 0.0f), k),
            prepare(to_ycxcz(test, true, 0.0f), k),
            k.cmax,
            error);
    FlipResult r;
    finish(r, error, reference.width(), reference.height());
    return r;
}

FlipResult flip_hdr(const Image &reference, const Image &test, const FlipOptions &options)
{
    check_inputs(reference, test, "hdr-flip");
    const int w = reference.width(), h = reference.height();
    FlipResult r;
    if (reference.empty()) {
        r.error_map = Image(w, h, 1);
        return r;
    }

    // Exposure range from the reference's luminance: the brightest pixel and the median reach
    // the tone mapper's 0.85 at the start and stop exposures.
    std::vector<float> lum(reference.pixel_count());
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float *p = reference.pixel(x, y);
            lum[std::size_t(y) * std::size_t(w) + std::size_t(x)] =
                0.2126f * sanitize(p[0], 65536.0f) + 0.7152f * sanitize(p[1], 65536.0f) +
                0.0722f * sanitize(p[2], 65536.0f);
        }
    }
    const float y_max = *std::max_element(lum.begin(), lum.end());
    const auto mid = lum.begin() + std::ptrdiff_t((lum.size() - 1) / 2);  // lower median
    std::nth_element(lum.begin(), mid, lum.end());
    float y_median = *mid;
    if (y_median <= 0.0f) {
        // Departure from the papers (log2 of infinity there): a mostly black reference uses
        // its smallest positive luminance instead.
        float smallest = y_max;
        for (float v : lum) {
            if (v > 0.0f) {
                smallest = std::min(smallest, v);
            }
        }
        y_median = smallest;
    }
    const float x_target = flip::tone_target_input();
    float start = 0.0f, stop = 0.0f;
    if (y_max > 0.0f) {  // an all-black reference keeps exposure 0
        start = std::log2(x_target / y_max);
        stop = std::log2(x_target / y_median);
    }
    r.start_exposure = options.start_exposure.value_or(start);
    r.stop_exposure = options.stop_exposure.value_or(stop);
    if (r.stop_exposure < r.start_exposure) {
        throw_runtime("hdr-flip: stop exposure ",
                      r.stop_exposure,
                      " is below start exposure ",
                      r.start_exposure);
    }
    r.num_exposures = options.num_exposures > 0
                          ? options.num_exposures
                          : std::max(2, int(std::ceil(r.stop_exposure - r.start_exposure)));
    const float step =
        (r.stop_exposure - r.start_exposure) / float(std::max(r.num_exposures - 1, 1));

    const Kernels k(options.pixels_per_degree);
    Plane error, max_error(reference.pixel_count(), 0.0f);
    for (int e = 0; e < r.num_exposures; ++e) {
        const float scale = std::exp2(r.start_exposure + float(e) * step);
        combine(prepare(to_ycxcz(reference, false, scale), k),
                prepare(to_ycxcz(test, false, scale), k),
                k.cmax,
                error);
        for (std::size_t i = 0; i < error.size(); ++i) {
            max_error[i] = std::max(max_error[i], error[i]);
        }
    }
    finish(r, max_error, w, h);
    return r;
}

glm::vec3 flip_color_map(float t)
{
    // Eight control points chosen by eye to run like magma: black through purple, magenta and
    // orange to pale yellow, with luminance rising monotonically (sRGB-encoded).
    struct Stop {
        float t;
        glm::vec3 rgb;
    };
    static const Stop kStops[] = {
        {0.0f / 7.0f, {0.00f, 0.00f, 0.02f}},
        {1.0f / 7.0f, {0.11f, 0.07f, 0.28f}},
        {2.0f / 7.0f, {0.31f, 0.07f, 0.48f}},
        {3.0f / 7.0f, {0.51f, 0.13f, 0.51f}},
        {4.0f / 7.0f, {0.72f, 0.21f, 0.47f}},
        {5.0f / 7.0f, {0.92f, 0.33f, 0.38f}},
        {6.0f / 7.0f, {0.99f, 0.60f, 0.42f}},
        {7.0f / 7.0f, {0.99f, 0.99f, 0.75f}},
    };
    constexpr int kCount = int(std::size(kStops));
    if (std::isnan(t)) {
        t = 1.0f;
    }
    t = std::clamp(t, 0.0f, 1.0f);
    const float s = t * float(kCount - 1);
    const int i = std::min(int(s), kCount - 2);
    const float f = s - float(i);
    return kStops[i].rgb + f * (kStops[i + 1].rgb - kStops[i].rgb);
}

Image flip_heatmap(const Image &error_map, bool linear)
{
    Image out = Image::uninitialized(error_map.width(), error_map.height(), 3);
    parallel_for_tiles(out.bounds(), [&](const Rect &r) {
        for (int y = r.y0; y < r.y1; ++y) {
            for (int x = r.x0; x < r.x1; ++x) {
                const glm::vec3 c = flip_color_map(error_map.at(x, y, 0));
                float *p = out.pixel(x, y);
                for (int i = 0; i < 3; ++i) {
                    p[i] = linear ? flip::srgb_to_linear(c[i]) : c[i];
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::metrics
