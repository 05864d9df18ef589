#pragma once
// Eight-lane float helpers (namespace simd::v8) for AVX2 kernels: include only from .cpp files, and
// call only from functions marked POSTHASTE_AVX2 behind simd::avx2() (see core/simd.h). Every
// function here is always-inline and compiled for AVX2 + FMA, so it never leaks AVX2 code into a
// scalar caller.
//
// exp/log are range-reduced polynomials, accurate to about 2 ulp over the normal float range
// (tests/unit/simd_test.cpp measures them against std::exp and std::log).

#include "core/simd.h"

#if POSTHASTE_HAVE_AVX2_TARGET
#include <immintrin.h>

#define POSTHASTE_AVX2_INLINE inline __attribute__((always_inline, target("avx2,fma,f16c")))

namespace posthaste::simd::v8 {

using V = __m256;
using VI = __m256i;

POSTHASTE_AVX2_INLINE V set1(float x)
{
    return _mm256_set1_ps(x);
}
POSTHASTE_AVX2_INLINE V clamp(V x, V lo, V hi)
{
    return _mm256_min_ps(_mm256_max_ps(x, lo), hi);
}
/// x * 2^n for integer-valued float n in [-126, 127].
POSTHASTE_AVX2_INLINE V ldexp_int(V x, V n)
{
    const VI e =
        _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvtps_epi32(n), _mm256_set1_epi32(127)), 23);
    return _mm256_mul_ps(x, _mm256_castsi256_ps(e));
}

/// e^x. Underflows to 0 below about -87.3, saturates to 2^128-ish (finite) above 88.7; NaN in,
/// NaN out.
POSTHASTE_AVX2_INLINE V exp(V x)
{
    const V xc = clamp(x, set1(-87.3f), set1(88.7f));
    // x = n ln2 + r, |r| <= ln2 / 2; ln2 split in two so n * ln2 is exact enough.
    const V n = _mm256_round_ps(_mm256_mul_ps(xc, set1(1.44269504088896341f)),
                                _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC);
    V r = _mm256_fnmadd_ps(n, set1(0.693359375f), xc);
    r = _mm256_fnmadd_ps(n, set1(-2.12194440e-4f), r);
    // Taylor series of e^r to degree 7 (error under 1e-8 relative on |r| <= 0.347).
    V p = set1(1.0f / 5040.0f);
    p = _mm256_fmadd_ps(p, r, set1(1.0f / 720.0f));
    p = _mm256_fmadd_ps(p, r, set1(1.0f / 120.0f));
    p = _mm256_fmadd_ps(p, r, set1(1.0f / 24.0f));
    p = _mm256_fmadd_ps(p, r, set1(1.0f / 6.0f));
    p = _mm256_fmadd_ps(p, r, set1(0.5f));
    p = _mm256_fmadd_ps(p, r, set1(1.0f));
    p = _mm256_fmadd_ps(p, r, set1(1.0f));
    // 2^n in two halves so that n = 128 (x near 88.7) stays finite.
    const V half_n = _mm256_floor_ps(_mm256_mul_ps(n, set1(0.5f)));
    V y = ldexp_int(ldexp_int(p, half_n), _mm256_sub_ps(n, half_n));
    y = _mm256_and_ps(y, _mm256_cmp_ps(x, set1(-87.3f), _CMP_GE_OQ));  // underflow -> 0
    return _mm256_blendv_ps(y, x, _mm256_cmp_ps(x, x, _CMP_UNORD_Q));  // NaN stays NaN
}

/// Natural log for x > 0 (normal floats). x <= 0 or NaN gives NaN; +inf gives +inf.
POSTHASTE_AVX2_INLINE V log(V x)
{
    const VI xi = _mm256_castps_si256(x);
    // x = m 2^e with m in [sqrt(1/2), sqrt(2)).
    VI e = _mm256_sub_epi32(_mm256_srli_epi32(xi, 23), _mm256_set1_epi32(127));
    V m = _mm256_castsi256_ps(_mm256_or_si256(_mm256_and_si256(xi, _mm256_set1_epi32(0x007fffff)),
                                              _mm256_set1_epi32(0x3f800000)));
    const V big = _mm256_cmp_ps(m, set1(1.41421356f), _CMP_GE_OQ);
    m = _mm256_blendv_ps(m, _mm256_mul_ps(m, set1(0.5f)), big);
    e = _mm256_add_epi32(e, _mm256_and_si256(_mm256_castps_si256(big), _mm256_set1_epi32(1)));
    // log m = 2 atanh(s), s = (m - 1) / (m + 1), |s| <= 0.1716: odd series to s^11.
    const V s = _mm256_div_ps(_mm256_sub_ps(m, set1(1.0f)), _mm256_add_ps(m, set1(1.0f)));
    const V s2 = _mm256_mul_ps(s, s);
    V p = set1(2.0f / 11.0f);
    p = _mm256_fmadd_ps(p, s2, set1(2.0f / 9.0f));
    p = _mm256_fmadd_ps(p, s2, set1(2.0f / 7.0f));
    p = _mm256_fmadd_ps(p, s2, set1(2.0f / 5.0f));
    p = _mm256_fmadd_ps(p, s2, set1(2.0f / 3.0f));
    p = _mm256_fmadd_ps(p, s2, set1(2.0f));
    const V lm = _mm256_mul_ps(p, s);
    const V ef = _mm256_cvtepi32_ps(e);
    V y = _mm256_fmadd_ps(ef, set1(0.693359375f), _mm256_fmadd_ps(ef, set1(-2.12194440e-4f), lm));
    const V bad = _mm256_cmp_ps(x, _mm256_setzero_ps(), _CMP_NGT_UQ);  // x <= 0 or NaN
    y = _mm256_or_ps(y, bad);                                          // all ones = NaN
    const V inf = set1(__builtin_inff());
    return _mm256_blendv_ps(y, inf, _mm256_cmp_ps(x, inf, _CMP_EQ_OQ));
}

/// x^y for x > 0.
POSTHASTE_AVX2_INLINE V pow(V x, V y)
{
    return exp(_mm256_mul_ps(y, log(x)));
}

/// 1 / x to about 23 bits (rcp + one Newton step).
POSTHASTE_AVX2_INLINE V rcp(V x)
{
    const V r = _mm256_rcp_ps(x);
    return _mm256_mul_ps(r, _mm256_fnmadd_ps(x, r, set1(2.0f)));
}

/// 1 / sqrt(x) to about 23 bits (rsqrt + one Newton step); x > 0.
POSTHASTE_AVX2_INLINE V rsqrt(V x)
{
    const V r = _mm256_rsqrt_ps(x);
    const V xr2 = _mm256_mul_ps(_mm256_mul_ps(x, r), r);
    return _mm256_mul_ps(_mm256_mul_ps(set1(0.5f), r), _mm256_sub_ps(set1(3.0f), xr2));
}

/// Sum of the eight lanes.
POSTHASTE_AVX2_INLINE float hsum(V x)
{
    __m128 s = _mm_add_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    s = _mm_add_ps(s, _mm_movehl_ps(s, s));
    s = _mm_add_ss(s, _mm_movehdup_ps(s));
    return _mm_cvtss_f32(s);
}

}  // namespace posthaste::simd::v8

#endif
