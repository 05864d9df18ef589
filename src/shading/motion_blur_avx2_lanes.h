#pragma once
// The motion blur AVX2 rows' lane vocabulary (motion_blur_avx2.cpp only): hashing and jitter,
// lane reductions, the group's frame and sample offsets, loads of a shared run, the per-lane
// plans and their final weights.

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/motion_blur_gather.h"

#if POSTHASTE_HAVE_AVX2_TARGET
namespace posthaste::shading::motion_blur_detail {

/// pcg_hash on eight lanes.
POSTHASTE_AVX2_INLINE VI pcg8(VI v)
{
    const VI state = _mm256_add_epi32(_mm256_mullo_epi32(v, _mm256_set1_epi32(747796405)),
                                      _mm256_set1_epi32(int(2891336453u)));
    const VI shift = _mm256_add_epi32(_mm256_srli_epi32(state, 28), _mm256_set1_epi32(4));
    const VI word = _mm256_mullo_epi32(_mm256_xor_si256(_mm256_srlv_epi32(state, shift), state),
                                       _mm256_set1_epi32(277803737));
    return _mm256_xor_si256(_mm256_srli_epi32(word, 22), word);
}
/// hash_to_unit on eight lanes.
POSTHASTE_AVX2_INLINE V unit8(VI h)
{
    return _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(h, 8)), set1(1.0f / 16777216.0f));
}
/// Gather::sample_count on eight lanes, as floats.
POSTHASTE_AVX2_INLINE V count8(V len, V most)
{
    const V n =
        _mm256_min_ps(most, _mm256_max_ps(set1(2.0f), _mm256_ceil_ps(_mm256_add_ps(len, len))));
    return _mm256_max_ps(set1(1.0f), n);
}
/// Largest lane, as an int (lanes hold small whole numbers).
POSTHASTE_AVX2_INLINE int max_lane(V x)
{
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_movehdup_ps(m));
    return int(_mm_cvtss_f32(m));
}
/// Smallest lane.
POSTHASTE_AVX2_INLINE float min_lane(V x)
{
    __m128 m = _mm_min_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_movehdup_ps(m));
    return _mm_cvtss_f32(m);
}
/// Largest lane.
POSTHASTE_AVX2_INLINE float max_lane_f(V x)
{
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_movehdup_ps(m));
    return _mm_cvtss_f32(m);
}
/// The bounding box of the (vx, vy) lanes in `mask`.
POSTHASTE_AVX2_INLINE Box bounds8(V vx, V vy, V mask)
{
    const V inf = set1(kInf), ninf = set1(-kInf);
    Box b;
    b.lo_x = min_lane(_mm256_blendv_ps(inf, vx, mask));
    b.hi_x = max_lane_f(_mm256_blendv_ps(ninf, vx, mask));
    b.lo_y = min_lane(_mm256_blendv_ps(inf, vy, mask));
    b.hi_y = max_lane_f(_mm256_blendv_ps(ninf, vy, mask));
    return b;
}

/// The pixel index of lane x + 0.5 + t v, clamped to the frame (Gather::at).
struct Frame8 {
    V xf, yf, xmax, ymax;
    VI w;
};
/// Frame8 of row y (xf: set per group with lanes8_at).
POSTHASTE_AVX2_INLINE Frame8 frame8(const Gather &g, int y)
{
    return Frame8{set1(0.0f),
                  set1(float(y) + 0.5f),
                  set1(float(g.w) - 0.5f),
                  set1(float(g.h) - 0.5f),
                  _mm256_set1_epi32(g.w)};
}
/// `f` at the pixel centres of columns xi.
POSTHASTE_AVX2_INLINE Frame8 lanes8_at(Frame8 f, VI xi)
{
    f.xf = _mm256_add_ps(_mm256_cvtepi32_ps(xi), set1(0.5f));
    return f;
}
/// The row's part of the per-pixel hash hash4(x, y, 0, seed) = pcg_hash(x ^ key).
POSTHASTE_AVX2_INLINE VI row_key8(const Gather &g, int y)
{
    return _mm256_set1_epi32(int(pcg_hash(std::uint32_t(y) ^ pcg_hash(0u ^ pcg_hash(g.o.seed)))));
}
POSTHASTE_AVX2_INLINE VI offset8(const Frame8 &f, V t, V vx, V vy)
{
    const V zero = _mm256_setzero_ps();
    const V fx =
        _mm256_min_ps(_mm256_max_ps(_mm256_add_ps(f.xf, _mm256_mul_ps(t, vx)), zero), f.xmax);
    const V fy =
        _mm256_min_ps(_mm256_max_ps(_mm256_add_ps(f.yf, _mm256_mul_ps(t, vy)), zero), f.ymax);
    return _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(fy), f.w),
                            _mm256_cvttps_epi32(fx));
}

/// A shared sample of a group (Gather::run_origin): where the run of eight pixels lies inside
/// its row, each field is one load; at the left and right edges, a gather of the clamped
/// columns.
struct RunAt {
    bool inside;
    std::size_t base;
    VI idx;
};
POSTHASTE_AVX2_INLINE RunAt run_at8(const Gather &g, int x0, int y, float t, float vx, float vy)
{
    int bx, by;
    g.run_origin(x0, y, t, vx, vy, bx, by);
    RunAt a{bx >= 0 && bx + 8 <= g.w, g.index(0, by) + std::size_t(std::max(bx, 0)), VI{}};
    if (!a.inside) {
        const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        const VI col = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(bx), lane), _mm256_setzero_si256()),
            _mm256_set1_epi32(g.w - 1));
        a.idx = _mm256_add_epi32(_mm256_set1_epi32(by * g.w), col);
    }
    return a;
}
POSTHASTE_AVX2_INLINE V field8(const Gather &g, int field, const RunAt &a)
{
    return a.inside ? _mm256_loadu_ps(g.f[field] + a.base)
                    : _mm256_i32gather_ps(g.f[field], a.idx, 4);
}
POSTHASTE_AVX2_INLINE V gather8(const Gather &g, int field, VI idx)
{
    return _mm256_i32gather_ps(g.f[field], idx, 4);
}

/// The most samples of a run whose origins a plan tabulates (longer runs compute them as
/// they go).
constexpr int kTabulated = 32;

/// Gather::run_origin for samples t_i = -1 + (i + u) step, i < n <= kTabulated, eight at a
/// time: first columns (unclamped) and row offsets (clamped row x width). Tabulated in the
/// plan, a sample's loads no longer wait on its chain of float-to-int conversions.
POSTHASTE_AVX2_INLINE void origins8(const Gather &g,
                                    int x0,
                                    int y,
                                    float u,
                                    float step,
                                    float vx,
                                    float vy,
                                    int n,
                                    std::int32_t *bx,
                                    std::int32_t *row)
{
    const V lanef = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const V ox = set1(float(x0) + 0.5f), oy = set1(float(y) + 0.5f);
    for (int i = 0; i < n; i += 8) {
        const V t = _mm256_fmadd_ps(
            _mm256_add_ps(_mm256_add_ps(set1(float(i)), lanef), set1(u)), set1(step), set1(-1.0f));
        const VI cx = _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_fmadd_ps(t, set1(vx), ox)));
        VI cy = _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_fmadd_ps(t, set1(vy), oy)));
        cy = _mm256_min_epi32(_mm256_max_epi32(cy, _mm256_setzero_si256()),
                              _mm256_set1_epi32(g.h - 1));
        _mm256_storeu_si256(reinterpret_cast<VI *>(bx + i), cx);
        _mm256_storeu_si256(reinterpret_cast<VI *>(row + i),
                            _mm256_mullo_epi32(cy, _mm256_set1_epi32(g.w)));
    }
}
/// RunAt of a tabulated origin.
POSTHASTE_AVX2_INLINE RunAt run_at8(const Gather &g, std::int32_t bx, std::int32_t row)
{
    RunAt a{bx >= 0 && bx + 8 <= g.w, std::size_t(row) + std::size_t(std::max(bx, 0)), VI{}};
    if (!a.inside) {
        const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        const VI col = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(bx), lane), _mm256_setzero_si256()),
            _mm256_set1_epi32(g.w - 1));
        a.idx = _mm256_add_epi32(_mm256_set1_epi32(row), col);
    }
    return a;
}

/// Gather::own for pixels x .. x + 7 of row y (lanes past the row's end read its last pixel):
/// three loads where the eight lie inside the row.
POSTHASTE_AVX2_INLINE void own8(const Gather &g, int x, int y, VI xc, V &vx, V &vy, V &len)
{
    V wx, wy;
    if (x + 8 <= g.w) {
        const std::size_t i0 = g.index(x, y);
        wx = _mm256_loadu_ps(g.f[kWx] + i0);
        wy = _mm256_loadu_ps(g.f[kWy] + i0);
        len = _mm256_loadu_ps(g.f[kLen] + i0);
    } else {
        const VI ci = _mm256_add_epi32(_mm256_set1_epi32(int(g.index(0, y))), xc);
        wx = _mm256_i32gather_ps(g.f[kWx], ci, 4);
        wy = _mm256_i32gather_ps(g.f[kWy], ci, 4);
        len = _mm256_i32gather_ps(g.f[kLen], ci, 4);
    }
    const V k = _mm256_mul_ps(_mm256_mul_ps(set1(2.0f), len), len);
    vx = _mm256_mul_ps(wx, k);
    vy = _mm256_mul_ps(wy, k);
}

/// Writes the first `lanes` results (SoA, r[channel][lane]) of row y from x, lanes not in
/// `keep` copied from the input.
POSTHASTE_AVX2_INLINE void store8(
    const Gather &g, Image &out, int x, int y, int lanes, const V *r, V keep)
{
    const int mask = _mm256_movemask_ps(keep);
    if (mask == 0xff && lanes == 8 && g.nc == 4 && out.channels() == 4) {
        // RGBA: transpose the four channel vectors into eight pixels, four 32-byte stores.
        const V t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
        const V t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
        const V p0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));  // pixels 0, 4
        const V p1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));  // 1, 5
        const V p2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));  // 2, 6
        const V p3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));  // 3, 7
        float *po = out.pixel(x, y);
        _mm256_storeu_ps(po, _mm256_permute2f128_ps(p0, p1, 0x20));
        _mm256_storeu_ps(po + 8, _mm256_permute2f128_ps(p2, p3, 0x20));
        _mm256_storeu_ps(po + 16, _mm256_permute2f128_ps(p0, p1, 0x31));
        _mm256_storeu_ps(po + 24, _mm256_permute2f128_ps(p2, p3, 0x31));
        return;
    }
    alignas(32) float v[4][8];
    for (int k = 0; k < 4; ++k) {
        _mm256_store_ps(v[k], r[k]);
    }
    for (int j = 0; j < lanes; ++j) {
        float *po = out.pixel(x + j, y);
        if (mask & (1 << j)) {
            for (int k = 0; k < g.nc; ++k) {
                po[k] = v[k][j];
            }
        } else {
            g.copy_pixel(out, x + j, y);
        }
    }
}

/// The eight lanes of a group: Gather::Lane, and the pixels' own records.
struct Lanes8 {
    VI xi;  ///< pixel columns
    V valid, cvx, cvy, clen, inv_own, own, shared, vx, vy, len, dx, dy, clz, cc[4];
};

/// Gather::finish on eight lanes; stores the first `lanes`.
POSTHASTE_AVX2_INLINE void finish8(const Gather &g,
                                   Image &out,
                                   int x,
                                   int y,
                                   int lanes,
                                   const Lanes8 &p,
                                   V F,
                                   V B,
                                   const V *fg,
                                   const V *bg,
                                   V own_weight)
{
    const V one = set1(1.0f);
    const V full = _mm256_cmp_ps(F, one, _CMP_GE_OQ);
    const V wc = _mm256_blendv_ps(one, _mm256_mul_ps(set1(1e-3f), own_weight), p.own);
    B = _mm256_add_ps(B, wc);
    const V rest = _mm256_div_ps(_mm256_sub_ps(one, F), B);
    const V inv_f = _mm256_div_ps(one, F);
    V r[4];
    for (int k = 0; k < 4; ++k) {
        const V blend = _mm256_add_ps(
            fg[k], _mm256_mul_ps(rest, _mm256_add_ps(bg[k], _mm256_mul_ps(wc, p.cc[k]))));
        r[k] = _mm256_blendv_ps(blend, _mm256_mul_ps(fg[k], inv_f), full);
    }
    if (g.opaque) {
        r[3] = one;
    }
    store8(g, out, x, y, lanes, r, _mm256_castsi256_ps(_mm256_set1_epi32(-1)));
}

/// Gather::second_lane on the lanes in `second` (n: the front estimate's sample counts);
/// returns the weight of one sample.
POSTHASTE_AVX2_INLINE V
second_lanes8(const Gather &g, const Frame8 &f, const Lanes8 &p, V second, V n, VI hu, V &B, V *bg)
{
    const V one = set1(1.0f), half = set1(0.5f), zero = _mm256_setzero_ps();
    const V inv_soft = set1(g.inv_soft);
    const V half_n = _mm256_floor_ps(_mm256_mul_ps(_mm256_add_ps(n, one), half));
    const V m = _mm256_and_ps(
        _mm256_max_ps(set1(2.0f), _mm256_min_ps(count8(p.clen, set1(float(g.o.samples))), half_n)),
        second);
    const V mstep = _mm256_div_ps(set1(2.0f), _mm256_max_ps(m, one));
    const V wm = _mm256_mul_ps(_mm256_mul_ps(p.clen, mstep), p.inv_own);
    const V u2 = unit8(pcg8(hu));
    const int m_max = max_lane(m);
    for (int i = 0; i < m_max; ++i) {
        const V fi = set1(float(i));
        const V active = _mm256_cmp_ps(fi, m, _CMP_LT_OQ);
        const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u2), mstep));
        const VI idx = offset8(f, t, p.cvx, p.cvy);
        const V fr = simd::v8::clamp(
            _mm256_add_ps(half,
                          _mm256_mul_ps(_mm256_sub_ps(p.clz, gather8(g, kLogZ, idx)), inv_soft)),
            zero,
            one);
        const V wb = _mm256_and_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr), wm), active);
        B = _mm256_add_ps(B, wb);
        for (int k = 0; k < 4; ++k) {
            bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, gather8(g, kRed + k, idx)));
        }
    }
    return wm;
}

/// Gather::reconstruct_lane on eight lanes: each follows its own plan and jitter (lanes past
/// their sample count add nothing).
POSTHASTE_AVX2_INLINE void lanes8(
    const Gather &g, Image &out, int x, int y, int lanes, const Lanes8 &p, const Frame8 &fr, VI ky0)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft);
    const Frame8 f = lanes8_at(fr, p.xi);
    const V n = count8(p.len, set1(float(g.o.samples)));
    const V step = _mm256_div_ps(set1(2.0f), n);
    const V delta = _mm256_mul_ps(p.len, step);
    const V own_w = _mm256_and_ps(_mm256_mul_ps(delta, p.inv_own), p.shared);
    const VI hu = pcg8(_mm256_xor_si256(p.xi, ky0));
    const V u = unit8(hu);
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const int n_max = max_lane(n);
    for (int i = 0; i < n_max; ++i) {
        const V fi = set1(float(i));
        const V active = _mm256_cmp_ps(fi, n, _CMP_LT_OQ);
        const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u), step));
        const VI idx = offset8(f, t, p.vx, p.vy);
        const V T = _mm256_mul_ps(abs8(t), p.len);
        const V fr_w = simd::v8::clamp(
            _mm256_add_ps(half,
                          _mm256_mul_ps(_mm256_sub_ps(p.clz, gather8(g, kLogZ, idx)), inv_soft)),
            zero,
            one);
        const V reach_s = simd::v8::clamp(
            _mm256_sub_ps(_mm256_add_ps(gather8(g, kLen, idx), half), T), zero, one);
        const V reach_c = simd::v8::clamp(_mm256_sub_ps(_mm256_add_ps(p.clen, half), T), zero, one);
        const V along = abs8(_mm256_add_ps(_mm256_mul_ps(gather8(g, kWx, idx), p.dx),
                                           _mm256_mul_ps(gather8(g, kWy, idx), p.dy)));
        const V wf = _mm256_and_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(fr_w, reach_s), along), delta), active);
        const V wb = _mm256_and_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr_w), reach_c), own_w), active);
        F = _mm256_add_ps(F, wf);
        B = _mm256_add_ps(B, wb);
        for (int k = 0; k < 4; ++k) {
            const V c = gather8(g, kRed + k, idx);
            fg[k] = _mm256_add_ps(fg[k], _mm256_mul_ps(wf, c));
            bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, c));
        }
    }
    V own_weight = own_w;
    const V second = _mm256_andnot_ps(p.shared, p.own);
    if (_mm256_movemask_ps(second) != 0) {
        own_weight =
            _mm256_blendv_ps(own_weight, second_lanes8(g, f, p, second, n, hu, B, bg), second);
    }
    finish8(g, out, x, y, lanes, p, F, B, fg, bg, own_weight);
}

}  // namespace posthaste::shading::motion_blur_detail
#endif
