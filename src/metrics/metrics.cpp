#include "metrics/metrics.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "core/error.h"
#include "core/parallel.h"

namespace posthaste::metrics {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// Two values that match whatever the thresholds: equal, or both NaN (two NaNs, or two equal
/// infinities, are no error; the statistics and the difference image share the rule).
inline bool same_value(float a, float b)
{
    return a == b || (std::isnan(a) && std::isnan(b));
}

/// Running state of one comparison, updated value by value as ImageBufAlgo::compare does it,
/// except for non-finite values: two NaNs, or two equal infinities, are equal; a NaN or an
/// infinity against anything else is an error of +inf that fails and warns and makes the mean
/// and RMS +inf (idiff lets all but the first such value through uncounted: a frame of NaNs
/// passed).
struct Accumulator {
    double sum = 0.0;
    double sum2 = 0.0;
    double max_error = 0.0;
    int max_x = 0, max_y = 0, max_c = 0;
    float peak = 1.0f;
    std::uint64_t warn_count = 0, fail_count = 0;

    void add(float a, float b, int x, int y, int c, const Thresholds &t, bool &warned, bool &failed)
    {
        if (!std::isfinite(a) || !std::isfinite(b)) {
            if (same_value(a, b)) {
                return;
            }
            // Mean and RMS become +inf too: a result with NaNs never looks better than one with
            // a large finite error. The first in scan order is the max.
            sum += kInf;
            sum2 += kInf;
            if (!(max_error >= kInf)) {
                set_max(kInf, x, y, c);
            }
            if (!warned) {
                ++warn_count;
                warned = true;
            }
            if (!failed) {
                ++fail_count;
                failed = true;
            }
            return;
        }
        const float aabs = std::abs(a), babs = std::abs(b);
        // OIIO's lerp(aabs, babs, 0.5) evaluates in double and returns float.
        const float meanabs = float(double(aabs) * 0.5 + double(babs) * 0.5);
        peak = std::max(peak, std::max(aabs, babs));
        const double f = std::abs(a - b);  // float subtraction, like idiff
        const double rel = meanabs > 0.0f ? f / meanabs : 0.0;
        sum += f;
        sum2 += f * f;
        // "!(f <= x)" so that a NaN error counts as over every threshold.
        if (!(f <= max_error)) {
            set_max(f, x, y, c);
        }
        if (!warned && !(f <= t.warn) && !(rel <= t.warn_relative)) {
            ++warn_count;
            warned = true;
        }
        if (!failed && !(f <= t.fail) && !(rel <= t.fail_relative)) {
            ++fail_count;
            failed = true;
        }
    }

    void set_max(double f, int x, int y, int c)
    {
        max_error = f;
        max_x = x;
        max_y = y;
        max_c = c;
    }

    /// Fold in the accumulator of a later tile: the max is the largest error, the earliest in
    /// scan order on ties.
    void merge(const Accumulator &o)
    {
        sum += o.sum;
        sum2 += o.sum2;
        peak = std::max(peak, o.peak);
        warn_count += o.warn_count;
        fail_count += o.fail_count;
        const bool earlier = std::tie(o.max_y, o.max_x, o.max_c) < std::tie(max_y, max_x, max_c);
        if (o.max_error > max_error || (o.max_error == max_error && o.max_error > 0.0 && earlier)) {
            set_max(o.max_error, o.max_x, o.max_y, o.max_c);
        }
    }

    ErrorStats finish(std::uint64_t value_count) const
    {
        ErrorStats s;
        if (value_count > 0) {
            s.mean_error = sum / double(value_count);
            s.rms_error = std::sqrt(sum2 / double(value_count));
            s.psnr = 20.0 * std::log10(double(peak) / s.rms_error);
        }
        s.max_error = max_error;
        s.max_x = max_x;
        s.max_y = max_y;
        s.max_channel = max_c;
        s.peak = peak;
        s.warn_count = warn_count;
        s.fail_count = fail_count;
        return s;
    }
};

/// Accumulators for all channels together (index 0) and for each channel (1 + c).
struct RegionResult {
    std::vector<Accumulator> acc;
};

RegionResult compare_region(const Image &a, const Image &b, const Rect &r, const Thresholds &t)
{
    const int nc = a.channels();
    RegionResult res;
    res.acc.resize(std::size_t(nc) + 1);
    bool channel_warned[kMaxChannels], channel_failed[kMaxChannels];
    for (int y = r.y0; y < r.y1; ++y) {
        for (int x = r.x0; x < r.x1; ++x) {
            const float *pa = a.pixel(x, y);
            const float *pb = b.pixel(x, y);
            bool warned = false, failed = false;
            for (int c = 0; c < nc; ++c) {
                res.acc[0].add(pa[c], pb[c], x, y, c, t, warned, failed);
                channel_warned[c] = channel_failed[c] = false;
                res.acc[std::size_t(c) + 1].add(
                    pa[c], pb[c], x, y, c, t, channel_warned[c], channel_failed[c]);
            }
        }
    }
    return res;
}

}  // namespace

double CompareStats::warn_percent() const
{
    return pixel_count ? 100.0 * double(all.warn_count) / double(pixel_count) : 0.0;
}

double CompareStats::fail_percent() const
{
    return pixel_count ? 100.0 * double(all.fail_count) / double(pixel_count) : 0.0;
}

namespace {

/// Throws an Error naming `who` when a and b differ in width, height or channel count.
void require_same_shape(const Image &a, const Image &b, const char *who)
{
    if (a.width() != b.width() || a.height() != b.height() || a.channels() != b.channels()) {
        throw_runtime(who,
                      ": images differ in shape: ",
                      a.width(),
                      "x",
                      a.height(),
                      "x",
                      a.channels(),
                      " vs ",
                      b.width(),
                      "x",
                      b.height(),
                      "x",
                      b.channels());
    }
}

}  // namespace

CompareStats compare(const Image &a, const Image &b, const Thresholds &thresholds)
{
    require_same_shape(a, b, "compare");
    const Rect bounds = a.bounds();
    const int tile = kDefaultTileSize;
    const int tiles_x = (bounds.width() + tile - 1) / tile;
    const int tiles_y = (bounds.height() + tile - 1) / tile;
    std::vector<RegionResult> tiles(std::size_t(tiles_x) * std::size_t(tiles_y));
    parallel_for_tiles(
        bounds,
        [&](const Rect &r) {
            const std::size_t index =
                std::size_t(r.y0 / tile) * std::size_t(tiles_x) + std::size_t(r.x0 / tile);
            tiles[index] = compare_region(a, b, r, thresholds);
        },
        tile);

    RegionResult total;
    if (tiles.empty()) {
        total.acc.resize(std::size_t(a.channels()) + 1);
    } else {
        total = std::move(tiles[0]);
        for (std::size_t i = 1; i < tiles.size(); ++i) {
            for (std::size_t k = 0; k < total.acc.size(); ++k) {
                total.acc[k].merge(tiles[i].acc[k]);
            }
        }
    }

    CompareStats stats;
    stats.pixel_count = a.pixel_count();
    stats.all = total.acc[0].finish(a.value_count());
    for (int c = 0; c < a.channels(); ++c) {
        stats.channels.push_back(total.acc[std::size_t(c) + 1].finish(a.pixel_count()));
    }
    return stats;
}

CompareStats compare_surface(
    const Image &a, const Image &b, const Image &depth, int channels, const Thresholds &thresholds)
{
    if (a.width() != depth.width() || a.height() != depth.height() || b.width() != a.width() ||
        b.height() != a.height()) {
        throw_runtime("compare_surface: images of ",
                      a.width(),
                      "x",
                      a.height(),
                      " and ",
                      b.width(),
                      "x",
                      b.height(),
                      " with a depth of ",
                      depth.width(),
                      "x",
                      depth.height());
    }
    const int nc = channels > 0 ? channels : a.channels();
    if (nc > a.channels() || nc > b.channels()) {
        throw_runtime("compare_surface: ",
                      nc,
                      " channels asked of images with ",
                      a.channels(),
                      " and ",
                      b.channels());
    }
    std::vector<std::size_t> keep;
    for (std::size_t i = 0; i < depth.pixel_count(); ++i) {
        if (std::isfinite(depth.data()[i * std::size_t(depth.channels())])) {
            keep.push_back(i);
        }
    }
    if (keep.empty()) {
        // (one zeroed pixel stood in for none: RMSE 0, PSNR inf, a perfect score for nothing)
        throw_runtime("compare_surface: no surface pixel (every depth is the sky or not finite)");
    }
    const int n = int(keep.size());
    Image pa(n, 1, nc), pb(n, 1, nc);
    const std::size_t ca = std::size_t(a.channels()), cb = std::size_t(b.channels());
    for (std::size_t k = 0; k < keep.size(); ++k) {
        std::copy_n(a.data() + keep[k] * ca, nc, pa.data() + k * std::size_t(nc));
        std::copy_n(b.data() + keep[k] * cb, nc, pb.data() + k * std::size_t(nc));
    }
    return compare(pa, pb, thresholds);
}

Verdict verdict(const CompareStats &stats, const Thresholds &t)
{
    // idiff divides by at least one pixel.
    const double pixels = double(std::max<std::uint64_t>(stats.pixel_count, 1));
    const ErrorStats &s = stats.all;
    if (s.fail_count <= std::uint64_t(std::max(t.allow_failures, 0))) {
        return Verdict::Pass;
    }
    if (double(s.fail_count) > t.fail_percent / 100.0 * pixels || s.max_error > t.hard_fail) {
        return Verdict::Failure;
    }
    if (double(s.warn_count) > t.warn_percent / 100.0 * pixels || s.max_error > t.hard_warn) {
        return Verdict::Warning;
    }
    return Verdict::Pass;
}

const char *verdict_name(Verdict v)
{
    switch (v) {
        case Verdict::Pass:
            return "PASS";
        case Verdict::Warning:
            return "WARNING";
        case Verdict::Failure:
            return "FAILURE";
        case Verdict::SizeMismatch:
            return "SIZE MISMATCH";
        case Verdict::FileError:
            return "FILE ERROR";
    }
    return "UNKNOWN";
}

Image difference_image(const Image &a, const Image &b, float scale)
{
    require_same_shape(a, b, "difference_image");
    Image out = Image::uninitialized(a.width(), a.height(), a.channels());
    parallel_for_tiles(out.bounds(), [&](const Rect &r) {
        for (int y = r.y0; y < r.y1; ++y) {
            const float *pa = a.pixel(r.x0, y);
            const float *pb = b.pixel(r.x0, y);
            float *po = out.pixel(r.x0, y);
            for (int i = 0, n = r.width() * a.channels(); i < n; ++i) {
                // As compare counts it: equal values (NaN and NaN, inf and inf) differ by 0,
                // any other non-finite pair by infinity (the image said NaN where the verdict
                // passed, and scale inf made 0 x inf a NaN).
                const float va = pa[i], vb = pb[i];
                const bool same = same_value(va, vb);
                const float d = std::isfinite(va) && std::isfinite(vb) ? std::abs(va - vb) : kInf;
                po[i] = same || scale == 0.0f ? 0.0f : d * scale;
            }
        }
    });
    return out;
}

}  // namespace posthaste::metrics
