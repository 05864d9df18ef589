// Tone curves over Highway (see tonemap_kernels.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "filter/tonemap_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include <hwy/contrib/math/math-inl.h>
// clang-format on

#include "filter/tonemap_kernels.h"

#include <algorithm>

HWY_BEFORE_NAMESPACE();
namespace posthaste::filter::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

template <class D, class V>
HWY_INLINE V HablePartial(D d, V x)
{
    const V A = hn::Set(d, 0.15f), B = hn::Set(d, 0.50f), C = hn::Set(d, 0.10f),
            Dd = hn::Set(d, 0.20f), E = hn::Set(d, 0.02f), F = hn::Set(d, 0.30f);
    const V num = hn::MulAdd(x, hn::MulAdd(A, x, hn::Mul(C, B)), hn::Mul(Dd, E));
    const V den = hn::MulAdd(x, hn::MulAdd(A, x, B), hn::Mul(Dd, F));
    return hn::Sub(hn::Div(num, den), hn::Div(E, F));
}

/// The per-value curves (not AgX), clamped to [0, 1].
template <class D, class V>
HWY_INLINE V Curve(D d, V x, ToneCurve curve, float white)
{
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    x = hn::Max(x, zero);
    if (curve != ToneCurve::Reinhard) {
        // Past max(1e6, white) both curves are at 1 already (ACES's from 7.25, Hable's from
        // white / 2); above about 1e19 their squares overflowed to inf / inf, NaN, and the
        // clamp below made the brightest values black.
        x = hn::Min(x, hn::Set(d, std::max(1e6f, white)));
    }
    V y;
    if (curve == ToneCurve::Reinhard) {
        const V num = hn::Mul(x, hn::MulAdd(x, hn::Set(d, 1.0f / (white * white)), one));
        y = hn::Div(num, hn::Add(one, x));
    } else if (curve == ToneCurve::Hable) {
        const V w = hn::Set(d, white);
        y = hn::Div(HablePartial(d, hn::Add(x, x)), HablePartial(d, w));
    } else {
        const V num = hn::Mul(x, hn::MulAdd(hn::Set(d, 2.51f), x, hn::Set(d, 0.03f)));
        const V den =
            hn::MulAdd(x, hn::MulAdd(hn::Set(d, 2.43f), x, hn::Set(d, 0.59f)), hn::Set(d, 0.14f));
        y = hn::Div(num, den);
    }
    return hn::Min(hn::Max(y, zero), one);
}

/// AgX-style on three channel vectors, to display-linear.
template <class D, class V>
HWY_INLINE void Agx(D d, V &r, V &g, V &b)
{
    // Inset and outset matrices (rows), Rec.709.
    constexpr float kIn[9] = {0.842479062253094f,
                              0.0784335999999992f,
                              0.0792237451477643f,
                              0.0423282422610123f,
                              0.878468636469772f,
                              0.0791661274605434f,
                              0.0423756549057051f,
                              0.0784336f,
                              0.879142973793104f};
    constexpr float kOut[9] = {1.19687900512017f,
                               -0.0980208811401368f,
                               -0.0990297440797205f,
                               -0.0528968517574562f,
                               1.15190312990417f,
                               -0.0989611768448433f,
                               -0.0529716355144438f,
                               -0.0980434501171241f,
                               1.15107367264116f};
    constexpr float kMinEv = -12.47393f, kMaxEv = 4.026069f;
    auto mix = [&](const float *m, V a0, V a1, V a2, V &o0, V &o1, V &o2) {
        o0 = hn::MulAdd(
            hn::Set(d, m[0]), a0, hn::MulAdd(hn::Set(d, m[1]), a1, hn::Mul(hn::Set(d, m[2]), a2)));
        o1 = hn::MulAdd(
            hn::Set(d, m[3]), a0, hn::MulAdd(hn::Set(d, m[4]), a1, hn::Mul(hn::Set(d, m[5]), a2)));
        o2 = hn::MulAdd(
            hn::Set(d, m[6]), a0, hn::MulAdd(hn::Set(d, m[7]), a1, hn::Mul(hn::Set(d, m[8]), a2)));
    };
    auto sigmoid = [&](V v) {
        const V ev = hn::Log2(d, hn::Mul(hn::Max(v, hn::Set(d, 1e-10f)), hn::Set(d, 1.0f / 0.18f)));
        V x = hn::Mul(hn::Sub(ev, hn::Set(d, kMinEv)), hn::Set(d, 1.0f / (kMaxEv - kMinEv)));
        x = hn::Min(hn::Max(x, hn::Zero(d)), hn::Set(d, 1.0f));
        // 15.5 x^6 - 40.14 x^5 + 31.96 x^4 - 6.868 x^3 + 0.4298 x^2 + 0.1191 x - 0.00232.
        V p = hn::Set(d, 15.5f);
        p = hn::MulAdd(p, x, hn::Set(d, -40.14f));
        p = hn::MulAdd(p, x, hn::Set(d, 31.96f));
        p = hn::MulAdd(p, x, hn::Set(d, -6.868f));
        p = hn::MulAdd(p, x, hn::Set(d, 0.4298f));
        p = hn::MulAdd(p, x, hn::Set(d, 0.1191f));
        return hn::MulAdd(p, x, hn::Set(d, -0.00232f));
    };
    auto linearise = [&](V v) {
        v = hn::Min(hn::Max(v, hn::Zero(d)), hn::Set(d, 1.0f));
        const V safe = hn::Max(v, hn::Set(d, 1e-30f));
        const V y = hn::Exp(d, hn::Mul(hn::Set(d, 2.2f), hn::Log(d, safe)));
        return hn::IfThenElse(hn::Gt(v, hn::Zero(d)), y, hn::Zero(d));
    };
    V i0, i1, i2, o0, o1, o2;
    mix(kIn, r, g, b, i0, i1, i2);
    mix(kOut, sigmoid(i0), sigmoid(i1), sigmoid(i2), o0, o1, o2);
    r = linearise(o0);
    g = linearise(o1);
    b = linearise(o2);
}

template <class D, class V>
HWY_INLINE void MapPixels(D d, V &r, V &g, V &b, V a, ToneCurve curve, bool luminance, float white)
{
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const auto finite = hn::And(hn::IsFinite(r), hn::And(hn::IsFinite(g), hn::IsFinite(b)));
    const auto has_alpha = hn::Gt(a, hn::Set(d, 1e-6f));
    const V pre = hn::IfThenElse(has_alpha, a, one);
    const V inv = hn::Div(one, pre);
    V ur = hn::Mul(r, inv), ug = hn::Mul(g, inv), ub = hn::Mul(b, inv);
    if (luminance) {
        const V lum =
            hn::MulAdd(hn::Set(d, 0.2126f),
                       ur,
                       hn::MulAdd(hn::Set(d, 0.7152f), ug, hn::Mul(hn::Set(d, 0.0722f), ub)));
        V mapped;
        if (curve == ToneCurve::Agx) {
            V gr = lum, gg = lum, gb = lum;
            Agx(d, gr, gg, gb);
            mapped = gg;
        } else {
            mapped = Curve(d, lum, curve, white);
        }
        const auto positive = hn::Gt(lum, zero);
        const V k =
            hn::IfThenElse(positive, hn::Div(mapped, hn::IfThenElse(positive, lum, one)), zero);
        ur = hn::Mul(hn::Max(ur, zero), k);
        ug = hn::Mul(hn::Max(ug, zero), k);
        ub = hn::Mul(hn::Max(ub, zero), k);
    } else if (curve == ToneCurve::Agx) {
        Agx(d, ur, ug, ub);
    } else {
        ur = Curve(d, ur, curve, white);
        ug = Curve(d, ug, curve, white);
        ub = Curve(d, ub, curve, white);
    }
    r = hn::IfThenElse(finite, hn::Mul(ur, pre), r);
    g = hn::IfThenElse(finite, hn::Mul(ug, pre), g);
    b = hn::IfThenElse(finite, hn::Mul(ub, pre), b);
}

void TonemapRgbaRow(
    const float *src, float *dst, int n, ToneCurve curve, bool luminance, float white)
{
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    int x = 0;
    for (; x + lanes <= n; x += lanes) {
        hn::Vec<decltype(d)> r, g, b, a;
        hn::LoadInterleaved4(d, src + 4 * x, r, g, b, a);
        MapPixels(d, r, g, b, a, curve, luminance, white);
        hn::StoreInterleaved4(r, g, b, a, d, dst + 4 * x);
    }
    if (x < n) {
        // The last pixels through a full vector of a padded copy: the same arithmetic.
        HWY_ALIGN float px[4 * hn::MaxLanes(d)] = {};
        std::copy(src + 4 * x, src + 4 * n, px);
        hn::Vec<decltype(d)> r, g, b, a;
        hn::LoadInterleaved4(d, px, r, g, b, a);
        MapPixels(d, r, g, b, a, curve, luminance, white);
        hn::StoreInterleaved4(r, g, b, a, d, px);
        std::copy(px, px + 4 * (n - x), dst + 4 * x);
    }
}

}  // namespace posthaste::filter::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::filter {

HWY_EXPORT(TonemapRgbaRow);

void tonemap_rgba_row(
    const float *src, float *dst, int n, ToneCurve curve, bool luminance, float white)
{
    HWY_DYNAMIC_DISPATCH(TonemapRgbaRow)(src, dst, n, curve, luminance, white);
}

}  // namespace posthaste::filter
#endif  // HWY_ONCE
