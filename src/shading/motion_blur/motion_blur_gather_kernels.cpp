// The motion blur's gather rows, one source over Highway's lane types: eight adjacent pixels (a
// group, motion_blur_gather.h) a vector, a group that shares its sample positions reading each
// field of a sample with one load. Gather::reconstruct and Gather::uniform are the reference they
// follow; on targets whose vectors hold fewer than eight floats, the rows run the reference.
// Compiled without FP contraction (CMakeLists.txt): the fused steps are the ones written as
// MulAdd, so every target gives the same bits.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/motion_blur/motion_blur_gather_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "shading/motion_blur/motion_blur_gather_lanes-inl.h"
// clang-format on

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shading/motion_blur/motion_blur_gather.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE {

#if POSTHASTE_MB_GROUP_LANES

/// The front estimate along a shared run (Gather::reconstruct_run's first loop; kBack: also
/// the own-surface sums, needed only where some lane's own path is the shared one). The sums
/// leave out the path length per sample, delta, which the caller multiplies in.
template <bool kBack, int kNc>
HWY_INLINE void FrontRun(const Gather &g,
                         int x,
                         int y,
                         const Run &r,
                         float u,
                         const std::int32_t *bx,
                         const std::int32_t *row,
                         const Lanes &p,
                         V &F,
                         V &B,
                         V *fg,
                         V *bg)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V inv_soft = hn::Set(d, g.inv_soft), dx = hn::Set(d, r.dx), dy = hn::Set(d, r.dy);
    const float step = 2.0f / float(r.n);
    for (int i = 0; i < r.n; ++i) {
        const float t = -1.0f + (float(i) + u) * step;
        const V rT = hn::Set(d, 0.5f - std::abs(t) * r.len);
        const RunAt a = bx ? RunAtOrigin(g, bx[i], row[i]) : RunAtSample(g, x, y, t, r.vx, r.vy);
        const V fr =
            ClampToRange(hn::MulAdd(hn::Sub(p.clz, Field(g, kLogZ, a)), inv_soft, half), zero, one);
        const V reach_s = ClampToRange(hn::Add(Field(g, kLen, a), rT), zero, one);
        const V along = hn::Abs(hn::MulAdd(Field(g, kWx, a), dx, hn::Mul(Field(g, kWy, a), dy)));
        const V wf = hn::Mul(hn::Mul(fr, reach_s), along);
        F = hn::Add(F, wf);
        V c[4];
        for (int k = 0; k < kNc; ++k) {
            c[k] = Field(g, kRed + k, a);
            fg[k] = hn::MulAdd(wf, c[k], fg[k]);
        }
        if constexpr (kBack) {
            const V reach_c = ClampToRange(hn::Add(p.clen, rT), zero, one);
            const V wb = hn::NegMulAdd(fr, reach_c, reach_c);  // (1 - fr) reach_c
            B = hn::Add(B, wb);
            for (int k = 0; k < kNc; ++k) {
                bg[k] = hn::MulAdd(wb, c[k], bg[k]);
            }
        }
    }
}

/// A group's plan: everything Gather::reconstruct decides before its sample loops. The row
/// plans the next group before it samples this one, so that the plan's chain of latencies
/// (hashes, lookup, square roots, divisions, reductions) overlaps the previous group's loops.
struct Plan {
    int x, lanes;
    bool live;
    Lanes p;
    Run r;        ///< the shared run (r.ok false: each lane samples on its own)
    Run c;        ///< the second direction's shared run, for the lanes whose path is not shared
    bool second;  ///< some lane needs the second direction
    float u, u2;
    /// Sample origins of the shared runs (front: r.n of them, second: m), when tabulated.
    HWY_ALIGN std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    HWY_ALIGN std::int32_t bx2[kTabulated + 8], row2[kTabulated + 8];
    int m;
};

HWY_INLINE void MakePlan(const Gather &g, int x, int y, int x1, Plan &pl)
{
    const D d;
    const DI di;
    const V half = hn::Set(d, 0.5f), one = hn::Set(d, 1.0f);
    pl.x = x;
    pl.lanes = std::min(8, x1 - x);
    const Lookup l = g.lookup(x, y);
    pl.live = l.len >= 0.5f;
    if (!pl.live) {
        return;
    }
    Lanes &p = pl.p;
    p.xi = hn::Add(hn::Set(di, x), hn::Iota(di, 0));
    // Lanes past the row's end (narrow tiles) compute on the last pixel, unstored.
    const VI xc = hn::Min(p.xi, hn::Set(di, g.w - 1));
    p.valid = FirstLanes(pl.lanes);
    const std::size_t i0 = g.index(x, y);
    if (x + 8 <= g.w) {
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = hn::LoadU(d, g.f[kRed + k] + i0);
        }
        p.clz = hn::LoadU(d, g.f[kLogZ] + i0);
    } else {
        const VI ci = hn::Add(hn::Set(di, int(g.index(0, y))), xc);
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = GatherField(g, kRed + k, ci);
        }
        p.clz = GatherField(g, kLogZ, ci);
    }
    Own(g, x, y, xc, p.cvx, p.cvy, p.clen);
    p.own = hn::Ge(p.clen, half);
    // One division for the direction and the own weight.
    const V inv_len = hn::IfThenElseZero(p.own, hn::Div(one, p.clen));
    const V dcx = hn::Mul(p.cvx, inv_len), dcy = hn::Mul(p.cvy, inv_len);
    const V ldx = hn::Set(d, l.dx), ldy = hn::Set(d, l.dy), llen = hn::Set(d, l.len);
    const V cosine = hn::Abs(hn::Add(hn::Mul(dcx, ldx), hn::Mul(dcy, ldy)));
    p.shared = hn::And(hn::And(p.own, hn::Gt(cosine, hn::Set(d, 0.9f))),
                       hn::Ge(p.clen, hn::Mul(half, llen)));
    p.inv_own = hn::Mul(half, inv_len);
    p.dx = hn::IfThenElse(p.shared, dcx, ldx);
    p.dy = hn::IfThenElse(p.shared, dcy, ldy);
    p.vx = hn::IfThenElse(p.shared, hn::Mul(dcx, llen), hn::Set(d, l.vx));
    p.vy = hn::IfThenElse(p.shared, hn::Mul(dcy, llen), hn::Set(d, l.vy));
    const M longer = hn::And(p.shared, hn::Gt(p.clen, hn::Mul(hn::Set(d, 0.8f), llen)));
    p.vx = hn::IfThenElse(longer, p.cvx, p.vx);
    p.vy = hn::IfThenElse(longer, p.cvy, p.vy);
    p.len = hn::IfThenElse(longer, p.clen, llen);
    g.run(Bounds(p.vx, p.vy, p.valid), pl.r);
    pl.c.ok = 0;
    pl.second = false;
    if (pl.r.ok) {
        const std::uint32_t hu = hash4(std::uint32_t(x), std::uint32_t(y), 0u, g.o.seed);
        pl.u = hash_to_unit(hu);
        pl.u2 = hash_to_unit(pcg_hash(hu));
        const M second_valid = hn::And(hn::AndNot(p.shared, p.own), p.valid);
        pl.second = !hn::AllFalse(d, second_valid);
        if (pl.second) {
            g.run(Bounds(p.cvx, p.cvy, second_valid), pl.c);
        }
        if (pl.r.n <= kTabulated) {
            Origins(g, x, y, pl.u, 2.0f / float(pl.r.n), pl.r.vx, pl.r.vy, pl.r.n, pl.bx, pl.row);
        }
        if (pl.c.ok) {
            pl.m = std::max(2, std::min(pl.c.n, (pl.r.n + 1) / 2));
            if (pl.m <= kTabulated) {
                Origins(
                    g, x, y, pl.u2, 2.0f / float(pl.m), pl.c.vx, pl.c.vy, pl.m, pl.bx2, pl.row2);
            }
        }
    }
}

/// Gather::reconstruct_run on eight lanes (kNc: colour channels summed; 3 for opaque RGBA).
template <int kNc>
HWY_INLINE void SharedRun(
    const Gather &g, Image &out, int y, const Plan &pl, const Frame &fr, VU key)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V inv_soft = hn::Set(d, g.inv_soft);
    const Lanes &p = pl.p;
    const Run &r = pl.r;
    const int x = pl.x;
    const float delta = r.len * (2.0f / float(r.n));
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const std::int32_t *bx = r.n <= kTabulated ? pl.bx : nullptr;
    if (!hn::AllFalse(d, hn::And(p.shared, p.valid))) {
        FrontRun<true, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    } else {
        FrontRun<false, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    }
    const V vdelta = hn::Set(d, delta);
    V own_weight = hn::IfThenElseZero(p.shared, hn::Mul(vdelta, p.inv_own));
    F = hn::Mul(F, vdelta);
    B = hn::Mul(B, own_weight);
    for (int k = 0; k < 4; ++k) {
        fg[k] = hn::Mul(fg[k], vdelta);
        bg[k] = hn::Mul(bg[k], own_weight);
    }
    if (pl.second) {
        const M second = hn::AndNot(p.shared, p.own);
        const Run &c = pl.c;
        if (c.ok) {
            const int m = pl.m;
            const float mstep = 2.0f / float(m);
            const V wm = hn::IfThenElseZero(second, hn::Set(d, 1.0f / float(m)));
            for (int i = 0; i < m; ++i) {
                const RunAt a =
                    m <= kTabulated
                        ? RunAtOrigin(g, pl.bx2[i], pl.row2[i])
                        : RunAtSample(g, x, y, -1.0f + (float(i) + pl.u2) * mstep, c.vx, c.vy);
                const V f = ClampToRange(
                    hn::MulAdd(hn::Sub(p.clz, Field(g, kLogZ, a)), inv_soft, half), zero, one);
                const V wb = hn::NegMulAdd(f, wm, wm);  // (1 - f) wm
                B = hn::Add(B, wb);
                for (int k = 0; k < kNc; ++k) {
                    bg[k] = hn::MulAdd(wb, Field(g, kRed + k, a), bg[k]);
                }
            }
            own_weight = hn::IfThenElse(second, wm, own_weight);
        } else {
            const VU hv = PixelHash(p.xi, key);
            own_weight = hn::IfThenElse(
                second,
                SecondLanes(g, LanesAt(fr, p.xi), p, second, hn::Set(d, float(r.n)), hv, B, bg),
                own_weight);
        }
    }
    Finish(g, out, x, y, pl.lanes, p, F, B, fg, bg, own_weight);
}

/// The mean colour of eight pixels along a shared run (Gather::uniform's run; kNc channels
/// summed, 3 for opaque RGBA, whose mean alpha of n ones is exactly 1). A template, so the
/// sums stay in registers (a run-time channel count kept them on the stack, each sample
/// waiting on a store-to-load forward).
template <int kNc>
HWY_INLINE void UniformRun(const Gather &g, int x, int y, const Run &r, V *acc)
{
    const D d;
    const float step = 2.0f / float(r.n);
    const float u = hash_unit(x, y, 0, g.o.seed);
    for (int k = 0; k < 4; ++k) {
        acc[k] = hn::Zero(d);
    }
    HWY_ALIGN std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    const bool tab = r.n <= kTabulated;
    if (tab) {
        Origins(g, x, y, u, step, r.vx, r.vy, r.n, bx, row);
    }
    for (int i = 0; i < r.n; ++i) {
        const RunAt a = tab ? RunAtOrigin(g, bx[i], row[i])
                            : RunAtSample(g, x, y, -1.0f + (float(i) + u) * step, r.vx, r.vy);
        for (int k = 0; k < kNc; ++k) {
            acc[k] = hn::Add(acc[k], Field(g, kRed + k, a));
        }
    }
    const V vn = hn::Set(d, float(r.n));
    for (int k = 0; k < 4; ++k) {
        acc[k] = k < kNc ? hn::Div(acc[k], vn) : hn::Set(d, 1.0f);
    }
}

int ReconstructRow(const Gather &g, Image &out, int y, int x0, int x1)
{
    int shared = 0;
    const Frame fr = RowFrame(g, y);
    const VU key = RowKey(g, y);
    Plan plans[2];
    int cur = 0;
    MakePlan(g, x0, y, x1, plans[0]);
    for (int x = x0; x < x1; x += 8) {
        if (x + 8 < x1) {
            MakePlan(g, x + 8, y, x1, plans[cur ^ 1]);
        }
        const Plan &pl = plans[cur];
        cur ^= 1;
        if (!pl.live) {
            for (int j = 0; j < pl.lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
        } else if (pl.r.ok) {
            ++shared;
            if (g.opaque) {
                SharedRun<3>(g, out, y, pl, fr, key);
            } else {
                SharedRun<4>(g, out, y, pl, fr, key);
            }
        } else {
            PerLane(g, out, x, y, pl.lanes, pl.p, fr, key);
        }
    }
    return shared;
}

int UniformRow(const Gather &g, Image &out, int y, int x0, int x1, bool runs)
{
    const D d;
    const DI di;
    int shared = 0;
    const Frame fr = RowFrame(g, y);
    const VU key = RowKey(g, y);
    const V most = hn::Set(d, float(g.o.samples));
    for (int x = x0; x < x1; x += 8) {
        const int lanes = std::min(8, x1 - x);
        const VI xi = hn::Add(hn::Set(di, x), hn::Iota(di, 0));
        V vx, vy, len;
        Own(g, x, y, hn::Min(xi, hn::Set(di, g.w - 1)), vx, vy, len);
        const M moving = hn::Ge(len, hn::Set(d, 0.5f));
        if (hn::AllFalse(d, moving)) {
            for (int j = 0; j < lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
            continue;
        }
        const M valid = FirstLanes(lanes);
        if (runs && hn::AllTrue(d, hn::Or(moving, hn::Not(valid)))) {
            const Run r = g.run(Bounds(vx, vy, valid));
            if (r.ok) {
                V acc[4];
                if (g.opaque) {
                    UniformRun<3>(g, x, y, r, acc);
                } else {
                    UniformRun<4>(g, x, y, r, acc);
                }
                Store(g, out, x, y, lanes, acc, nullptr);
                ++shared;
                continue;
            }
        }
        const Frame f = LanesAt(fr, xi);
        const V n = hn::IfThenElseZero(moving, Count(len, most));
        const int n_max = int(MaxLane(n));
        const V step = hn::Div(hn::Set(d, 2.0f), hn::Max(n, hn::Set(d, 1.0f)));
        const V u = Unit(PixelHash(xi, key));
        // Sample i at t = -1 + (i + u) step, rounded as the reference rounds it (the product,
        // then the sum; Offset likewise): the same pixels, so the same bits. (Fused steps
        // a + i b put a sample on the next pixel now and then: one pixel in 10^5 off by up to
        // 0.036 at 2026-11-29's sample counts.)
        const V minus_one = hn::Set(d, -1.0f);
        V acc[4] = {hn::Zero(d), hn::Zero(d), hn::Zero(d), hn::Zero(d)};
        for (int i = 0; i < n_max; ++i) {
            const V fi = hn::Set(d, float(i));
            const M active = hn::Lt(fi, n);
            const V t = hn::Add(minus_one, hn::Mul(hn::Add(fi, u), step));
            const VI idx = Offset(f, t, vx, vy);
            for (int k = 0; k < 4; ++k) {
                acc[k] = hn::Add(acc[k], hn::IfThenElseZero(active, GatherField(g, kRed + k, idx)));
            }
        }
        for (int k = 0; k < 4; ++k) {
            acc[k] = hn::Div(acc[k], n);
        }
        Store(g, out, x, y, lanes, acc, &moving);
    }
    return shared;
}

#else  // fewer than eight lanes: the reference, a group at a time

int ReconstructRow(const Gather &g, Image &out, int y, int x0, int x1)
{
    return g.reconstruct_groups(out, y, x0, x1);
}

int UniformRow(const Gather &g, Image &out, int y, int x0, int x1, bool runs)
{
    return g.uniform_groups(out, y, x0, x1, runs);
}

#endif

bool GroupLanes()
{
    return POSTHASTE_MB_GROUP_LANES != 0;
}

}  // namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading::motion_blur_detail {

HWY_EXPORT(ReconstructRow);
HWY_EXPORT(UniformRow);
HWY_EXPORT(GroupLanes);

int reconstruct_row(const Gather &g, Image &out, int y, int x0, int x1)
{
    return HWY_DYNAMIC_DISPATCH(ReconstructRow)(g, out, y, x0, x1);
}

int uniform_row(const Gather &g, Image &out, int y, int x0, int x1, bool runs)
{
    return HWY_DYNAMIC_DISPATCH(UniformRow)(g, out, y, x0, x1, runs);
}

bool group_lanes()
{
    return HWY_DYNAMIC_DISPATCH(GroupLanes)();
}

}  // namespace posthaste::shading::motion_blur_detail
#endif
