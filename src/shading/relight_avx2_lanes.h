#pragma once
// The relight AVX2 rows' lane vocabulary (relight_avx2.cpp only): 8-lane arithmetic that rounds
// like the scalar reference, de-interleaving loads, the light-channel sums, the energy table
// lookup, toon masks and positions from depth.

#include <cstdint>

#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/relight_pixel.h"

#if POSTHASTE_HAVE_AVX2_TARGET
namespace posthaste::shading::relight {

using simd::v8::V;

// No FMA contraction (relight_avx2.cpp says why).
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif

POSTHASTE_AVX2_INLINE V vset(float x)
{
    return _mm256_set1_ps(x);
}
POSTHASTE_AVX2_INLINE V vadd(V a, V b)
{
    return _mm256_add_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vsub(V a, V b)
{
    return _mm256_sub_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vmul(V a, V b)
{
    return _mm256_mul_ps(a, b);
}
// a b + c with two roundings, like the scalar code (see the note on contraction above).
POSTHASTE_AVX2_INLINE V vfma(V a, V b, V c)
{
    return _mm256_add_ps(_mm256_mul_ps(a, b), c);
}
POSTHASTE_AVX2_INLINE V vdot(V ax, V ay, V az, V bx, V by, V bz)
{
    return vfma(ax, bx, vfma(ay, by, vmul(az, bz)));
}
// All-ones lanes where x is finite (not NaN, not +-inf).
POSTHASTE_AVX2_INLINE V finite_mask(V x)
{
    const V abs = _mm256_andnot_ps(vset(-0.0f), x);
    return _mm256_cmp_ps(abs, vset(std::numeric_limits<float>::infinity()), _CMP_LT_OQ);
}
POSTHASTE_AVX2_INLINE V select(V mask, V if_true, V if_false)
{
    return _mm256_blendv_ps(if_false, if_true, mask);
}

// Channels 0..2 of pixels x .. x + n - 1 (n <= 8) of row y, de-interleaved; missing lanes are 0.
POSTHASTE_AVX2_INLINE void load3x8(const Image &img, int x, int y, int n, V &a, V &b, V &c)
{
    const float *p = img.pixel(x, y);
    const int ch = img.channels();
    if (ch == 3 && n == 8) {
        // 24 floats x0 y0 z0 x1 ... as three 256-bit registers of 128-bit halves
        // [x0 y0 z0 x1 | x4 y4 z4 x5], [y1 z1 x2 y2 | y5 z5 x6 y6], [z2 x3 y3 z3 | z6 x7 y7 z7].
        const V m03 =
            _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 12), 1);
        const V m14 = _mm256_insertf128_ps(
            _mm256_castps128_ps256(_mm_loadu_ps(p + 4)), _mm_loadu_ps(p + 16), 1);
        const V m25 = _mm256_insertf128_ps(
            _mm256_castps128_ps256(_mm_loadu_ps(p + 8)), _mm_loadu_ps(p + 20), 1);
        const V xy = _mm256_shuffle_ps(m14, m25, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
        const V yz = _mm256_shuffle_ps(m03, m14, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
        a = _mm256_shuffle_ps(m03, xy, _MM_SHUFFLE(2, 0, 3, 0));
        b = _mm256_shuffle_ps(yz, xy, _MM_SHUFFLE(3, 1, 2, 0));
        c = _mm256_shuffle_ps(yz, m25, _MM_SHUFFLE(3, 0, 3, 1));
        return;
    }
    alignas(32) float t[3][8] = {};
    for (int i = 0; i < n; ++i) {
        t[0][i] = p[i * ch];
        t[1][i] = p[i * ch + 1];
        t[2][i] = p[i * ch + 2];
    }
    a = _mm256_load_ps(t[0]);
    b = _mm256_load_ps(t[1]);
    c = _mm256_load_ps(t[2]);
}

// Four registers of 8 lanes (one channel each) to four registers of two interleaved pixels
// each ([p0 | p1], [p2 | p3], [p4 | p5], [p6 | p7]); its own inverse up to the register order.
POSTHASTE_AVX2_INLINE void interleave4x8(V r, V g, V b, V a, V out[4])
{
    const V t0 = _mm256_unpacklo_ps(r, g), t1 = _mm256_unpackhi_ps(r, g);
    const V t2 = _mm256_unpacklo_ps(b, a), t3 = _mm256_unpackhi_ps(b, a);
    const V u0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));  // p0 | p4
    const V u1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));  // p1 | p5
    const V u2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));  // p2 | p6
    const V u3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));  // p3 | p7
    out[0] = _mm256_permute2f128_ps(u0, u1, 0x20);
    out[1] = _mm256_permute2f128_ps(u2, u3, 0x20);
    out[2] = _mm256_permute2f128_ps(u0, u1, 0x31);
    out[3] = _mm256_permute2f128_ps(u2, u3, 0x31);
}

// One channel of a light's contribution: (kd dfac + F spec) e, clamped, zero where unlit;
// f1 = 1 - f0.
POSTHASTE_AVX2_INLINE V light_channel(V f0, V f1, V kd, V e, V m5, V dfac, V spec, V lit, V clamp_v)
{
    const V f = vfma(f1, m5, f0);
    const V c = vmul(vfma(kd, dfac, vmul(f, spec)), e);
    return _mm256_and_ps(lit, _mm256_min_ps(c, clamp_v));
}

// The same with the multiple-scattering lobe `ms` (already times n.l) added to the BRDF.
POSTHASTE_AVX2_INLINE V
light_channel_ms(V f0, V f1, V kd, V e, V m5, V dfac, V spec, V ms, V lit, V clamp_v)
{
    const V f = vfma(f1, m5, f0);
    const V c = vmul(vadd(vfma(kd, dfac, vmul(f, spec)), ms), e);
    return _mm256_and_ps(lit, _mm256_min_ps(c, clamp_v));
}

// The coloured term of shading::multiscatter, F_avg^2 E_avg / (1 - F_avg (1 - E_avg)) with
// Schlick's F_avg = (20 F0 + 1) / 21.
POSTHASTE_AVX2_INLINE V ms_colour(V f0, V e_avg)
{
    const V one = vset(1.0f);
    const V f_avg = _mm256_div_ps(vadd(vmul(vset(20.0f), f0), one), vset(21.0f));
    return _mm256_div_ps(vmul(vmul(f_avg, f_avg), e_avg), vsub(one, vmul(f_avg, vsub(one, e_avg))));
}

// EnergyTable::lookup_e for 8 lanes at mu = min(n.l, 1), the roughness row `row0` (j0 kMu) and
// its weight tr fixed per pixel. Unlit lanes (n.l <= 0 or NaN) read a clamped, valid entry.
POSTHASTE_AVX2_INLINE V energy_e(const shading::EnergyTable &t, __m256i row0, V tr, V nl)
{
    constexpr int kMu = shading::EnergyTable::kMu;
    const V mu = _mm256_min_ps(nl, vset(1.0f));
    // max(x, 0) returns 0 for a NaN x (the second operand).
    const V fm = _mm256_min_ps(
        _mm256_max_ps(vsub(vmul(mu, vset(float(kMu))), vset(0.5f)), _mm256_setzero_ps()),
        vset(float(kMu - 1)));
    const __m256i i0 = _mm256_min_epi32(_mm256_cvttps_epi32(fm), _mm256_set1_epi32(kMu - 2));
    const V tm = vsub(fm, _mm256_cvtepi32_ps(i0));
    const __m256i idx = _mm256_add_epi32(row0, i0);
    const float *e = t.e.data();
    const V r00 = _mm256_i32gather_ps(e, idx, 4), r01 = _mm256_i32gather_ps(e + 1, idx, 4);
    const V r10 = _mm256_i32gather_ps(e + kMu, idx, 4),
            r11 = _mm256_i32gather_ps(e + kMu + 1, idx, 4);
    const V a = vadd(r00, vmul(vsub(r01, r00), tm));
    const V b = vadd(r10, vmul(vsub(r11, r10), tm));
    return vadd(a, vmul(vsub(b, a), tr));
}

// Lanes whose bit is set in `bits`, as an all-ones mask.
POSTHASTE_AVX2_INLINE V mask_from_bits(int bits)
{
    const __m256i b =
        _mm256_and_si256(_mm256_set1_epi32(bits), _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128));
    return _mm256_castsi256_ps(_mm256_cmpgt_epi32(b, _mm256_setzero_si256()));
}

// Lanes whose material id (rounded) is a toon id: bit i of the 256-bit set `bits` (8 words).
POSTHASTE_AVX2_INLINE V toon_mask(const Image &id, int x, int y, int n, __m256i bits)
{
    V m;
    if (id.channels() == 1 && n == 8) {
        m = _mm256_loadu_ps(id.pixel(x, y));
    } else {
        alignas(32) float t[8] = {};
        for (int i = 0; i < n; ++i) {
            t[i] = id.at(x + i, y, 0);
        }
        m = _mm256_load_ps(t);
    }
    // As prepare_pixel: ids in [0.5, 255.5) round to 1..255; the rest (and NaN) are not toon.
    const V in_range = _mm256_and_ps(_mm256_cmp_ps(m, vset(0.5f), _CMP_GE_OQ),
                                     _mm256_cmp_ps(m, vset(255.5f), _CMP_LT_OQ));
    const __m256i k = _mm256_cvttps_epi32(_mm256_and_ps(in_range, vadd(m, vset(0.5f))));
    const __m256i word = _mm256_permutevar8x32_epi32(bits, _mm256_srli_epi32(k, 5));
    const __m256i bit = _mm256_and_si256(
        _mm256_srlv_epi32(word, _mm256_and_si256(k, _mm256_set1_epi32(31))), _mm256_set1_epi32(1));
    return _mm256_and_ps(in_range,
                         _mm256_castsi256_ps(_mm256_cmpeq_epi32(bit, _mm256_set1_epi32(1))));
}

// World positions of 8 pixels from depth, as prepare_pixel: the 2x2 solve of the NDC equations
// for the camera point (X, Y, z, 1), then camera to world. `ok` clears lanes with an infinite
// depth (background) or a singular system.
POSTHASTE_AVX2_INLINE void position_from_depth(
    const Inputs &sh, int x, int y, int n, V &px, V &py, V &pz, V &ok)
{
    const Image &depth = *sh.depth;
    alignas(32) float zs[8] = {};
    for (int i = 0; i < n; ++i) {
        zs[i] = depth.at(x + i, y, 0);
    }
    const V z = _mm256_load_ps(zs);
    const V xs = vadd(vset(float(x)), _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7));
    const V u = _mm256_div_ps(vadd(xs, vset(0.5f)), vset(float(sh.width)));
    const float v = (float(y) + 0.5f) / float(sh.height);
    const glm::mat4 &m = sh.cam_to_ndc;
    const V a00 = vsub(vset(m[0][0]), vmul(u, vset(m[0][3])));
    const V a01 = vsub(vset(m[1][0]), vmul(u, vset(m[1][3])));
    const V a10 = vset(m[0][1] - v * m[0][3]), a11 = vset(m[1][1] - v * m[1][3]);
    const V b0 = _mm256_xor_ps(
        vset(-0.0f),
        vsub(vadd(vmul(vsub(vset(m[2][0]), vmul(u, vset(m[2][3]))), z), vset(m[3][0])),
             vmul(u, vset(m[3][3]))));
    const V b1 = _mm256_xor_ps(
        vset(-0.0f),
        vsub(vadd(vmul(vset(m[2][1] - v * m[2][3]), z), vset(m[3][1])), vset(v * m[3][3])));
    const V det = vsub(vmul(a00, a11), vmul(a01, a10));
    ok = _mm256_and_ps(finite_mask(z), _mm256_cmp_ps(det, _mm256_setzero_ps(), _CMP_NEQ_UQ));
    const V d = select(ok, det, vset(1.0f));
    const V qx = _mm256_div_ps(vsub(vmul(b0, a11), vmul(a01, b1)), d);
    const V qy = _mm256_div_ps(vsub(vmul(a00, b1), vmul(a10, b0)), d);
    const glm::mat4 &c = sh.c2w;
    px = vadd(vadd(vadd(vmul(vset(c[0][0]), qx), vmul(vset(c[1][0]), qy)), vmul(vset(c[2][0]), z)),
              vset(c[3][0]));
    py = vadd(vadd(vadd(vmul(vset(c[0][1]), qx), vmul(vset(c[1][1]), qy)), vmul(vset(c[2][1]), z)),
              vset(c[3][1]));
    pz = vadd(vadd(vadd(vmul(vset(c[0][2]), qx), vmul(vset(c[1][2]), qy)), vmul(vset(c[2][2]), z)),
              vset(c[3][2]));
}

#if !defined(__clang__)
#pragma GCC pop_options
#endif

}  // namespace posthaste::shading::relight
#endif
