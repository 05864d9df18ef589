#include "shading/hatch.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"

namespace posthaste::shading {
namespace {

constexpr float kPiF = 3.14159265358979323846f;

/// log2(x) for x > 0 within 0.005, continuous and increasing: exponent plus a quadratic on the
/// mantissa (exact at powers of two). For mip levels, where libm's log2f was a hot spot.
inline float fast_log2(float x)
{
    std::uint32_t bits;
    std::memcpy(&bits, &x, 4);
    const float e = float(int((bits >> 23) & 0xffu) - 127);
    bits = (bits & 0x007fffffu) | 0x3f800000u;  // mantissa in [1, 2)
    float m;
    std::memcpy(&m, &bits, 4);
    const float t = m - 1.0f;
    return e + t * (1.3466f - 0.3466f * t);
}

/// Per-pixel surface facts read from the passes.
struct Sample {
    bool hit = false;     ///< Finite positive depth and finite position.
    bool normal = false;  ///< hit and a usable (finite, non-zero) normal.
    float z = 0.0f;
    glm::vec3 p{0.0f}, n{0.0f};
};

/// x is finite (not NaN, not +-inf); cheaper than std::isfinite on three values.
inline bool finite_f(float x)
{
    return x - x == 0.0f;
}

Sample read_sample(const float *z_px, const float *p_px, const float *n_px)
{
    Sample s;
    const float z = *z_px;
    if (!(z > 0.0f && finite_f(z) && finite_f(p_px[0] + p_px[1] + p_px[2]))) {
        return s;  // sky, or unusable geometry
    }
    s.hit = true;
    s.z = z;
    s.p = {p_px[0], p_px[1], p_px[2]};
    const glm::vec3 nv{n_px[0], n_px[1], n_px[2]};
    const float len2 = glm::dot(nv, nv);
    if (len2 > 1e-4f && finite_f(len2)) {
        s.normal = true;
        s.n = std::abs(len2 - 1.0f) < 1e-4f ? nv : nv / std::sqrt(len2);
    }
    return s;
}

/// Whether pixel p carries an outline against neighbour q (one side only, so lines stay thin).
inline bool is_edge(const Sample &p, const Sample &q, bool q_after, float depth_thr, float cos_thr)
{
    if (!p.hit) {
        return false;
    }
    if (!q.hit) {
        return true;  // silhouette against the sky
    }
    const float gap = p.normal ? std::abs(glm::dot(p.n, q.p - p.p)) : std::abs(q.z - p.z);
    if (gap > depth_thr * p.z) {
        return p.z <= q.z;  // the nearer side draws the line
    }
    return q_after && p.normal && q.normal && glm::dot(p.n, q.n) < cos_thr;
}

/// World-space step to a neighbour usable for footprints: on the same smooth surface.
bool neighbour_step(const Sample &c, const Sample &q, glm::vec3 &step)
{
    if (!q.hit || !q.normal || glm::dot(c.n, q.n) < 0.7f) {
        return false;
    }
    step = q.p - c.p;
    return glm::dot(step, step) > 0.0f;  // at image borders the pixel stands in for q
}

/// The smaller of the forward and backward steps that are usable (central pixel c).
bool pick_step(const Sample &c, const Sample &a, const Sample &b, glm::vec3 &step)
{
    glm::vec3 sa, sb;
    const bool ha = neighbour_step(c, a, sa), hb = neighbour_step(c, b, sb);
    if (ha && hb) {
        step = glm::dot(sa, sa) <= glm::dot(sb, sb) ? sa : sb;
    } else if (ha || hb) {
        step = ha ? sa : sb;
    }
    return ha || hb;
}

/// Outline pen: coverage clamp(r + 1 - dist, 0, 1) of an edge pixel at offset (dx, dy).
struct LineTap {
    int dx, dy;
    float coverage;
};

/// Everything the per-tile kernels need, computed once per frame.
struct KernelCtx {
    const Image *color, *depth, *normal, *position;
    Image *out;
    const Tam *tam;
    const ToneCurve *curve;
    const LineTap *taps;
    int tap_count;
    int line_reach;
    bool screen_space, tone_from_light, partial_mix, needs_samples;
    float depth_threshold, cos_thr, inv_scale, lod_offset, flat_lod, finest;
    float ambient, exposure, mix;
    glm::vec3 light, paper, ink_minus_paper, outline_color;
    bool triplanar;
    float triplanar_sharpness, zero_pow;  ///< zero_pow = std::pow(0, triplanar_sharpness)
    const Image *id;                      ///< With ids only.
    const std::vector<int> *ids;          ///< Hatch only these ids; null: everywhere.
};

#if POSTHASTE_HAVE_AVX2_TARGET
// The kernel below mirrors the scalar path operation by operation. GCC would fuse a * b + c of
// intrinsics into FMA (its C++ default is -ffp-contract=fast, and the scalar path, built for
// baseline x86-64, has no FMA), which rounds differently: keep the two paths equal.
#if defined(__GNUC__) && !defined(__clang__)
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif
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

/// Fills the sample planes of region r (stride `stride`, `rows` rows) from the passes.
POSTHASTE_AVX2 void fill_samples_avx2(
    const KernelCtx &k, const Rect &r, int stride, float *buf, std::size_t plane)
{
    const int w = k.color->width(), h = k.color->height();
    const int zs = k.depth->channels(), ps = k.position->channels(), ns = k.normal->channels();
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const V zero = _mm256_setzero_ps(), ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for (int row = 0; row < r.height(); ++row) {
        const int y = std::clamp(r.y0 + row, 0, h - 1);
        const float *zr = k.depth->pixel(0, y), *pr = k.position->pixel(0, y);
        const float *nr = k.normal->pixel(0, y);
        for (int col = 0; col < stride; col += 8) {
            const int x = r.x0 + col;
            V z, px, py, pz, nx, ny, nz;
            if (x >= 0 && x + 8 <= w && zs == 1 && ps == 3 && ns == 3) {
                z = ld(zr + x);
                load_xyz8(pr + 3 * std::size_t(x), px, py, pz);
                load_xyz8(nr + 3 * std::size_t(x), nx, ny, nz);
            } else {
                const VI xi =
                    _mm256_min_epi32(_mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane),
                                                      _mm256_setzero_si256()),
                                     _mm256_set1_epi32(w - 1));
                const VI zi = _mm256_mullo_epi32(xi, _mm256_set1_epi32(zs));
                const VI pi = _mm256_mullo_epi32(xi, _mm256_set1_epi32(ps));
                const VI ni = _mm256_mullo_epi32(xi, _mm256_set1_epi32(ns));
                const VI c1 = _mm256_set1_epi32(1), c2 = _mm256_set1_epi32(2);
                z = _mm256_i32gather_ps(zr, zi, 4);
                px = _mm256_i32gather_ps(pr, pi, 4);
                py = _mm256_i32gather_ps(pr, _mm256_add_epi32(pi, c1), 4);
                pz = _mm256_i32gather_ps(pr, _mm256_add_epi32(pi, c2), 4);
                nx = _mm256_i32gather_ps(nr, ni, 4);
                ny = _mm256_i32gather_ps(nr, _mm256_add_epi32(ni, c1), 4);
                nz = _mm256_i32gather_ps(nr, _mm256_add_epi32(ni, c2), 4);
            }
            // read_sample: hit = finite positive depth and finite position.
            const V hit = vand(vand(_mm256_cmp_ps(z, zero, _CMP_GT_OQ), finite_v(z)),
                               finite_v(add(add(px, py), pz)));
            const V len2 = dot3(nx, ny, nz, nx, ny, nz);
            const V nrm =
                vand(vand(hit, _mm256_cmp_ps(len2, v8::set1(1e-4f), _CMP_GT_OQ)), finite_v(len2));
            const V unit =
                _mm256_cmp_ps(vabs(sub(len2, v8::set1(1.0f))), v8::set1(1e-4f), _CMP_LT_OQ);
            const V rescale = andnot(nrm, unit);
            if (!_mm256_testz_ps(rescale, rescale)) {  // rendered normals are unit already
                const V root = _mm256_sqrt_ps(len2);
                nx = select(unit, nx, _mm256_div_ps(nx, root));
                ny = select(unit, ny, _mm256_div_ps(ny, root));
                nz = select(unit, nz, _mm256_div_ps(nz, root));
            }
            nx = vand(nrm, nx);
            ny = vand(nrm, ny);
            nz = vand(nrm, nz);
            float *o = buf + std::size_t(row) * std::size_t(stride) + std::size_t(col);
            _mm256_storeu_ps(o + kZ * plane, vand(hit, z));
            _mm256_storeu_ps(o + kPx * plane, vand(hit, px));
            _mm256_storeu_ps(o + kPy * plane, vand(hit, py));
            _mm256_storeu_ps(o + kPz * plane, vand(hit, pz));
            _mm256_storeu_ps(o + kNx * plane, nx);
            _mm256_storeu_ps(o + kNy * plane, ny);
            _mm256_storeu_ps(o + kNz * plane, nz);
            _mm256_storeu_ps(o + kHit * plane, vand(hit, ones));
            _mm256_storeu_ps(o + kNrm * plane, vand(nrm, ones));
        }
    }
}

/// One tile of hatch() with AVX2, eight pixels of a row at a time (mix > 0; the caller checks).
POSTHASTE_AVX2 void hatch_tile_avx2(const KernelCtx &k, const Rect &t)
{
    const Image &color = *k.color;
    const int w = color.width(), nc = color.channels();
    const Rect bounds = color.bounds();
    const Rect er = t.expand(k.line_reach);  // edge flags (zero outside the image)
    const Rect r = er.expand(1);             // samples
    const int stride = ((r.width() + 7) & ~7) + 8;
    const std::size_t plane = std::size_t(stride) * std::size_t(r.height());
    thread_local std::vector<float> tls_buf;
    tls_buf.resize(plane * kPlaneCount + 8);
    float *const buf = tls_buf.data();
    auto index = [&](int x, int y) {
        return std::size_t(y - r.y0) * std::size_t(stride) + std::size_t(x - r.x0);
    };
    const V zero = _mm256_setzero_ps(), ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const bool outlines = k.tap_count > 0;
    if (k.needs_samples) {
        fill_samples_avx2(k, r, stride, buf, plane);
    }
    float *const edges = buf + kEdge * plane;
    if (outlines) {
        std::fill(edges, edges + plane, 0.0f);
        const V cos_thr = v8::set1(k.cos_thr), dt = v8::set1(k.depth_threshold);
        const Rect eb = er.intersect(bounds);
        for (int y = eb.y0; y < eb.y1; ++y) {
            for (int x = eb.x0; x < eb.x1; x += 8) {
                const std::size_t i = index(x, y);
                const SampleV c = load_sample(buf, plane, i);
                if (_mm256_testz_ps(c.hit, c.hit)) {
                    continue;  // edges stay 0
                }
                const V dt_z = mul(dt, c.z);
                const V e = vor(
                    vor(is_edge_v(c, load_sample(buf, plane, i - 1), false, dt_z, cos_thr),
                        is_edge_v(c, load_sample(buf, plane, i + 1), true, dt_z, cos_thr)),
                    vor(is_edge_v(c, load_sample(buf, plane, i - stride), false, dt_z, cos_thr),
                        is_edge_v(c, load_sample(buf, plane, i + stride), true, dt_z, cos_thr)));
                const V in = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                    _mm256_set1_epi32(eb.x1 - x), lane));  // lanes inside the image and er
                _mm256_storeu_ps(edges + i, vand(vand(c.hit, in), vand(e, ones)));
            }
        }
    }

    const float *table = k.curve->table();
    const Tam &tam = *k.tam;
    const V paper[3] = {v8::set1(k.paper.x), v8::set1(k.paper.y), v8::set1(k.paper.z)};
    const V imp[3] = {v8::set1(k.ink_minus_paper.x),
                      v8::set1(k.ink_minus_paper.y),
                      v8::set1(k.ink_minus_paper.z)};
    const V oc[3] = {
        v8::set1(k.outline_color.x), v8::set1(k.outline_color.y), v8::set1(k.outline_color.z)};
    const V one = v8::set1(1.0f), mix = v8::set1(k.mix), exposure = v8::set1(k.exposure);
    alignas(32) float stage[4][8];
    for (int y = t.y0; y < t.y1; ++y) {
        for (int x = t.x0; x < t.x1; x += 8) {
            const int n = std::min(8, t.x1 - x);
            const float *src = color.pixel(x, y);
            V cr, cg, cb, ca;
            if (nc == 4 && n == 8) {
                load_rgba8(src, cr, cg, cb, ca);
            } else {
                for (int j = 0; j < 8; ++j) {
                    const float *s = color.pixel(std::min(x + j, w - 1), y);
                    stage[0][j] = s[0];
                    stage[1][j] = s[1];
                    stage[2][j] = s[2];
                    stage[3][j] = nc >= 4 ? s[3] : 1.0f;
                }
                cr = _mm256_load_ps(stage[0]);
                cg = _mm256_load_ps(stage[1]);
                cb = _mm256_load_ps(stage[2]);
                ca = _mm256_load_ps(stage[3]);
            }
            const std::size_t i = index(x, y);
            SampleV c;
            if (k.needs_samples) {
                c = load_sample(buf, plane, i);
            } else {
                c = SampleV{zero, zero, zero, zero, zero, zero, zero, zero, zero};
            }
            // Tone (ToneCurve::tone or the n.l variant); darkness 0 where nothing is drawn (the
            // sky in surface mode), and no tone at all for eight such pixels.
            const V drawn = k.screen_space ? ones : c.hit;
            V darkness = zero;
            if (!_mm256_testz_ps(drawn, drawn)) {
                V tone;
                if (k.tone_from_light) {
                    const V nl = _mm256_max_ps(dot3(c.nx,
                                                    c.ny,
                                                    c.nz,
                                                    v8::set1(k.light.x),
                                                    v8::set1(k.light.y),
                                                    v8::set1(k.light.z)),
                                               zero);
                    const V lit = select(c.nrm, nl, one);
                    tone = tone_curve_v(
                        table,
                        mul(add(v8::set1(k.ambient), mul(v8::set1(1.0f - k.ambient), lit)),
                            exposure));
                } else {
                    V lum = add(add(mul(v8::set1(0.2126f), cr), mul(v8::set1(0.7152f), cg)),
                                mul(v8::set1(0.0722f), cb));
                    const V part = vand(_mm256_cmp_ps(ca, v8::set1(1e-6f), _CMP_GT_OQ),
                                        _mm256_cmp_ps(ca, one, _CMP_LT_OQ));
                    lum = select(part, _mm256_div_ps(lum, ca), lum);
                    tone = tone_curve_v(table, mul(lum, exposure));
                }
                darkness = vand(drawn, sub(one, tone));
            }

            V ink;
            if (k.screen_space) {
                const V fx = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane));
                const V u = _mm256_div_ps(add(fx, v8::set1(0.5f)), v8::set1(k.finest));
                const V v =
                    _mm256_div_ps(add(v8::set1(float(y)), v8::set1(0.5f)), v8::set1(k.finest));
                ink = ramp_v(tam, ones, darkness, u, v, zero);
            } else if (_mm256_testz_ps(c.hit, c.hit)) {
                ink = zero;  // all sky: blank paper
            } else {
                V dxx, dxy, dxz, dyx, dyy, dyz;
                const V hx = pick_step_v(c,
                                         load_sample(buf, plane, i + 1),
                                         load_sample(buf, plane, i - 1),
                                         dxx,
                                         dxy,
                                         dxz);
                const V hy = pick_step_v(c,
                                         load_sample(buf, plane, i + stride),
                                         load_sample(buf, plane, i - stride),
                                         dyx,
                                         dyy,
                                         dyz);
                const V x_from_y = andnot(hy, hx), y_from_x = andnot(hx, hy);
                const V ux0 = dxx, uy0 = dxy, uz0 = dxz;
                dxx = select(x_from_y, dyx, dxx);
                dxy = select(x_from_y, dyy, dxy);
                dxz = select(x_from_y, dyz, dxz);
                dyx = select(y_from_x, ux0, dyx);
                dyy = select(y_from_x, uy0, dyy);
                dyz = select(y_from_x, uz0, dyz);
                const V footprint = vor(hx, hy);
                const V ax = vabs(c.nx), ay = vabs(c.ny), az = vabs(c.nz);
                const V flat = andnot(c.hit, c.nrm);  // no usable normal: flat mean tone
                const V flat_lod = v8::set1(k.flat_lod);
                if (k.triplanar) {
                    ink = triplanar_ink(k,
                                        c,
                                        flat,
                                        footprint,
                                        darkness,
                                        V3{{ax, ay, az}},
                                        V3{{dxx, dxy, dxz}},
                                        V3{{dyx, dyy, dyz}});
                } else {
                    // Dominant plane: 0 = (z, y), 1 = (x, z), 2 = (x, y).
                    const V p0 =
                        vand(_mm256_cmp_ps(ax, ay, _CMP_GE_OQ), _mm256_cmp_ps(ax, az, _CMP_GE_OQ));
                    const V p1 = andnot(_mm256_cmp_ps(ay, az, _CMP_GE_OQ), p0);
                    const V u = andnot(mul(select(p0, c.pz, c.px), v8::set1(k.inv_scale)), flat);
                    const V v = andnot(mul(select(p1, c.pz, c.py), v8::set1(k.inv_scale)), flat);
                    const V lod = plane_lod(k,
                                            select(p0, dxz, dxx),
                                            select(p1, dxz, dxy),
                                            select(p0, dyz, dyx),
                                            select(p1, dyz, dyy));
                    ink = ramp_v(tam,
                                 c.hit,
                                 darkness,
                                 u,
                                 v,
                                 select(vor(flat, andnot(ones, footprint)), flat_lod, lod));
                }
            }

            V line = zero;
            for (int j = 0; j < k.tap_count; ++j) {
                const LineTap &tap = k.taps[j];
                const V e = ld(edges + index(x + tap.dx, y + tap.dy));
                line = _mm256_max_ps(line, vand(e, v8::set1(tap.coverage)));
            }

            V alpha = nc >= 4 ? select(finite_v(ca), ca, one) : one;
            const V srcv[3] = {cr, cg, cb};
            V outv[3];
            // Id mask: lanes whose id is not listed keep their input pixel (all channels).
            alignas(32) std::int32_t keep_lane[8] = {};
            bool any_kept = false;
            if (k.ids) {
                for (int j = 0; j < n; ++j) {
                    const float id = k.id->at(x + j, y, 0);
                    const int key = std::isfinite(id) ? int(std::lround(id)) : -1;
                    const bool listed =
                        std::find(k.ids->begin(), k.ids->end(), key) != k.ids->end();
                    keep_lane[j] = listed ? 0 : -1;
                    any_kept = any_kept || !listed;
                }
            }
            const V keep =
                _mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const VI *>(keep_lane)));
            for (int ch = 0; ch < 3; ++ch) {
                V val = add(paper[ch], mul(ink, imp[ch]));
                val = add(val, mul(line, sub(oc[ch], val)));
                val = mul(val, alpha);
                if (k.partial_mix) {
                    const V base = select(finite_v(srcv[ch]), srcv[ch], val);
                    val = add(base, mul(mix, sub(val, base)));
                }
                outv[ch] = select(keep, srcv[ch], val);
            }
            if (any_kept && nc >= 4) {
                alpha = select(keep, ca, alpha);
            }
            float *dst = k.out->pixel(x, y);
            if (nc == 4 && n == 8 && (reinterpret_cast<std::uintptr_t>(dst) & 15) == 0) {
                stream_rgba8(dst, outv[0], outv[1], outv[2], alpha);
            } else if (nc == 4 && n == 8) {
                store_rgba8(dst, outv[0], outv[1], outv[2], alpha);
            } else {
                _mm256_store_ps(stage[0], outv[0]);
                _mm256_store_ps(stage[1], outv[1]);
                _mm256_store_ps(stage[2], outv[2]);
                _mm256_store_ps(stage[3], alpha);
                for (int j = 0; j < n; ++j) {
                    float *d = dst + std::size_t(j) * std::size_t(nc);
                    const float *s = src + std::size_t(j) * std::size_t(nc);
                    if (keep_lane[j]) {
                        std::copy_n(s, nc, d);
                        continue;
                    }
                    d[0] = stage[0][j];
                    d[1] = stage[1][j];
                    d[2] = stage[2][j];
                    if (nc >= 4) {
                        d[3] = stage[3][j];
                        for (int ch = 4; ch < nc; ++ch) {
                            d[ch] = s[ch];
                        }
                    }
                }
            }
        }
    }
    _mm_sfence();  // order the streaming stores before the tile counts as done
}
#if defined(__GNUC__) && !defined(__clang__)
#if !defined(__clang__)
#pragma GCC pop_options
#endif
#endif
#endif

}  // namespace

ToneCurve::ToneCurve(float gamma)
{
    for (int i = 0; i <= kSegments; ++i) {
        table_[std::size_t(i)] = std::pow(float(i) / float(kSegments), 2.0f / gamma);
    }
}

float hatch_tone(const float *rgba, int channels, const HatchSettings &s)
{
    return ToneCurve(s.gamma).tone(rgba, channels, s.exposure);
}

Image hatch(const HatchInputs &in, const HatchSettings &s, const Tam &tam)
{
    const Image &color = *in.color;
    const int w = color.width(), h = color.height(), nc = color.channels();
    assert(in.depth && in.normal && in.position);
    assert(in.depth->width() == w && in.normal->width() == w && in.position->width() == w);
    assert(s.ids.empty() || in.id);

    const bool outlines = s.outline_width > 0.0f;
    const float cos_thr = std::cos(s.normal_threshold_deg * kPiF / 180.0f);
    const float line_r = 0.5f * (s.outline_width - 1.0f);  // coverage = clamp(r + 1 - dist)
    const int line_reach = outlines ? std::max(0, int(std::ceil(line_r))) : 0;
    // Outline pen taps, kept where the coverage is positive.
    std::vector<LineTap> line_taps;
    for (int dy = -line_reach; outlines && dy <= line_reach; ++dy) {
        for (int dx = -line_reach; dx <= line_reach; ++dx) {
            const float c =
                std::clamp(line_r + 1.0f - std::sqrt(float(dx * dx + dy * dy)), 0.0f, 1.0f);
            if (c > 0.0f) {
                line_taps.push_back({dx, dy, c});
            }
        }
    }
    const glm::vec3 light = glm::normalize(s.light_dir);
    const ToneCurve curve(s.gamma);
    const float finest = float(tam.size());
    const float flat_lod = float(tam.levels() - 1);
    const float inv_scale = 1.0f / s.scale;
    const float lod_offset = std::log2(inv_scale * finest);  // log2 of texels per metre
    const Rect bounds = color.bounds();
    // Locals, not reads through `s`: stores to the output could alias them otherwise.
    const glm::vec3 paper = s.paper, ink_minus_paper = s.ink - s.paper, outline_color = s.outline;
    const float mix = s.mix, exposure = s.exposure;
    const bool partial_mix = s.mix < 1.0f, screen_space = s.screen_space;
    // Screen mode without outlines or light reads no geometry (sky and surfaces alike).
    const bool needs_samples = !s.screen_space || outlines || s.tone_from_light;

    Image out = Image::uninitialized(w, h, nc);
    // The AVX2 kernel covers every mode; mix 0 (a copy) stays on the scalar path.
    const bool use_avx2 = POSTHASTE_HAVE_AVX2_TARGET && simd::avx2() && mix > 0.0f;
    [[maybe_unused]] const KernelCtx kc{&color,
                                        in.depth,
                                        in.normal,
                                        in.position,
                                        &out,
                                        &tam,
                                        &curve,
                                        line_taps.data(),
                                        int(line_taps.size()),
                                        line_reach,
                                        screen_space,
                                        s.tone_from_light,
                                        partial_mix,
                                        needs_samples,
                                        s.depth_threshold,
                                        cos_thr,
                                        inv_scale,
                                        lod_offset,
                                        flat_lod,
                                        finest,
                                        s.ambient,
                                        exposure,
                                        mix,
                                        light,
                                        paper,
                                        ink_minus_paper,
                                        outline_color,
                                        s.triplanar,
                                        s.triplanar_sharpness,
                                        std::pow(0.0f, s.triplanar_sharpness),
                                        in.id,
                                        s.ids.empty() ? nullptr : &s.ids};
    for (int l = 0; l < tam.levels(); ++l) {  // the AVX2 kernel computes level offsets
        assert(int(tam.level_offset(l)) ==
               4 * (tam.size() * tam.size() - tam.level_size(l) * tam.level_size(l)) / 3);
    }
#if POSTHASTE_HAVE_AVX2_TARGET
    if (use_avx2) {
        // Wide, short tiles: each row of a tile is a long sequential read of every pass (64-pixel
        // rows are too short for the hardware prefetchers), and the tile's planes stay in L2.
        // The output of a pixel does not depend on the tile it falls in.
        constexpr int kTileW = 512, kTileH = 32;
        const int tiles_x = (w + kTileW - 1) / kTileW, tiles_y = (h + kTileH - 1) / kTileH;
        parallel_for(0, tiles_x * tiles_y, [&](int i) {
            const int tx = i % tiles_x, ty = i / tiles_x;
            const Rect t{tx * kTileW,
                         ty * kTileH,
                         std::min((tx + 1) * kTileW, w),
                         std::min((ty + 1) * kTileH, h)};
            hatch_tile_avx2(kc, t);
        });
        return out;
    }
#endif
    parallel_for_tiles(bounds, [&](const Rect &t) {
        // Tile-local copies: samples on the tile plus the outline reach plus one pixel (edges and
        // footprints look at 4-neighbours), edge flags on the tile plus the outline reach.
        const Rect re = t.expand(line_reach).intersect(bounds);
        const Rect rs = re.expand(1).intersect(bounds);
        const int sw = rs.width(), ew = re.width();
        thread_local std::vector<Sample> tls_samples;  // reused: no allocation per tile
        tls_samples.resize(std::size_t(sw) * std::size_t(rs.height()));
        Sample *const smp = tls_samples.data();
        if (needs_samples) {
            for (int y = rs.y0; y < rs.y1; ++y) {
                Sample *row = smp + std::size_t(y - rs.y0) * std::size_t(sw);
                const float *zr = in.depth->pixel(rs.x0, y), *pr = in.position->pixel(rs.x0, y);
                const float *nr = in.normal->pixel(rs.x0, y);
                const int zs = in.depth->channels(), ps = in.position->channels();
                const int ns = in.normal->channels();
                for (int i = 0; i < sw; ++i) {
                    row[i] = read_sample(zr + i * zs, pr + i * ps, nr + i * ns);
                }
            }
        }
        // Neighbours by index; at the image border the pixel stands in for the missing one
        // (never an edge with itself, and a zero step is no footprint).
        auto index = [&](int x, int y) {
            return std::size_t(y - rs.y0) * std::size_t(sw) + std::size_t(x - rs.x0);
        };
        struct Around {
            std::size_t c, l, r, u, d;
        };
        auto around = [&](int x, int y) {
            const std::size_t c = index(x, y);
            return Around{c,
                          x > rs.x0 ? c - 1 : c,
                          x + 1 < rs.x1 ? c + 1 : c,
                          y > rs.y0 ? c - std::size_t(sw) : c,
                          y + 1 < rs.y1 ? c + std::size_t(sw) : c};
        };
        thread_local std::vector<std::uint8_t> tls_edges;
        std::vector<std::uint8_t> &edges = tls_edges;
        if (outlines) {
            edges.assign(std::size_t(ew) * std::size_t(re.height()), 0);
            for (int y = re.y0; y < re.y1; ++y) {
                for (int x = re.x0; x < re.x1; ++x) {
                    const Around a = around(x, y);
                    const Sample &c = smp[a.c];
                    if (!c.hit) {
                        continue;
                    }
                    const float dt = s.depth_threshold;
                    const bool e = is_edge(c, smp[a.l], false, dt, cos_thr) ||
                                   is_edge(c, smp[a.r], true, dt, cos_thr) ||
                                   is_edge(c, smp[a.u], false, dt, cos_thr) ||
                                   is_edge(c, smp[a.d], true, dt, cos_thr);
                    edges[std::size_t(y - re.y0) * std::size_t(ew) + std::size_t(x - re.x0)] =
                        e ? 1 : 0;
                }
            }
        }
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float *src = color.pixel(x, y);
                float *dst = out.pixel(x, y);
                bool masked_in = true;
                if (!s.ids.empty()) {
                    const float id = in.id->at(x, y, 0);
                    masked_in =
                        std::find(s.ids.begin(),
                                  s.ids.end(),
                                  std::isfinite(id) ? int(std::lround(id)) : -1) != s.ids.end();
                }
                if (!masked_in || mix <= 0.0f) {
                    std::copy_n(src, nc, dst);
                    continue;
                }
                const Around a = around(x, y);
                const Sample &c = smp[a.c];
                float darkness = 0.0f;
                if (screen_space || c.hit) {  // surface mode: the sky is blank paper
                    const float tone =
                        s.tone_from_light
                            ? curve((s.ambient +
                                     (1.0f - s.ambient) *
                                         (c.normal ? std::max(0.0f, glm::dot(c.n, light)) : 1.0f)) *
                                    s.exposure)
                            : curve.tone(src, nc, exposure);
                    darkness = 1.0f - tone;
                }
                float ink = 0.0f;
                if (screen_space) {
                    ink = tam.ramp(
                        darkness, (float(x) + 0.5f) / finest, (float(y) + 0.5f) / finest, 0.0f);
                } else if (c.hit && !c.normal) {
                    ink = tam.ramp(darkness, 0.0f, 0.0f, flat_lod);  // flat mean tone, no strokes
                } else if (c.hit && darkness > 0.0f) {
                    glm::vec3 dpx, dpy;
                    const bool hx = pick_step(c, smp[a.r], smp[a.l], dpx);
                    const bool hy = pick_step(c, smp[a.d], smp[a.u], dpy);
                    if (!hx && hy) {
                        dpx = dpy;
                    }
                    if (!hy && hx) {
                        dpy = dpx;
                    }
                    const bool footprint = hx || hy;
                    // Planes: 0 = (z, y) for x-facing, 1 = (x, z) for y-facing, 2 = (x, y).
                    const glm::vec3 an = glm::abs(c.n);
                    float weight[3] = {0.0f, 0.0f, 0.0f};
                    if (s.triplanar) {
                        float sum = 0.0f;
                        for (int a = 0; a < 3; ++a) {
                            weight[a] =
                                std::pow(std::max(an[a] - 0.2f, 0.0f), s.triplanar_sharpness);
                            sum += weight[a];
                        }
                        for (float &wa : weight) {
                            wa /= sum;  // sum > 0: the largest |n| of a unit vector is >= 0.577
                        }
                    } else {
                        weight[an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2)] = 1.0f;
                    }
                    static constexpr int kU[3] = {2, 0, 0}, kV[3] = {1, 2, 1};
                    for (int a = 0; a < 3; ++a) {
                        if (weight[a] <= 0.0f) {
                            continue;
                        }
                        const float u = c.p[kU[a]] * inv_scale, v = c.p[kV[a]] * inv_scale;
                        float lod = flat_lod;
                        if (footprint) {
                            const float ux = dpx[kU[a]], vx = dpx[kV[a]];
                            const float uy = dpy[kU[a]], vy = dpy[kV[a]];
                            const float len2 = std::max(ux * ux + vx * vx, uy * uy + vy * vy);
                            // log2(sqrt(len2) * texels per metre)
                            lod = 0.5f * fast_log2(std::max(len2, 1e-30f)) + lod_offset;
                        }
                        ink += weight[a] * tam.ramp(darkness, u, v, lod);
                    }
                }

                float line = 0.0f;
                for (const LineTap &tap : line_taps) {
                    const int xx = x + tap.dx, yy = y + tap.dy;
                    if (xx >= re.x0 && xx < re.x1 && yy >= re.y0 && yy < re.y1 &&
                        edges[std::size_t(yy - re.y0) * std::size_t(ew) +
                              std::size_t(xx - re.x0)]) {
                        line = std::max(line, tap.coverage);
                    }
                }

                const float alpha = nc >= 4 ? (finite_f(src[3]) ? src[3] : 1.0f) : 1.0f;
                for (int ch = 0; ch < 3; ++ch) {
                    float v = paper[ch] + ink * (ink_minus_paper[ch]);
                    v += line * (outline_color[ch] - v);
                    v *= alpha;
                    if (partial_mix) {
                        const float base = finite_f(src[ch]) ? src[ch] : v;
                        v = base + mix * (v - base);
                    }
                    dst[ch] = v;
                }
                if (nc >= 4) {
                    dst[3] = alpha;
                    for (int ch = 4; ch < nc; ++ch) {
                        dst[ch] = src[ch];
                    }
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
