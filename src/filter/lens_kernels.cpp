// The lens node's RGBA resampling over Highway (see lens_kernels.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter/lens_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "filter/lens_kernels.h"

#include <cmath>
#include <cstddef>

HWY_BEFORE_NAMESPACE();
namespace posthaste::filter::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// Catmull-Rom weights of the taps at -1, 0, 1, 2 for a fraction t.
HWY_INLINE void CubicWeights(float t, float *w)
{
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
    w[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
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
    // Up to four lanes: one pixel's channels (one lane at a time on a scalar target).
    const hn::CappedTag<float, 4> d4;
    const int lanes = int(hn::Lanes(d4));
    const std::size_t stride = std::size_t(w) * 4;
    for (int x = 0; x < n; ++x) {
        const float fx = sx[x] - 0.5f, fy = sy[x] - 0.5f;
        // NaN fails every comparison: such positions go to the edge path too.
        if (!(fx > -2.0f && fx < float(w) + 2.0f && fy > -2.0f && fy < float(h) + 2.0f)) {
            edge[x] = 1;
            continue;
        }
        const int ix = int(std::floor(fx)), iy = int(std::floor(fy));
        const int i = ix - (taps / 2 - 1), j = iy - (taps / 2 - 1);
        if (i < 0 || j < 0 || i + taps > w || j + taps > h) {
            edge[x] = 1;
            continue;
        }
        edge[x] = 0;
        const float a = fx - float(ix), b = fy - float(iy);
        float wx[4], wy[4];
        if (taps == 4) {
            CubicWeights(a, wx);
            CubicWeights(b, wy);
        } else {
            wx[0] = 1.0f - a;
            wx[1] = a;
            wy[0] = 1.0f - b;
            wy[1] = b;
        }
        const float *p = img + std::size_t(j) * stride + std::size_t(i) * 4;
        // The weights broadcast once per pixel (the compiler did not hoist them out of the
        // loops over rows and channels).
        const auto vx0 = hn::Set(d4, wx[0]), vx1 = hn::Set(d4, wx[1]);
        const auto vx2 = hn::Set(d4, taps == 4 ? wx[2] : 0.0f);
        const auto vx3 = hn::Set(d4, taps == 4 ? wx[3] : 0.0f);
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
                acc = hn::MulAdd(hn::Set(d4, wy[m]), row, acc);
            }
            hn::StoreU(acc, d4, out + 4 * x + c);
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
