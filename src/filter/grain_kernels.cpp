// Grain's row kernels over Highway (see grain_kernels.h). This file is compiled once per target:
// Highway's foreach_target.h includes it again for each, and HWY_EXPORT/HWY_DYNAMIC_DISPATCH pick
// the best target the CPU has.

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter/grain_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "core/hwy_math-inl.h"
// clang-format on

#include "filter/grain_kernels.h"

#include <algorithm>

HWY_BEFORE_NAMESPACE();
namespace posthaste::filter::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
using posthaste::simd::HWY_NAMESPACE::Exp2;

/// pcg_hash (core/hash.h) on every lane.
template <class DU, class VU>
HWY_INLINE VU PcgHash(DU du, VU v)
{
    const VU state = hn::Add(hn::Mul(v, hn::Set(du, 747796405u)), hn::Set(du, 2891336453u));
    const VU shift = hn::Add(hn::ShiftRight<28>(state), hn::Set(du, 4u));
    const VU word = hn::Mul(hn::Xor(hn::Shr(state, shift), state), hn::Set(du, 277803737u));
    return hn::Xor(hn::ShiftRight<22>(word), word);
}

void GrainNoiseRow(std::uint32_t row_key, int x0, int n, float unit, float *out)
{
    const hn::ScalableTag<std::uint32_t> du;
    const hn::ScalableTag<float> df;
    const hn::RebindToSigned<decltype(du)> di;
    const int lanes = int(hn::Lanes(du));
    const auto key = hn::Set(du, row_key);
    const auto byte = hn::Set(du, 255u);
    const auto centre = hn::Set(di, 510);
    const auto scale = hn::Set(df, unit);
    for (int x = 0; x < n; x += lanes) {
        const auto coord = hn::Iota(du, std::uint32_t(x0 + x));
        const auto v = PcgHash(du, hn::Xor(coord, key));
        const auto sum =
            hn::Add(hn::Add(hn::And(v, byte), hn::And(hn::ShiftRight<8>(v), byte)),
                    hn::Add(hn::And(hn::ShiftRight<16>(v), byte), hn::ShiftRight<24>(v)));
        const auto centred = hn::Sub(hn::BitCast(di, sum), centre);
        hn::StoreU(hn::Mul(hn::ConvertTo(df, centred), scale), df, out + x);
    }
}

template <class DF, class VF>
HWY_INLINE void GrainPixels(
    DF df, VF &r, VF &g, VF &b, VF gr, VF gg, VF gb, float amount, float response, float offset)
{
    const VF zero = hn::Zero(df);
    const VF lum =
        hn::Max(zero,
                hn::MulAdd(hn::Set(df, 0.2126f),
                           r,
                           hn::MulAdd(hn::Set(df, 0.7152f), g, hn::Mul(hn::Set(df, 0.0722f), b))));
    const auto finite = hn::IsFinite(lum);
    // lum / (lum + 0.18) by the reciprocal estimate and one Newton step (about 23 bits).
    const VF den = hn::Add(lum, hn::Set(df, 0.18f));
    VF inv = hn::ApproximateReciprocal(den);
    inv = hn::Mul(inv, hn::NegMulAdd(den, inv, hn::Set(df, 2.0f)));
    const VF u = hn::IfThenElse(finite, hn::Mul(lum, inv), hn::Set(df, 1.0f));
    const VF bump =
        hn::Mul(hn::Mul(hn::Set(df, 4.0f * response), u), hn::Sub(hn::Set(df, 1.0f), u));
    const VF wgt = hn::Mul(hn::Set(df, amount), hn::Add(hn::Set(df, 1.0f - response), bump));
    const VF off = hn::Set(df, offset);
    auto grain = [&](VF v, VF field) {
        const VF out = hn::Sub(hn::Mul(hn::Add(v, off), Exp2(df, hn::Mul(field, wgt))), off);
        return hn::IfThenElse(hn::IsFinite(v), out, v);
    };
    r = grain(r, gr);
    g = grain(g, gg);
    b = grain(b, gb);
}

void GrainApplyRgbaRow(const float *src,
                       float *dst,
                       const float *fr,
                       const float *fg,
                       const float *fb,
                       int n,
                       float amount,
                       float response,
                       float offset)
{
    const hn::ScalableTag<float> df;
    const int lanes = int(hn::Lanes(df));
    int x = 0;
    for (; x + lanes <= n; x += lanes) {
        hn::Vec<decltype(df)> r, g, b, a;
        hn::LoadInterleaved4(df, src + 4 * x, r, g, b, a);
        GrainPixels(df,
                    r,
                    g,
                    b,
                    hn::LoadU(df, fr + x),
                    hn::LoadU(df, fg + x),
                    hn::LoadU(df, fb + x),
                    amount,
                    response,
                    offset);
        hn::StoreInterleaved4(r, g, b, a, df, dst + 4 * x);
    }
    if (x < n) {
        // The last pixels through a full vector of a padded copy: the same arithmetic.
        HWY_ALIGN float px[4 * hn::MaxLanes(df)] = {};
        HWY_ALIGN float f[3][hn::MaxLanes(df)] = {};
        const int rest = n - x;
        std::copy(src + 4 * x, src + 4 * n, px);
        std::copy(fr + x, fr + n, f[0]);
        std::copy(fg + x, fg + n, f[1]);
        std::copy(fb + x, fb + n, f[2]);
        hn::Vec<decltype(df)> r, g, b, a;
        hn::LoadInterleaved4(df, px, r, g, b, a);
        GrainPixels(df,
                    r,
                    g,
                    b,
                    hn::Load(df, f[0]),
                    hn::Load(df, f[1]),
                    hn::Load(df, f[2]),
                    amount,
                    response,
                    offset);
        hn::StoreInterleaved4(r, g, b, a, df, px);
        std::copy(px, px + 4 * rest, dst + 4 * x);
    }
}

}  // namespace posthaste::filter::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::filter {

HWY_EXPORT(GrainNoiseRow);
HWY_EXPORT(GrainApplyRgbaRow);

void grain_noise_row(std::uint32_t row_key, int x0, int n, float unit, float *out)
{
    HWY_DYNAMIC_DISPATCH(GrainNoiseRow)(row_key, x0, n, unit, out);
}

void grain_apply_rgba_row(const float *src,
                          float *dst,
                          const float *field_r,
                          const float *field_g,
                          const float *field_b,
                          int n,
                          float amount,
                          float response,
                          float offset)
{
    HWY_DYNAMIC_DISPATCH(GrainApplyRgbaRow)
    (src, dst, field_r, field_g, field_b, n, amount, response, offset);
}

}  // namespace posthaste::filter
#endif  // HWY_ONCE
