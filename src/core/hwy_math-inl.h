// Per-lane math shared by the Highway kernels (fog, atmosphere, grain), with the rounding each
// promises written down, so that a kernel's scalar twin (shading/fast_math.h) and its vector
// targets compute the same formula. Include it after <hwy/highway.h> inside a kernel file that uses
// foreach_target.h; like every Highway "-inl.h" it is compiled once per target (the toggle guard
// below).

// clang-format off
#if defined(POSTHASTE_CORE_HWY_MATH_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef POSTHASTE_CORE_HWY_MATH_INL_H_
#undef POSTHASTE_CORE_HWY_MATH_INL_H_
#else
#define POSTHASTE_CORE_HWY_MATH_INL_H_
#endif
// clang-format on

#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace posthaste::simd::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// e^r for |r| <= ln2 / 2 by its degree-6 Taylor series in Horner form (fused multiply-adds
/// where the target has them); relative error under 2e-7 there.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V ExpTaylor6(D d, V r)
{
    V p = hn::Set(d, 1.0f / 720.0f);
    p = hn::MulAdd(p, r, hn::Set(d, 1.0f / 120.0f));
    p = hn::MulAdd(p, r, hn::Set(d, 1.0f / 24.0f));
    p = hn::MulAdd(p, r, hn::Set(d, 1.0f / 6.0f));
    p = hn::MulAdd(p, r, hn::Set(d, 0.5f));
    p = hn::MulAdd(p, r, hn::Set(d, 1.0f));
    return hn::MulAdd(p, r, hn::Set(d, 1.0f));
}

/// 2^n for integer lanes n in [-126, 127], built from the exponent bits.
template <class D, class VI>
HWY_INLINE hn::Vec<D> Pow2i(D d, VI n)
{
    const hn::RebindToSigned<D> di;
    return hn::BitCast(d, hn::ShiftLeft<23>(hn::Add(n, hn::Set(di, 127))));
}

/// exp(x) by shading::fast_exp's method: x clamped to [-87, 88] (so exp(-huge) is 1.6e-38, not
/// 0, and NaN becomes one of the bounds: callers mask NaN lanes), Cody-Waite reduction
/// x = n ln2 + r with n rounded to nearest, ExpTaylor6(r), then scaled by 2^n. Relative error
/// < 3e-7.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V FastExp(D d, V x)
{
    x = hn::Min(hn::Max(x, hn::Set(d, -87.0f)), hn::Set(d, 88.0f));
    const auto n = hn::NearestInt(hn::Mul(x, hn::Set(d, 1.44269504089f)));
    const V nf = hn::ConvertTo(d, n);
    const V r = hn::NegMulAdd(nf,
                              hn::Set(d, 1.428606765330187e-06f),
                              hn::NegMulAdd(nf, hn::Set(d, 0.693145751953125f), x));
    return hn::Mul(ExpTaylor6(d, r), Pow2i(d, n));
}

/// 2^y for |y| <= 100 (clamped there): 2^round(y) times ExpTaylor6 of the fraction times ln 2,
/// |fraction| <= 1/2 (relative error under 2e-7).
template <class D, class V = hn::Vec<D>>
HWY_INLINE V Exp2(D d, V y)
{
    y = hn::Min(hn::Max(y, hn::Set(d, -100.0f)), hn::Set(d, 100.0f));
    const auto n = hn::NearestInt(y);
    const V t = hn::Mul(hn::Sub(y, hn::ConvertTo(d, n)), hn::Set(d, 0.69314718f));
    return hn::Mul(ExpTaylor6(d, t), Pow2i(d, n));
}

/// ax * bx + ay * by + az * bz, summed from the z term outwards (glm's dot order when the
/// target fuses: fma(ax, bx, fma(ay, by, az * bz))).
template <class V>
HWY_INLINE V Dot3(V ax, V ay, V az, V bx, V by, V bz)
{
    return hn::MulAdd(ax, bx, hn::MulAdd(ay, by, hn::Mul(az, bz)));
}

/// ax * bx + ay * by + az * bz in glm's order without fusing, ((x + y) + z), for kernels that
/// promise the same bits on every target (compiled without FP contraction).
template <class V>
HWY_INLINE V Dot3Unfused(V ax, V ay, V az, V bx, V by, V bz)
{
    return hn::Add(hn::Add(hn::Mul(ax, bx), hn::Mul(ay, by)), hn::Mul(az, bz));
}

/// Lanes where x is finite, as x - x == 0 (0 for a finite x, NaN for an infinite or NaN one):
/// two instructions on every x86 target, where Highway's IsFinite takes four on AVX2 (shifts
/// and an integer compare). The same lanes as IsFinite.
template <class V>
HWY_INLINE hn::Mask<hn::DFromV<V>> Finite(V x)
{
    return hn::Eq(hn::Sub(x, x), hn::Zero(hn::DFromV<V>()));
}

/// min(max(x, lo), hi), in that order: on x86 a NaN x gives lo (Highway's Clamp takes
/// max(lo, x), which keeps the NaN).
template <class V>
HWY_INLINE V ClampToRange(V x, V lo, V hi)
{
    return hn::Min(hn::Max(x, lo), hi);
}

/// Three interleaved floats a pixel (x y z x y z ...) from p into planes: hn::LoadInterleaved3,
/// with a shorter sequence on AVX2. There Highway's version loads three 32-byte vectors and
/// moves 16-byte blocks across them (three block permutes, four blends, five shuffles); here
/// each 32-byte register is two 16-byte loads (pixels 0-3 and 4-7 side by side) and five
/// in-block shuffles sort them. The same values either way.
template <class D>
HWY_INLINE void LoadXyz(
    D d, const float *HWY_RESTRICT p, hn::Vec<D> &x, hn::Vec<D> &y, hn::Vec<D> &z)
{
#if HWY_TARGET == HWY_AVX2
    if constexpr (hn::MaxLanes(D()) == 8) {
        const hn::Full128<float> d4;
        // Per block: m03 = x0 y0 z0 x1, m14 = y1 z1 x2 y2, m25 = z2 x3 y3 z3 (the lower block
        // pixels 0-3, the upper 4-7).
        const __m256 m03 = hn::Combine(d, hn::LoadU(d4, p + 12), hn::LoadU(d4, p)).raw;
        const __m256 m14 = hn::Combine(d, hn::LoadU(d4, p + 16), hn::LoadU(d4, p + 4)).raw;
        const __m256 m25 = hn::Combine(d, hn::LoadU(d4, p + 20), hn::LoadU(d4, p + 8)).raw;
        const __m256 xy = _mm256_shuffle_ps(m14, m25, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
        const __m256 yz = _mm256_shuffle_ps(m03, m14, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
        x = hn::Vec<D>{_mm256_shuffle_ps(m03, xy, _MM_SHUFFLE(2, 0, 3, 0))};
        y = hn::Vec<D>{_mm256_shuffle_ps(yz, xy, _MM_SHUFFLE(3, 1, 2, 0))};
        z = hn::Vec<D>{_mm256_shuffle_ps(yz, m25, _MM_SHUFFLE(3, 0, 3, 1))};
        return;
    }
#endif
    hn::LoadInterleaved3(d, p, x, y, z);
}

}  // namespace posthaste::simd::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // include guard
