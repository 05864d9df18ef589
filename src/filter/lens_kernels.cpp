// The lens node's RGBA resampling over Highway (see lens_kernels.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter/lens_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "filter/lens_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>

HWY_BEFORE_NAMESPACE();
namespace posthaste::filter::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// Catmull-Rom weights of the taps at -1, 0, 1, 2 for the fractions in `t` (products and sums,
/// no fused multiply-add, so every target computes the same values).
template <class D, class V>
HWY_INLINE void CubicWeightsV(D d, V t, V &w0, V &w1, V &w2, V &w3)
{
    const V t2 = hn::Mul(t, t), t3 = hn::Mul(t2, t);
    const V half = hn::Set(d, 0.5f);
    w0 = hn::Sub(hn::Add(hn::Mul(hn::Set(d, -0.5f), t3), t2), hn::Mul(half, t));
    w1 = hn::Add(hn::Sub(hn::Mul(hn::Set(d, 1.5f), t3), hn::Mul(hn::Set(d, 2.5f), t2)),
                 hn::Set(d, 1.0f));
    w2 = hn::Add(hn::Add(hn::Mul(hn::Set(d, -1.5f), t3), hn::Mul(hn::Set(d, 2.0f), t2)),
                 hn::Mul(half, t));
    w3 = hn::Sub(hn::Mul(half, t3), hn::Mul(half, t2));
}

void LensResampleRgbaRow(const float *img,
                         int w,
                         int h,
                         const float *sx,
                         const float *sy,
                         int n,
                         int taps,
                         float *out,
                         std::uint8_t *edge)
{
    // Two phases per block of pixels: their footprints' corners and weights a vector of pixels
    // at a time, then each pixel's taps summed with its four channels in one 4-lane vector (one
    // lane at a time on a scalar target).
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(df)> di;
    const hn::CappedTag<float, 4> d4;
    const int lanes = int(hn::Lanes(d4)), vl = int(hn::Lanes(df));
    const std::size_t stride = std::size_t(w) * 4;
    constexpr int kBlock = 64;
    HWY_ALIGN float wx[4][kBlock], wy[4][kBlock];
    HWY_ALIGN std::int32_t ox[kBlock], oy[kBlock], inside[kBlock];
    const int back = taps / 2 - 1;  // the footprint starts this many pixels before floor(f)
    for (int b0 = 0; b0 < n; b0 += kBlock) {
        const int bn = std::min(kBlock, n - b0);
        for (int k = 0; k < bn; k += vl) {
            // A full vector of positions: past the row's end (n + padding of the caller's
            // arrays is not promised) the last lanes read position 0, their results unused.
            HWY_ALIGN float px[hn::MaxLanes(df)], py[hn::MaxLanes(df)];
            for (int l = 0; l < vl; ++l) {
                const bool in_row = k + l < bn;
                px[l] = in_row ? sx[b0 + k + l] : 0.0f;
                py[l] = in_row ? sy[b0 + k + l] : 0.0f;
            }
            const auto fx = hn::Sub(hn::Load(df, px), hn::Set(df, 0.5f));
            const auto fy = hn::Sub(hn::Load(df, py), hn::Set(df, 0.5f));
            // NaN fails every comparison: such positions go to the edge path too.
            const auto near = hn::And(
                hn::And(hn::Gt(fx, hn::Set(df, -2.0f)), hn::Lt(fx, hn::Set(df, float(w) + 2.0f))),
                hn::And(hn::Gt(fy, hn::Set(df, -2.0f)), hn::Lt(fy, hn::Set(df, float(h) + 2.0f))));
            const auto flx = hn::Floor(hn::IfThenElseZero(near, fx));
            const auto fly = hn::Floor(hn::IfThenElseZero(near, fy));
            // The footprint's corner, checked in floats (exact at these sizes).
            const auto i = hn::Sub(flx, hn::Set(df, float(back)));
            const auto j = hn::Sub(fly, hn::Set(df, float(back)));
            const auto zero = hn::Zero(df), ftaps = hn::Set(df, float(taps));
            const auto ok =
                hn::And(near,
                        hn::And(hn::And(hn::Ge(i, zero), hn::Ge(j, zero)),
                                hn::And(hn::Le(hn::Add(i, ftaps), hn::Set(df, float(w))),
                                        hn::Le(hn::Add(j, ftaps), hn::Set(df, float(h))))));
            hn::Store(hn::IfThenElseZero(hn::RebindMask(di, ok), hn::Set(di, 1)), di, inside + k);
            hn::Store(hn::ConvertTo(di, i), di, ox + k);
            hn::Store(hn::ConvertTo(di, j), di, oy + k);
            const auto a = hn::Sub(fx, flx), bb = hn::Sub(fy, fly);
            if (taps == 4) {
                hn::Vec<decltype(df)> w0, w1, w2, w3;
                CubicWeightsV(df, a, w0, w1, w2, w3);
                hn::Store(w0, df, wx[0] + k);
                hn::Store(w1, df, wx[1] + k);
                hn::Store(w2, df, wx[2] + k);
                hn::Store(w3, df, wx[3] + k);
                CubicWeightsV(df, bb, w0, w1, w2, w3);
                hn::Store(w0, df, wy[0] + k);
                hn::Store(w1, df, wy[1] + k);
                hn::Store(w2, df, wy[2] + k);
                hn::Store(w3, df, wy[3] + k);
            } else {
                const auto one = hn::Set(df, 1.0f);
                hn::Store(hn::Sub(one, a), df, wx[0] + k);
                hn::Store(a, df, wx[1] + k);
                hn::Store(hn::Sub(one, bb), df, wy[0] + k);
                hn::Store(bb, df, wy[1] + k);
            }
        }
        for (int k = 0; k < bn; ++k) {
            const int x = b0 + k;
            if (!inside[k]) {
                edge[x] = 1;
                continue;
            }
            edge[x] = 0;
            const float *p = img + std::size_t(oy[k]) * stride + std::size_t(ox[k]) * 4;
            const auto vx0 = hn::Set(d4, wx[0][k]), vx1 = hn::Set(d4, wx[1][k]);
            const auto vx2 = hn::Set(d4, taps == 4 ? wx[2][k] : 0.0f);
            const auto vx3 = hn::Set(d4, taps == 4 ? wx[3][k] : 0.0f);
            for (int c = 0; c < 4; c += lanes) {
                auto acc = hn::Zero(d4);
                for (int m = 0; m < taps; ++m) {
                    const float *r = p + std::size_t(m) * stride + c;
                    auto row = hn::Mul(vx0, hn::LoadU(d4, r));
                    row = hn::MulAdd(vx1, hn::LoadU(d4, r + 4), row);
                    if (taps == 4) {
                        row = hn::MulAdd(vx2, hn::LoadU(d4, r + 8), row);
                        row = hn::MulAdd(vx3, hn::LoadU(d4, r + 12), row);
                    }
                    acc = hn::MulAdd(hn::Set(d4, wy[m][k]), row, acc);
                }
                hn::StoreU(acc, d4, out + 4 * x + c);
            }
        }
    }
}

}  // namespace posthaste::filter::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::filter {

HWY_EXPORT(LensResampleRgbaRow);

void lens_resample_rgba_row(const float *img,
                            int w,
                            int h,
                            const float *sx,
                            const float *sy,
                            int n,
                            int taps,
                            float *out,
                            std::uint8_t *edge)
{
    HWY_DYNAMIC_DISPATCH(LensResampleRgbaRow)(img, w, h, sx, sy, n, taps, out, edge);
}

}  // namespace posthaste::filter
#endif  // HWY_ONCE
