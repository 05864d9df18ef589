#pragma once
// The hatching kernel's AVX2 lane vocabulary (hatch_avx2.cpp only): 8-lane arithmetic that
// rounds like the scalar path, the tone curve and TAM lookups, de-interleaving loads and
// stores, the edge tests on sample planes and the triplanar ink.

#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>

#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/hatch_kernel.h"

#if POSTHASTE_HAVE_AVX2_TARGET
namespace posthaste::shading::hatch_detail {

// No FMA contraction: the lanes mirror the scalar path operation by operation (hatch_avx2.cpp
// says why).
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif

namespace v8 = simd::v8;
using v8::V;
using v8::VI;

// Local 8-lane helpers. HatchingSimd.Avx2MatchesScalarOnRenderedFrame checks that both paths
// give the same values.

POSTHASTE_AVX2_INLINE V add(V a, V b)
{
    return _mm256_add_ps(a, b);
}
POSTHASTE_AVX2_INLINE V sub(V a, V b)
{
    return _mm256_sub_ps(a, b);
}
POSTHASTE_AVX2_INLINE V mul(V a, V b)
{
    return _mm256_mul_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vand(V a, V b)
{
    return _mm256_and_ps(a, b);
}
POSTHASTE_AVX2_INLINE V vor(V a, V b)
{
    return _mm256_or_ps(a, b);
}
/// a and not b.
POSTHASTE_AVX2_INLINE V andnot(V a, V b)
{
    return _mm256_andnot_ps(b, a);
}
/// m ? b : a, per lane (m all ones or all zeros).
POSTHASTE_AVX2_INLINE V select(V m, V b, V a)
{
    return _mm256_blendv_ps(a, b, m);
}
POSTHASTE_AVX2_INLINE V vabs(V a)
{
    return _mm256_and_ps(a, _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff)));
}
POSTHASTE_AVX2_INLINE V finite_v(V a)
{
    return _mm256_cmp_ps(_mm256_sub_ps(a, a), _mm256_setzero_ps(), _CMP_EQ_OQ);
}
POSTHASTE_AVX2_INLINE V ld(const float *p)
{
    return _mm256_loadu_ps(p);
}
POSTHASTE_AVX2_INLINE V dot3(V ax, V ay, V az, V bx, V by, V bz)
{
    return add(add(mul(ax, bx), mul(ay, by)), mul(az, bz));  // glm's order: (x + y) + z
}

/// fast_log2 on eight lanes, same operations.
POSTHASTE_AVX2_INLINE V fast_log2_v(V x)
{
    const VI bits = _mm256_castps_si256(x);
    const V e = _mm256_cvtepi32_ps(
        _mm256_sub_epi32(_mm256_and_si256(_mm256_srli_epi32(bits, 23), _mm256_set1_epi32(0xff)),
                         _mm256_set1_epi32(127)));
    const V m = _mm256_castsi256_ps(_mm256_or_si256(
        _mm256_and_si256(bits, _mm256_set1_epi32(0x007fffff)), _mm256_set1_epi32(0x3f800000)));
    const V t = sub(m, v8::set1(1.0f));
    return add(e, mul(t, sub(v8::set1(1.3466f), mul(v8::set1(0.3466f), t))));
}

/// Two adjacent floats at a (low 64 bits) and at b (high 64 bits).
POSTHASTE_AVX2_INLINE __m128i load_two_pairs(const float *a, const float *b)
{
    std::uint64_t x, y;
    std::memcpy(&x, a, 8);
    std::memcpy(&y, b, 8);
    return _mm_insert_epi64(_mm_cvtsi64_si128(std::int64_t(x)), std::int64_t(y), 1);
}

/// Loads the float pairs (base[i], base[i + 1]) of eight float indices i: a gets the first,
/// b the second. Scalar 64-bit loads: as fast as vgatherdpd on the development machine, and not
/// at the mercy of gather microcode mitigations elsewhere.
POSTHASTE_AVX2_INLINE void gather_pairs(const float *base, VI idx, V &a, V &b)
{
    alignas(32) std::int32_t i[8];
    _mm256_store_si256(reinterpret_cast<VI *>(i), idx);
    // Pixels 0, 1, 4, 5 in lo and 2, 3, 6, 7 in hi, so that the shuffles below put the pairs
    // back in lane order.
    const VI lo =
        _mm256_inserti128_si256(_mm256_castsi128_si256(load_two_pairs(base + i[0], base + i[1])),
                                load_two_pairs(base + i[4], base + i[5]),
                                1);
    const VI hi =
        _mm256_inserti128_si256(_mm256_castsi128_si256(load_two_pairs(base + i[2], base + i[3])),
                                load_two_pairs(base + i[6], base + i[7]),
                                1);
    a = _mm256_shuffle_ps(
        _mm256_castsi256_ps(lo), _mm256_castsi256_ps(hi), _MM_SHUFFLE(2, 0, 2, 0));
    b = _mm256_shuffle_ps(
        _mm256_castsi256_ps(lo), _mm256_castsi256_ps(hi), _MM_SHUFFLE(3, 1, 3, 1));
}

/// ToneCurve::operator() on eight lanes.
POSTHASTE_AVX2_INLINE V tone_curve_v(const float *table, V linear)
{
    const V nan = _mm256_cmp_ps(linear, linear, _CMP_UNORD_Q);
    const V c = v8::clamp(linear, _mm256_setzero_ps(), v8::set1(1.0f));
    const V q = mul(_mm256_sqrt_ps(c), v8::set1(float(ToneCurve::kSegments)));
    const VI i =
        _mm256_min_epi32(_mm256_cvttps_epi32(q), _mm256_set1_epi32(ToneCurve::kSegments - 1));
    const V f = sub(q, _mm256_cvtepi32_ps(i));
    V t0, t1;
    gather_pairs(table, _mm256_andnot_si256(_mm256_castps_si256(nan), i), t0, t1);
    return select(nan, v8::set1(1.0f), add(t0, mul(f, sub(t1, t0))));
}

/// Ramp entries k and k + 1 of texel row + col of packed texels, blended by f.
POSTHASTE_AVX2_INLINE V texel_v(const float *packed, VI row, VI col, VI k, V f)
{
    static_assert(Tam::kPacked == 8, "the shift below multiplies by kPacked");
    const VI i = _mm256_add_epi32(_mm256_slli_epi32(_mm256_add_epi32(row, col), 3), k);
    V a, b;
    gather_pairs(packed, i, a, b);
    return add(a, mul(f, sub(b, a)));
}

/// Tam::ramp_level on eight lanes (per-lane level, ramp entry k and blend f).
POSTHASTE_AVX2_INLINE V
ramp_level_v(const float *packed, int size, VI level, VI k, V f, VI fu, VI fv)
{
    const VI one = _mm256_set1_epi32(1);
    const VI s = _mm256_srlv_epi32(_mm256_set1_epi32(size), level);
    const VI mask = _mm256_sub_epi32(s, one);
    const VI half = _mm256_set1_epi32(32768), frac = _mm256_set1_epi32(0xffff);
    const VI x = _mm256_sub_epi32(_mm256_srav_epi32(fu, level), half);
    const VI y = _mm256_sub_epi32(_mm256_srav_epi32(fv, level), half);
    const VI x0 = _mm256_and_si256(_mm256_srai_epi32(x, 16), mask);
    const VI y0 = _mm256_and_si256(_mm256_srai_epi32(y, 16), mask);
    const V inv = v8::set1(1.0f / 65536.0f);
    const V fx = mul(_mm256_cvtepi32_ps(_mm256_and_si256(x, frac)), inv);
    const V fy = mul(_mm256_cvtepi32_ps(_mm256_and_si256(y, frac)), inv);
    const VI x1 = _mm256_and_si256(_mm256_add_epi32(x0, one), mask);
    const VI y1 = _mm256_and_si256(_mm256_add_epi32(y0, one), mask);
    // First texel of the level: sum of (size >> j)^2 for j < level = 4 (size^2 - s^2) / 3,
    // divided exactly by multiplying with the inverse of 3 modulo 2^32.
    const VI sz = _mm256_set1_epi32(size);
    const VI base = _mm256_mullo_epi32(
        _mm256_slli_epi32(_mm256_sub_epi32(_mm256_mullo_epi32(sz, sz), _mm256_mullo_epi32(s, s)),
                          2),
        _mm256_set1_epi32(int(0xaaaaaaabu)));
    const VI row0 = _mm256_add_epi32(base, _mm256_mullo_epi32(y0, s));
    const VI row1 = _mm256_add_epi32(base, _mm256_mullo_epi32(y1, s));
    const V t00 = texel_v(packed, row0, x0, k, f), t10 = texel_v(packed, row0, x1, k, f);
    const V t01 = texel_v(packed, row1, x0, k, f), t11 = texel_v(packed, row1, x1, k, f);
    const V a = add(t00, mul(fx, sub(t10, t00)));
    const V c = add(t01, mul(fx, sub(t11, t01)));
    return add(a, mul(fy, sub(c, a)));
}

/// Tam::ramp on eight lanes; lanes outside `live` (or with darkness <= 0) give 0.
POSTHASTE_AVX2_INLINE V ramp_v(const Tam &tam, V live, V d, V u, V v, V lod)
{
    const V active = vand(live, _mm256_cmp_ps(d, _mm256_setzero_ps(), _CMP_GT_OQ));
    if (_mm256_testz_ps(active, active)) {
        return _mm256_setzero_ps();
    }
    const V sv = mul(_mm256_min_ps(d, v8::set1(1.0f)), v8::set1(float(kTamTones)));
    // max with 0: inactive lanes (darkness <= 0 or NaN) must still address valid texels.
    const VI k = _mm256_max_epi32(
        _mm256_min_epi32(_mm256_cvttps_epi32(sv), _mm256_set1_epi32(kTamTones - 1)),
        _mm256_setzero_si256());
    const V f = sub(sv, _mm256_cvtepi32_ps(k));
    // ramp_at: NaN lod reads the coarsest level.
    const float top = float(tam.levels() - 1);
    V l = v8::clamp(lod, _mm256_setzero_ps(), v8::set1(top));
    l = select(_mm256_cmp_ps(lod, lod, _CMP_UNORD_Q), v8::set1(top), l);
    const VI l0 = _mm256_cvttps_epi32(l);
    const V fl = sub(l, _mm256_cvtepi32_ps(l0));
    u = sub(u, _mm256_floor_ps(u));
    v = sub(v, _mm256_floor_ps(v));
    const V one = v8::set1(float(tam.size()) * 65536.0f);
    const VI fu = _mm256_cvttps_epi32(mul(u, one)), fv = _mm256_cvttps_epi32(mul(v, one));
    const V b = v8::clamp(
        sub(mul(v8::set1(2.0f), fl), v8::set1(0.5f)), _mm256_setzero_ps(), v8::set1(1.0f));
    const V only0 = _mm256_cmp_ps(b, _mm256_setzero_ps(), _CMP_LE_OQ);
    const V only1 = _mm256_cmp_ps(b, v8::set1(1.0f), _CMP_GE_OQ);
    const V need0 = andnot(active, only1), need1 = andnot(active, only0);
    V c0 = _mm256_setzero_ps(), c1 = _mm256_setzero_ps();
    if (!_mm256_testz_ps(need0, need0)) {
        c0 = ramp_level_v(tam.packed(), tam.size(), l0, k, f, fu, fv);
    }
    if (!_mm256_testz_ps(need1, need1)) {
        const VI l1 = _mm256_min_epi32(_mm256_add_epi32(l0, _mm256_set1_epi32(1)),
                                       _mm256_set1_epi32(tam.levels() - 1));
        c1 = ramp_level_v(tam.packed(), tam.size(), l1, k, f, fu, fv);
    }
    const V r = select(only0, c0, select(only1, c1, add(c0, mul(b, sub(c1, c0)))));
    return vand(active, r);
}

/// Eight packed xyz pixels (24 floats) into three planes.
POSTHASTE_AVX2_INLINE void load_xyz8(const float *p, V &x, V &y, V &z)
{
    // Per 128-bit half: m03 = x0 y0 z0 x1, m14 = y1 z1 x2 y2, m25 = z2 x3 y3 z3 (pixels 0-3
    // low, 4-7 high).
    const V m03 =
        _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 12), 1);
    const V m14 =
        _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 4)), _mm_loadu_ps(p + 16), 1);
    const V m25 =
        _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 8)), _mm_loadu_ps(p + 20), 1);
    const V xy = _mm256_shuffle_ps(m14, m25, _MM_SHUFFLE(2, 1, 3, 2));  // x2 y2 x3 y3
    const V yz = _mm256_shuffle_ps(m03, m14, _MM_SHUFFLE(1, 0, 2, 1));  // y0 z0 y1 z1
    x = _mm256_shuffle_ps(m03, xy, _MM_SHUFFLE(2, 0, 3, 0));
    y = _mm256_shuffle_ps(yz, xy, _MM_SHUFFLE(3, 1, 2, 0));
    z = _mm256_shuffle_ps(yz, m25, _MM_SHUFFLE(3, 0, 3, 1));
}

/// Pixel i (4 floats at p) in the low half, pixel i + 4 in the high half.
POSTHASTE_AVX2_INLINE V load_pair(const float *p)
{
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 16), 1);
}

/// Eight RGBA pixels (32 floats) into four planes.
POSTHASTE_AVX2_INLINE void load_rgba8(const float *p, V &r, V &g, V &b, V &a)
{
    const V m0 = load_pair(p), m1 = load_pair(p + 4), m2 = load_pair(p + 8), m3 = load_pair(p + 12);
    const V t0 = _mm256_unpacklo_ps(m0, m1), t1 = _mm256_unpackhi_ps(m0, m1);  // r0 r1 g0 g1
    const V t2 = _mm256_unpacklo_ps(m2, m3), t3 = _mm256_unpackhi_ps(m2, m3);  // b2 b3 a2 a3
    r = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));
    g = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
    b = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));
    a = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
}

/// Four planes into eight RGBA pixels (32 floats).
POSTHASTE_AVX2_INLINE void store_rgba8(float *p, V r, V g, V b, V a)
{
    const V t0 = _mm256_unpacklo_ps(r, g), t1 = _mm256_unpacklo_ps(b, a);  // r0 g0 r1 g1
    const V t2 = _mm256_unpackhi_ps(r, g), t3 = _mm256_unpackhi_ps(b, a);  // r2 g2 r3 g3
    const V p0 = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0));       // pixel 0 | 4
    const V p1 = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2));       // pixel 1 | 5
    const V p2 = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0));       // pixel 2 | 6
    const V p3 = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2));       // pixel 3 | 7
    _mm256_storeu_ps(p, _mm256_permute2f128_ps(p0, p1, 0x20));
    _mm256_storeu_ps(p + 8, _mm256_permute2f128_ps(p2, p3, 0x20));
    _mm256_storeu_ps(p + 16, _mm256_permute2f128_ps(p0, p1, 0x31));
    _mm256_storeu_ps(p + 24, _mm256_permute2f128_ps(p2, p3, 0x31));
}

/// store_rgba8 with non-temporal 16-byte stores (p 16-byte aligned): the output is written
/// once and not read again here, so it need not be read into the cache first.
POSTHASTE_AVX2_INLINE void stream_rgba8(float *p, V r, V g, V b, V a)
{
    const V t0 = _mm256_unpacklo_ps(r, g), t1 = _mm256_unpacklo_ps(b, a);
    const V t2 = _mm256_unpackhi_ps(r, g), t3 = _mm256_unpackhi_ps(b, a);
    const V q[4] = {_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0)),
                    _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2)),
                    _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0)),
                    _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2))};  // pixel j | j + 4
    for (int j = 0; j < 4; ++j) {
        _mm_stream_ps(p + 4 * j, _mm256_castps256_ps128(q[j]));
        _mm_stream_ps(p + 16 + 4 * j, _mm256_extractf128_ps(q[j], 1));
    }
}

/// Tile-local planes of the AVX2 kernel, in one buffer: samples over the tile plus the outline
/// reach plus one pixel, with coordinates clamped to the image (at the border the pixel stands
/// in for its missing neighbour, as in the scalar path), and edge flags.
enum Plane { kZ, kPx, kPy, kPz, kNx, kNy, kNz, kHit, kNrm, kEdge, kPlaneCount };

/// A pixel's samples, eight lanes.
struct SampleV {
    V z, px, py, pz, nx, ny, nz, hit, nrm;
};

POSTHASTE_AVX2_INLINE SampleV load_sample(const float *buf, std::size_t plane, std::size_t i)
{
    const float *p = buf + i;
    return {ld(p + kZ * plane),
            ld(p + kPx * plane),
            ld(p + kPy * plane),
            ld(p + kPz * plane),
            ld(p + kNx * plane),
            ld(p + kNy * plane),
            ld(p + kNz * plane),
            ld(p + kHit * plane),
            ld(p + kNrm * plane)};
}

/// is_edge on eight lanes, without the c.hit test (the caller masks by it).
POSTHASTE_AVX2_INLINE V
is_edge_v(const SampleV &c, const SampleV &q, bool q_after, V dt_z, V cos_thr)
{
    const V dn = dot3(c.nx, c.ny, c.nz, sub(q.px, c.px), sub(q.py, c.py), sub(q.pz, c.pz));
    const V gap = select(c.nrm, vabs(dn), vabs(sub(q.z, c.z)));
    const V far = _mm256_cmp_ps(gap, dt_z, _CMP_GT_OQ);
    const V nearer = _mm256_cmp_ps(c.z, q.z, _CMP_LE_OQ);
    V crease = _mm256_setzero_ps();
    if (q_after) {
        const V cn = dot3(c.nx, c.ny, c.nz, q.nx, q.ny, q.nz);
        crease = vand(vand(c.nrm, q.nrm), _mm256_cmp_ps(cn, cos_thr, _CMP_LT_OQ));
    }
    return vor(andnot(c.hit, q.hit), vand(q.hit, select(far, nearer, crease)));
}

/// neighbour_step on eight lanes: mask, and the step in sx, sy, sz.
POSTHASTE_AVX2_INLINE V neighbour_step_v(const SampleV &c, const SampleV &q, V &sx, V &sy, V &sz)
{
    const V cn = dot3(c.nx, c.ny, c.nz, q.nx, q.ny, q.nz);
    V ok = vand(vand(q.hit, q.nrm), _mm256_cmp_ps(cn, v8::set1(0.7f), _CMP_NLT_UQ));
    sx = sub(q.px, c.px);
    sy = sub(q.py, c.py);
    sz = sub(q.pz, c.pz);
    return vand(ok, _mm256_cmp_ps(dot3(sx, sy, sz, sx, sy, sz), _mm256_setzero_ps(), _CMP_GT_OQ));
}

/// pick_step on eight lanes.
POSTHASTE_AVX2_INLINE V
pick_step_v(const SampleV &c, const SampleV &a, const SampleV &b, V &x, V &y, V &z)
{
    V ax, ay, az, bx, by, bz;
    const V ha = neighbour_step_v(c, a, ax, ay, az), hb = neighbour_step_v(c, b, bx, by, bz);
    const V la = dot3(ax, ay, az, ax, ay, az), lb = dot3(bx, by, bz, bx, by, bz);
    const V take_a = vand(ha,
                          vor(andnot(_mm256_castsi256_ps(_mm256_set1_epi32(-1)), hb),
                              _mm256_cmp_ps(la, lb, _CMP_LE_OQ)));
    x = select(take_a, ax, bx);
    y = select(take_a, ay, by);
    z = select(take_a, az, bz);
    return vor(ha, hb);
}

/// Three lanes-of-8 vectors (x, y, z).
struct V3 {
    V v[3];
};

/// Mip level from the world steps to the x and y neighbours projected on a plane (u, v
/// components), as the scalar path: 0.5 log2(max |step|^2) + log2(texels per metre).
POSTHASTE_AVX2_INLINE V plane_lod(const KernelCtx &k, V ux, V vx, V uy, V vy)
{
    const V len2 = _mm256_max_ps(add(mul(uy, uy), mul(vy, vy)), add(mul(ux, ux), mul(vx, vx)));
    return add(mul(v8::set1(0.5f), fast_log2_v(_mm256_max_ps(v8::set1(1e-30f), len2))),
               v8::set1(k.lod_offset));
}

/// Three planar lookups blended by max(|n_i| - 0.2, 0)^sharpness (normalised); lanes without a
/// usable normal (`flat`) take the flat tone, sky lanes 0. The weights use the 8-lane pow (about
/// 2 ulp) where the scalar path calls std::pow, so this is the one part of the kernel that is not
/// bit-equal to it (HatchingSimd states the tolerance).
POSTHASTE_AVX2_INLINE V triplanar_ink(const KernelCtx &k,
                                      const SampleV &c,
                                      V flat,
                                      V footprint,
                                      V darkness,
                                      const V3 &an,
                                      const V3 &dpx,
                                      const V3 &dpy)
{
    const V zero = _mm256_setzero_ps(), ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    V w[3];
    for (int a = 0; a < 3; ++a) {
        const V x = _mm256_max_ps(sub(an.v[a], v8::set1(0.2f)), zero);
        const V pos = _mm256_cmp_ps(x, zero, _CMP_GT_OQ);
        // v8::pow takes x > 0 only; pow(0, sharpness) comes from std::pow once.
        w[a] = select(pos,
                      v8::pow(select(pos, x, v8::set1(1.0f)), v8::set1(k.triplanar_sharpness)),
                      v8::set1(k.zero_pow));
    }
    const V sum = add(add(w[0], w[1]), w[2]);
    const V surface = andnot(c.hit, flat);
    const V p[3] = {c.px, c.py, c.pz};
    static constexpr int kU[3] = {2, 0, 0}, kV[3] = {1, 2, 1};
    const V no_footprint = andnot(ones, footprint);
    V ink = zero;
    for (int a = 0; a < 3; ++a) {
        const V wa = _mm256_div_ps(w[a], sum);
        const int iu = kU[a], iv = kV[a];
        const V lod = select(no_footprint,
                             v8::set1(k.flat_lod),
                             plane_lod(k, dpx.v[iu], dpx.v[iv], dpy.v[iu], dpy.v[iv]));
        const V live = vand(surface, _mm256_cmp_ps(wa, zero, _CMP_GT_OQ));
        const V r = ramp_v(*k.tam,
                           live,
                           darkness,
                           mul(p[iu], v8::set1(k.inv_scale)),
                           mul(p[iv], v8::set1(k.inv_scale)),
                           lod);
        ink = add(ink, vand(live, mul(wa, r)));
    }
    const V flat_ink = ramp_v(*k.tam, flat, darkness, zero, zero, v8::set1(k.flat_lod));
    return vand(c.hit, select(flat, flat_ink, ink));
}

#if !defined(__clang__)
#pragma GCC pop_options
#endif

}  // namespace posthaste::shading::hatch_detail
#endif
