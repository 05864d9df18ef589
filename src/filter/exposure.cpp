// Exposure: photographic scale, metering and adaptation (see exposure.h).

#include "filter/exposure.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>

#include "core/parallel.h"

namespace posthaste::filter {
namespace {

constexpr int kBins = 1024;

struct Histogram {
    std::array<std::uint64_t, kBins> count{};
    std::array<double, kBins> sum{};
};

}  // namespace

double ev100(double fstop, double shutter_seconds, double iso)
{
    return std::log2(fstop * fstop / shutter_seconds * 100.0 / iso);
}

double photographic_scale(double ev)
{
    return 1.0 / (1.2 * std::exp2(ev));
}

double meter_log2_luminance(const Image &image, const MeterParams &p)
{
    if (image.channels() < 3 || image.empty()) {
        return p.min_ev;
    }
    const int step = std::max(1, p.step);
    const int rows = (image.height() + step - 1) / step;
    const double lo = p.min_ev, hi = std::max(p.max_ev, p.min_ev + 1e-6);
    const double bins_per_ev = kBins / (hi - lo);
    // Row blocks in fixed order, merged in order: the sums do not depend on the thread count.
    constexpr int kBlock = 16;
    const int blocks = (rows + kBlock - 1) / kBlock;
    std::vector<Histogram> partial(std::size_t(std::max(blocks, 0)));
    parallel_for(0, blocks, [&](int b) {
        Histogram &h = partial[std::size_t(b)];
        for (int r = b * kBlock; r < std::min(rows, (b + 1) * kBlock); ++r) {
            const int y = r * step + step / 2 < image.height() ? r * step + step / 2 : r * step;
            for (int x = std::min(step / 2, image.width() - 1); x < image.width(); x += step) {
                const float *px = image.pixel(x, y);
                const float lum = 0.2126f * px[0] + 0.7152f * px[1] + 0.0722f * px[2];
                if (!std::isfinite(lum)) {
                    continue;
                }
                const double ev = lum > 0.0f ? std::clamp(double(std::log2(lum)), lo, hi) : lo;
                const int bin = std::clamp(int((ev - lo) * bins_per_ev), 0, kBins - 1);
                ++h.count[std::size_t(bin)];
                h.sum[std::size_t(bin)] += ev;
            }
        }
    });
    Histogram total;
    for (const Histogram &h : partial) {
        for (int i = 0; i < kBins; ++i) {
            total.count[std::size_t(i)] += h.count[std::size_t(i)];
            total.sum[std::size_t(i)] += h.sum[std::size_t(i)];
        }
    }
    std::uint64_t n = 0;
    for (std::uint64_t c : total.count) {
        n += c;
    }
    if (n == 0) {
        return p.min_ev;
    }
    // The window [a, b) of ranks; each bin contributes the part of its samples inside it.
    const double a = std::clamp(p.low_percentile, 0.0, 100.0) / 100.0 * double(n);
    const double b =
        std::max(a + 1.0, std::clamp(p.high_percentile, 0.0, 100.0) / 100.0 * double(n));
    double below = 0.0, weight = 0.0, sum = 0.0;
    for (int i = 0; i < kBins; ++i) {
        const double c = double(total.count[std::size_t(i)]);
        if (c == 0.0) {
            continue;
        }
        const double inside = std::max(0.0, std::min(below + c, b) - std::max(below, a));
        if (inside > 0.0) {
            weight += inside;
            sum += inside * (total.sum[std::size_t(i)] / c);
        }
        below += c;
    }
    return weight > 0.0 ? sum / weight : p.min_ev;
}

double adapt_ev(const std::vector<MeterSample> &samples,
                double fps,
                double speed_up,
                double speed_down)
{
    if (samples.empty()) {
        return 0.0;
    }
    double ev = samples.front().second;
    for (std::size_t i = 1; i < samples.size(); ++i) {
        const double target = samples[i].second;
        const double speed = target > ev ? speed_up : speed_down;
        if (!(speed > 0.0) || !std::isfinite(speed)) {
            ev = target;
            continue;
        }
        const double dt = double(samples[i].first - samples[i - 1].first) / fps;
        ev += (target - ev) * (1.0 - std::exp(-speed * dt));
    }
    return ev;
}

Image scale_rgb(const Image &in, float scale)
{
    Image out = Image::uninitialized(in.width(), in.height(), in.channels());
    const int nc = in.channels(), w = in.width();
    parallel_for(0, (in.height() + 15) / 16, [&](int b) {
        for (int y = b * 16; y < std::min(in.height(), (b + 1) * 16); ++y) {
            const float *s = in.pixel(0, y);
            float *d = out.pixel(0, y);
            if (nc == 4) {
                for (int x = 0; x < w; ++x) {
                    d[4 * x] = s[4 * x] * scale;
                    d[4 * x + 1] = s[4 * x + 1] * scale;
                    d[4 * x + 2] = s[4 * x + 2] * scale;
                    d[4 * x + 3] = s[4 * x + 3];
                }
                continue;
            }
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < nc; ++c) {
                    const std::size_t i = std::size_t(x) * std::size_t(nc) + std::size_t(c);
                    d[i] = c < 3 ? s[i] * scale : s[i];
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::filter
