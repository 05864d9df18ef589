// The motion blur's AVX2 rows: eight adjacent pixels at a time, a group that shares its sample
// positions reading each field of a sample with one load (motion_blur_gather.h is the
// reference they follow).
#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/motion_blur_avx2_lanes.h"

#if POSTHASTE_HAVE_AVX2_TARGET
namespace posthaste::shading::motion_blur_detail {

/// The front estimate along a shared run (Gather::reconstruct_run's first loop; kBack: also
/// the own-surface sums, needed only where some lane's own path is the shared one). The sums
/// leave out the path length per sample, delta, which the caller multiplies in.
template <bool kBack, int kNc>
POSTHASTE_AVX2_INLINE void front_run8(const Gather &g,
                                      int x,
                                      int y,
                                      const Run &r,
                                      float u,
                                      const std::int32_t *bx,
                                      const std::int32_t *row,
                                      const Lanes8 &p,
                                      V &F,
                                      V &B,
                                      V *fg,
                                      V *bg)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft), dx = set1(r.dx), dy = set1(r.dy);
    const float step = 2.0f / float(r.n);
    for (int i = 0; i < r.n; ++i) {
        const float t = -1.0f + (float(i) + u) * step;
        const V rT = set1(0.5f - std::abs(t) * r.len);
        const RunAt a = bx ? run_at8(g, bx[i], row[i]) : run_at8(g, x, y, t, r.vx, r.vy);
        const V fr = simd::v8::clamp(
            _mm256_fmadd_ps(_mm256_sub_ps(p.clz, field8(g, kLogZ, a)), inv_soft, half), zero, one);
        const V reach_s = simd::v8::clamp(_mm256_add_ps(field8(g, kLen, a), rT), zero, one);
        const V along =
            abs8(_mm256_fmadd_ps(field8(g, kWx, a), dx, _mm256_mul_ps(field8(g, kWy, a), dy)));
        const V wf = _mm256_mul_ps(_mm256_mul_ps(fr, reach_s), along);
        F = _mm256_add_ps(F, wf);
        V c[4];
        for (int k = 0; k < kNc; ++k) {
            c[k] = field8(g, kRed + k, a);
            fg[k] = _mm256_fmadd_ps(wf, c[k], fg[k]);
        }
        if constexpr (kBack) {
            const V reach_c = simd::v8::clamp(_mm256_add_ps(p.clen, rT), zero, one);
            const V wb = _mm256_fnmadd_ps(fr, reach_c, reach_c);  // (1 - fr) reach_c
            B = _mm256_add_ps(B, wb);
            for (int k = 0; k < kNc; ++k) {
                bg[k] = _mm256_fmadd_ps(wb, c[k], bg[k]);
            }
        }
    }
}

/// A group's plan: everything Gather::reconstruct decides before its sample loops. The row
/// plans the next group before it samples this one, so that the plan's chain of latencies
/// (hashes, lookup, square roots, divisions, reductions) overlaps the previous group's loops.
struct Plan8 {
    int x, lanes;
    bool live;
    Lanes8 p;
    Run r;        ///< the shared run (r.ok false: each lane samples on its own)
    Run c;        ///< the second direction's shared run, for the lanes whose path is not shared
    bool second;  ///< some lane needs the second direction
    float u, u2;
    /// Sample origins of the shared runs (front: r.n of them, second: m), when tabulated.
    alignas(32) std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    alignas(32) std::int32_t bx2[kTabulated + 8], row2[kTabulated + 8];
    int m;
};

POSTHASTE_AVX2_INLINE void plan8(const Gather &g, int x, int y, int x1, Plan8 &pl)
{
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const V half = set1(0.5f);
    const VI last = _mm256_set1_epi32(g.w - 1);
    pl.x = x;
    pl.lanes = std::min(8, x1 - x);
    const Lookup l = g.lookup(x, y);
    pl.live = l.len >= 0.5f;
    if (!pl.live) {
        return;
    }
    Lanes8 &p = pl.p;
    p.xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
    // Lanes past the row's end (narrow tiles) compute on the last pixel, unstored.
    const VI xc = _mm256_min_epi32(p.xi, last);
    p.valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(pl.lanes), lane));
    const std::size_t i0 = g.index(x, y);
    if (x + 8 <= g.w) {
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = _mm256_loadu_ps(g.f[kRed + k] + i0);
        }
        p.clz = _mm256_loadu_ps(g.f[kLogZ] + i0);
    } else {
        const VI ci = _mm256_add_epi32(_mm256_set1_epi32(int(g.index(0, y))), xc);
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = gather8(g, kRed + k, ci);
        }
        p.clz = gather8(g, kLogZ, ci);
    }
    own8(g, x, y, xc, p.cvx, p.cvy, p.clen);
    p.own = _mm256_cmp_ps(p.clen, half, _CMP_GE_OQ);
    // One division for the direction and the own weight.
    const V inv_len = _mm256_and_ps(_mm256_div_ps(set1(1.0f), p.clen), p.own);
    const V dcx = _mm256_mul_ps(p.cvx, inv_len), dcy = _mm256_mul_ps(p.cvy, inv_len);
    const V ldx = set1(l.dx), ldy = set1(l.dy), llen = set1(l.len);
    const V cosine = abs8(_mm256_add_ps(_mm256_mul_ps(dcx, ldx), _mm256_mul_ps(dcy, ldy)));
    p.shared = _mm256_and_ps(_mm256_and_ps(p.own, _mm256_cmp_ps(cosine, set1(0.9f), _CMP_GT_OQ)),
                             _mm256_cmp_ps(p.clen, _mm256_mul_ps(half, llen), _CMP_GE_OQ));
    p.inv_own = _mm256_mul_ps(half, inv_len);
    p.dx = _mm256_blendv_ps(ldx, dcx, p.shared);
    p.dy = _mm256_blendv_ps(ldy, dcy, p.shared);
    p.vx = _mm256_blendv_ps(set1(l.vx), _mm256_mul_ps(dcx, llen), p.shared);
    p.vy = _mm256_blendv_ps(set1(l.vy), _mm256_mul_ps(dcy, llen), p.shared);
    const V longer =
        _mm256_and_ps(p.shared, _mm256_cmp_ps(p.clen, _mm256_mul_ps(set1(0.8f), llen), _CMP_GT_OQ));
    p.vx = _mm256_blendv_ps(p.vx, p.cvx, longer);
    p.vy = _mm256_blendv_ps(p.vy, p.cvy, longer);
    p.len = _mm256_blendv_ps(llen, p.clen, longer);
    g.run(bounds8(p.vx, p.vy, p.valid), pl.r);
    pl.c.ok = 0;
    pl.second = false;
    if (pl.r.ok) {
        const std::uint32_t hu = hash4(std::uint32_t(x), std::uint32_t(y), 0u, g.o.seed);
        pl.u = hash_to_unit(hu);
        pl.u2 = hash_to_unit(pcg_hash(hu));
        const V second_valid = _mm256_and_ps(_mm256_andnot_ps(p.shared, p.own), p.valid);
        pl.second = _mm256_movemask_ps(second_valid) != 0;
        if (pl.second) {
            g.run(bounds8(p.cvx, p.cvy, second_valid), pl.c);
        }
        if (pl.r.n <= kTabulated) {
            origins8(g, x, y, pl.u, 2.0f / float(pl.r.n), pl.r.vx, pl.r.vy, pl.r.n, pl.bx, pl.row);
        }
        if (pl.c.ok) {
            pl.m = std::max(2, std::min(pl.c.n, (pl.r.n + 1) / 2));
            if (pl.m <= kTabulated) {
                origins8(
                    g, x, y, pl.u2, 2.0f / float(pl.m), pl.c.vx, pl.c.vy, pl.m, pl.bx2, pl.row2);
            }
        }
    }
}

/// Gather::reconstruct_run on eight lanes (kNc: colour channels summed; 3 for opaque RGBA).
template <int kNc>
POSTHASTE_AVX2_INLINE void run8(
    const Gather &g, Image &out, int y, const Plan8 &pl, const Frame8 &fr)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft);
    const Lanes8 &p = pl.p;
    const Run &r = pl.r;
    const int x = pl.x;
    const float delta = r.len * (2.0f / float(r.n));
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const std::int32_t *bx = r.n <= kTabulated ? pl.bx : nullptr;
    if (_mm256_movemask_ps(_mm256_and_ps(p.shared, p.valid)) != 0) {
        front_run8<true, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    } else {
        front_run8<false, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    }
    const V vdelta = set1(delta);
    V own_weight = _mm256_and_ps(_mm256_mul_ps(vdelta, p.inv_own), p.shared);
    F = _mm256_mul_ps(F, vdelta);
    B = _mm256_mul_ps(B, own_weight);
    for (int k = 0; k < 4; ++k) {
        fg[k] = _mm256_mul_ps(fg[k], vdelta);
        bg[k] = _mm256_mul_ps(bg[k], own_weight);
    }
    if (pl.second) {
        const V second = _mm256_andnot_ps(p.shared, p.own);
        const Run &c = pl.c;
        if (c.ok) {
            const int m = pl.m;
            const float mstep = 2.0f / float(m);
            const V wm = _mm256_and_ps(set1(1.0f / float(m)), second);
            for (int i = 0; i < m; ++i) {
                const RunAt a =
                    m <= kTabulated
                        ? run_at8(g, pl.bx2[i], pl.row2[i])
                        : run_at8(g, x, y, -1.0f + (float(i) + pl.u2) * mstep, c.vx, c.vy);
                const V f = simd::v8::clamp(
                    _mm256_fmadd_ps(_mm256_sub_ps(p.clz, field8(g, kLogZ, a)), inv_soft, half),
                    zero,
                    one);
                const V wb = _mm256_fnmadd_ps(f, wm, wm);  // (1 - f) wm
                B = _mm256_add_ps(B, wb);
                for (int k = 0; k < kNc; ++k) {
                    bg[k] = _mm256_fmadd_ps(wb, field8(g, kRed + k, a), bg[k]);
                }
            }
            own_weight = _mm256_blendv_ps(own_weight, wm, second);
        } else {
            const VI hv = pcg8(_mm256_xor_si256(p.xi, row_key8(g, y)));
            own_weight = _mm256_blendv_ps(
                own_weight,
                second_lanes8(g, lanes8_at(fr, p.xi), p, second, set1(float(r.n)), hv, B, bg),
                second);
        }
    }
    finish8(g, out, x, y, pl.lanes, p, F, B, fg, bg, own_weight);
}

/// Gather::reconstruct for the groups of pixels [x0, x1) of row y; returns how many shared a
/// run.
POSTHASTE_AVX2 int reconstruct_row_avx2(const Gather &g, Image &out, int y, int x0, int x1)
{
    int shared = 0;
    const Frame8 fr = frame8(g, y);
    const VI ky0 = row_key8(g, y);
    Plan8 plans[2];
    int cur = 0;
    plan8(g, x0, y, x1, plans[0]);
    for (int x = x0; x < x1; x += 8) {
        if (x + 8 < x1) {
            plan8(g, x + 8, y, x1, plans[cur ^ 1]);
        }
        const Plan8 &pl = plans[cur];
        cur ^= 1;
        if (!pl.live) {
            for (int j = 0; j < pl.lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
        } else if (pl.r.ok) {
            ++shared;
            if (g.opaque) {
                run8<3>(g, out, y, pl, fr);
            } else {
                run8<4>(g, out, y, pl, fr);
            }
        } else {
            lanes8(g, out, x, y, pl.lanes, pl.p, fr, ky0);
        }
    }
    return shared;
}

/// The mean colour of eight pixels along a shared run (Gather::uniform's run; kNc channels
/// summed, 3 for opaque RGBA, whose mean alpha of n ones is exactly 1). A template, so the
/// sums stay in registers (a run-time channel count kept them on the stack, each sample
/// waiting on a store-to-load forward).
template <int kNc>
POSTHASTE_AVX2_INLINE void uniform_run8(const Gather &g, int x, int y, const Run &r, V *acc)
{
    const float step = 2.0f / float(r.n);
    const float u = hash_unit(x, y, 0, g.o.seed);
    for (int k = 0; k < 4; ++k) {
        acc[k] = _mm256_setzero_ps();
    }
    alignas(32) std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    const bool tab = r.n <= kTabulated;
    if (tab) {
        origins8(g, x, y, u, step, r.vx, r.vy, r.n, bx, row);
    }
    for (int i = 0; i < r.n; ++i) {
        const RunAt a = tab ? run_at8(g, bx[i], row[i])
                            : run_at8(g, x, y, -1.0f + (float(i) + u) * step, r.vx, r.vy);
        for (int k = 0; k < kNc; ++k) {
            acc[k] = _mm256_add_ps(acc[k], field8(g, kRed + k, a));
        }
    }
    const V vn = set1(float(r.n));
    for (int k = 0; k < 4; ++k) {
        acc[k] = k < kNc ? _mm256_div_ps(acc[k], vn) : set1(1.0f);
    }
}

/// Gather::uniform for the groups of pixels [x0, x1) of row y; returns how many shared a run.
POSTHASTE_AVX2 int uniform_row_avx2(const Gather &g, Image &out, int y, int x0, int x1, bool runs)
{
    int shared = 0;
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const Frame8 fr = frame8(g, y);
    const VI ky = row_key8(g, y);
    const V most = set1(float(g.o.samples));
    const VI last = _mm256_set1_epi32(g.w - 1);
    const V all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for (int x = x0; x < x1; x += 8) {
        const int lanes = std::min(8, x1 - x);
        const VI xc =
            _mm256_sub_epi32(_mm256_min_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane), last),
                             _mm256_set1_epi32(x));
        V vx, vy, len;
        own8(g, x, y, _mm256_add_epi32(xc, _mm256_set1_epi32(x)), vx, vy, len);
        const V moving = _mm256_cmp_ps(len, set1(0.5f), _CMP_GE_OQ);
        const int live = _mm256_movemask_ps(moving), wanted = (1 << lanes) - 1;
        if (live == 0) {
            for (int j = 0; j < lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
            continue;
        }
        if (runs && (live & wanted) == wanted) {
            const V valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(lanes), lane));
            const Run r = g.run(bounds8(vx, vy, valid));
            if (r.ok) {
                V acc[4];
                if (g.opaque) {
                    uniform_run8<3>(g, x, y, r, acc);
                } else {
                    uniform_run8<4>(g, x, y, r, acc);
                }
                store8(g, out, x, y, lanes, acc, all);
                ++shared;
                continue;
            }
        }
        const VI xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
        const Frame8 f = lanes8_at(fr, xi);
        const V n = _mm256_and_ps(count8(len, most), moving);
        const int n_max = max_lane(n);
        const V step = _mm256_div_ps(set1(2.0f), _mm256_max_ps(n, set1(1.0f)));
        const V u = unit8(pcg8(_mm256_xor_si256(xi, ky)));
        V acc[4] = {
            _mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps()};
        for (int i = 0; i < n_max; ++i) {
            const V fi = set1(float(i));
            const V active = _mm256_cmp_ps(fi, n, _CMP_LT_OQ);
            const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u), step));
            const VI idx = offset8(f, t, vx, vy);
            for (int k = 0; k < 4; ++k) {
                acc[k] = _mm256_add_ps(acc[k], _mm256_and_ps(gather8(g, kRed + k, idx), active));
            }
        }
        for (int k = 0; k < 4; ++k) {
            acc[k] = _mm256_div_ps(acc[k], n);
        }
        store8(g, out, x, y, lanes, acc, moving);
    }
    return shared;
}

}  // namespace posthaste::shading::motion_blur_detail
#endif
