// A depth pass through a reconstruction filter, made safe (see depth_resample.h).

#include "filter/depth_resample.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "core/parallel.h"

namespace posthaste::filter {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

/// Sliding minimum (Min) or maximum over windows of 2r + 1 elements along one axis, in time
/// independent of r (van Herk / Gil-Werman: prefix and suffix runs within blocks of 2r + 1 of the
/// sequence padded by r neutral elements at each end). `n` elements of `m` floats, element e at
/// in + e * stride; out likewise with `out_stride`.
template <bool Min>
void sliding_extreme(const float *in,
                     std::ptrdiff_t stride,
                     int n,
                     int m,
                     int r,
                     float *out,
                     std::ptrdiff_t out_stride)
{
    const float neutral = Min ? kInf : -kInf;
    auto op = [](float a, float b) { return Min ? std::min(a, b) : std::max(a, b); };
    const int k = 2 * r + 1, np = n + 2 * r;
    const std::size_t mm = std::size_t(m);
    std::vector<float> g(std::size_t(np) * mm), h(std::size_t(np) * mm);
    auto value = [&](int p, int j) {
        return p < r || p >= n + r ? neutral : in[(p - r) * stride + j];
    };
    for (int p = 0; p < np; ++p) {
        float *gp = g.data() + std::size_t(p) * mm;
        for (int j = 0; j < m; ++j) {
            gp[j] = p % k == 0 ? value(p, j)
                               : op(gp[std::ptrdiff_t(j) - std::ptrdiff_t(mm)], value(p, j));
        }
    }
    for (int p = np - 1; p >= 0; --p) {
        float *hp = h.data() + std::size_t(p) * mm;
        for (int j = 0; j < m; ++j) {
            hp[j] = p % k == k - 1 || p == np - 1 ? value(p, j) : op(hp[j + m], value(p, j));
        }
    }
    for (int e = 0; e < n; ++e) {
        const float *a = h.data() + std::size_t(e) * mm;
        const float *b = g.data() + std::size_t(e + 2 * r) * mm;
        for (int j = 0; j < m; ++j) {
            out[e * out_stride + j] = op(a[j], b[j]);
        }
    }
}

/// The sliding extreme of channel c's finite values over (2r + 1)^2 boxes, one channel.
template <bool Min>
Image box_extreme(const Image &depth, int c, int r)
{
    const int w = depth.width(), h = depth.height(), nc = depth.channels();
    const float neutral = Min ? kInf : -kInf;
    Image rows = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        std::vector<float> line(static_cast<std::size_t>(w));
        const float *s = depth.pixel(0, y) + c;
        for (int x = 0; x < w; ++x) {
            const float v = s[std::size_t(x) * std::size_t(nc)];
            line[std::size_t(x)] = std::isfinite(v) ? v : neutral;
        }
        sliding_extreme<Min>(line.data(), 1, w, 1, r, rows.pixel(0, y), 1);
    });
    Image box = Image::uninitialized(w, h, 1);
    constexpr int kColumns = 64;  // columns per task: whole row segments keep the pass in cache
    parallel_for(0, (w + kColumns - 1) / kColumns, [&](int t) {
        const int x0 = t * kColumns, m = std::min(kColumns, w - x0);
        sliding_extreme<Min>(rows.pixel(x0, 0), w, h, m, r, box.pixel(x0, 0), w);
    });
    return box;
}

}  // namespace

Image sky_split(const Image &depth)
{
    const int nc = depth.channels();
    Image out = Image::uninitialized(depth.width(), depth.height(), 2 * nc);
    parallel_for(0, depth.height(), [&](int y) {
        const float *s = depth.pixel(0, y);
        float *d = out.pixel(0, y);
        for (int x = 0; x < depth.width(); ++x, s += nc, d += 2 * nc) {
            for (int c = 0; c < nc; ++c) {
                const bool sky = s[c] == kInf;
                d[c] = sky ? 0.0f : s[c];
                d[nc + c] = sky ? 1.0f : 0.0f;
            }
        }
    });
    return out;
}

Image depth_range(const Image &depth, int radius)
{
    const int r = std::max(radius, 0), nc = depth.channels();
    Image range = Image::uninitialized(depth.width(), depth.height(), 2 * nc);
    for (int c = 0; c < nc; ++c) {
        const Image lo = box_extreme<true>(depth, c, r), hi = box_extreme<false>(depth, c, r);
        parallel_for(0, depth.height(), [&](int y) {
            const float *a = lo.pixel(0, y), *b = hi.pixel(0, y);
            float *d = range.pixel(0, y);
            for (int x = 0; x < depth.width(); ++x) {
                d[std::size_t(x) * std::size_t(2 * nc) + std::size_t(2 * c)] = a[x];
                d[std::size_t(x) * std::size_t(2 * nc) + std::size_t(2 * c + 1)] = b[x];
            }
        });
    }
    return range;
}

void guard_depth_row(const Image &depth,
                     const Image &range,
                     const std::int32_t *nearest,
                     int n,
                     const float *filtered,
                     float *row)
{
    const int nc = depth.channels();
    for (int i = 0; i < n; ++i) {
        const float *f = filtered + std::size_t(i) * std::size_t(2 * nc);
        float *d = row + std::size_t(i) * std::size_t(nc);
        if (nearest[i] < 0) {
            std::fill(d, d + nc, kInf);  // outside the input: the sky, as nearest sampling
            continue;
        }
        const float *near = depth.data() + std::size_t(nearest[i]) * std::size_t(nc);
        const float *lohi = range.data() + std::size_t(nearest[i]) * std::size_t(2 * nc);
        for (int c = 0; c < nc; ++c) {
            const float lo = lohi[2 * c], hi = lohi[2 * c + 1];
            // The indicator's sum is 0 unless a tap of non-zero weight lay on the sky (NaN:
            // outside the input).
            const bool touched = !(f[nc + c] == 0.0f);
            d[c] = touched || !std::isfinite(near[c]) || !(lo <= hi) ? near[c]
                                                                     : std::clamp(f[c], lo, hi);
        }
    }
}

}  // namespace posthaste::filter
