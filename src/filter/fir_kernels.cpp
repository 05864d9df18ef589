// One-dimensional FIR filters over Highway (see fir_kernels.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter/fir_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "filter/fir_kernels.h"

#include <algorithm>
#include <cmath>

HWY_BEFORE_NAMESPACE();
namespace posthaste::filter::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void FirRow(const float *src, const float *k, int taps, int stride, int n, float *out)
{
    const hn::ScalableTag<float> df;
    const int lanes = int(hn::Lanes(df));
    for (int x = 0; x < n; x += lanes) {
        auto acc = hn::Mul(hn::Set(df, k[0]), hn::LoadU(df, src + x));
        for (int i = 1; i < taps; ++i) {
            acc = hn::MulAdd(hn::Set(df, k[i]), hn::LoadU(df, src + x + i * stride), acc);
        }
        hn::StoreU(acc, df, out + x);
    }
}

void FirColumns(const float *const *rows, const float *k, int taps, int n, float *out)
{
    const hn::ScalableTag<float> df;
    const int lanes = int(hn::Lanes(df));
    for (int x = 0; x < n; x += lanes) {
        auto acc = hn::Mul(hn::Set(df, k[0]), hn::LoadU(df, rows[0] + x));
        for (int i = 1; i < taps; ++i) {
            acc = hn::MulAdd(hn::Set(df, k[i]), hn::LoadU(df, rows[i] + x), acc);
        }
        hn::StoreU(acc, df, out + x);
    }
}

}  // namespace posthaste::filter::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::filter {

std::vector<float> gaussian_kernel(double sigma, double truncate)
{
    if (!(sigma > 0.0)) {
        return {1.0f};
    }
    const int r = std::max(1, int(std::ceil(truncate * sigma)));
    std::vector<float> k(std::size_t(2 * r + 1));
    double sum = 0.0;
    for (int i = -r; i <= r; ++i) {
        const double v = std::exp(-0.5 * i * i / (sigma * sigma));
        k[std::size_t(i + r)] = float(v);
        sum += v;
    }
    for (float &v : k) {
        v = float(v / sum);
    }
    return k;
}

HWY_EXPORT(FirRow);
HWY_EXPORT(FirColumns);

void fir_row(const float *src, const float *k, int taps, int stride, int n, float *out)
{
    HWY_DYNAMIC_DISPATCH(FirRow)(src, k, taps, stride, n, out);
}

void fir_columns(const float *const *rows, const float *k, int taps, int n, float *out)
{
    HWY_DYNAMIC_DISPATCH(FirColumns)(rows, k, taps, n, out);
}

}  // namespace posthaste::filter
#endif  // HWY_ONCE
