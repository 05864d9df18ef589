// The motion blur rows' lane vocabulary over Highway (motion_blur_gather_kernels.cpp only): the
// hash and jitter, lane reductions, a group's frame and sample offsets, the loads of a shared run,
// the group's lanes and their final weights. A group is eight adjacent pixels of a row (the
// gather's unit, motion_blur_gather.h), so the lanes are FixedTag<float, 8>: compiled only for
// the x86 targets with 256-bit vectors (AVX2, and AVX-512 with its 256-bit forms); the narrower
// targets run the reference (POSTHASTE_MB_GROUP_LANES says which). Like every Highway "-inl.h"
// it is compiled once per target (the toggle guard).

// clang-format off
#if defined(POSTHASTE_SHADING_MOTION_BLUR_GATHER_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef POSTHASTE_SHADING_MOTION_BLUR_GATHER_LANES_INL_H_
#undef POSTHASTE_SHADING_MOTION_BLUR_GATHER_LANES_INL_H_
#else
#define POSTHASTE_SHADING_MOTION_BLUR_GATHER_LANES_INL_H_
#endif
// clang-format on

#include <hwy/highway.h>

#include <algorithm>
#include <cstdint>

#include "core/hwy_math-inl.h"
#include "shading/motion_blur/motion_blur_gather.h"

// Whether this target's vectors hold a group: eight floats.
#undef POSTHASTE_MB_GROUP_LANES
#if HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX2
#define POSTHASTE_MB_GROUP_LANES 1
#else
#define POSTHASTE_MB_GROUP_LANES 0
#endif

#if POSTHASTE_MB_GROUP_LANES
HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::FixedTag<float, 8>;
using DI = hn::RebindToSigned<D>;
using DU = hn::RebindToUnsigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using VU = hn::Vec<DU>;
using M = hn::Mask<D>;
using simd::HWY_NAMESPACE::ClampToRange;

/// pcg_hash on eight lanes.
HWY_INLINE VU Pcg(VU v)
{
    const DU du;
    const VU state = hn::Add(hn::Mul(v, hn::Set(du, 747796405u)), hn::Set(du, 2891336453u));
    const VU shift = hn::Add(hn::ShiftRight<28>(state), hn::Set(du, 4u));
    const VU word = hn::Mul(hn::Xor(hn::Shr(state, shift), state), hn::Set(du, 277803737u));
    return hn::Xor(hn::ShiftRight<22>(word), word);
}
/// hash_to_unit on eight lanes.
HWY_INLINE V Unit(VU h)
{
    const D d;
    return hn::Mul(hn::ConvertTo(d, hn::BitCast(DI(), hn::ShiftRight<8>(h))),
                   hn::Set(d, 1.0f / 16777216.0f));
}
/// Gather::sample_count on eight lanes, as floats.
HWY_INLINE V Count(V len, V most)
{
    const D d;
    const V n = hn::Min(most,
                        hn::Max(hn::Set(d, 2.0f),
                                hn::Ceil(hn::Mul(hn::Set(d, Gather::kSamplesPerHalfLength), len))));
    return hn::Max(hn::Set(d, 1.0f), n);
}
HWY_INLINE float MinLane(V x)
{
    return hn::GetLane(hn::MinOfLanes(D(), x));
}
HWY_INLINE float MaxLane(V x)
{
    return hn::GetLane(hn::MaxOfLanes(D(), x));
}
/// The bounding box of the (vx, vy) lanes in `mask`.
HWY_INLINE Box Bounds(V vx, V vy, M mask)
{
    const D d;
    const V inf = hn::Set(d, kInf), ninf = hn::Set(d, -kInf);
    Box b;
    b.lo_x = MinLane(hn::IfThenElse(mask, vx, inf));
    b.hi_x = MaxLane(hn::IfThenElse(mask, vx, ninf));
    b.lo_y = MinLane(hn::IfThenElse(mask, vy, inf));
    b.hi_y = MaxLane(hn::IfThenElse(mask, vy, ninf));
    return b;
}
/// The lanes below `lanes`.
HWY_INLINE M FirstLanes(int lanes)
{
    return hn::FirstN(D(), std::size_t(lanes));
}

/// The pixel index of lane x + 0.5 + t v, clamped to the frame (Gather::at).
struct Frame {
    V xf, yf, xmax, ymax;
    VI w;
    VI bias;  ///< FloorBits' offset of a row index times w plus a column's
};
/// The bits of floor(x) + 2^23 for lanes x in [0, 2^23): floor(x) plus 2^23's bits, 0x4B000000
/// (the float is exact there). The caller subtracts the offset once for both coordinates; a
/// ConvertTo would add an overflow fix-up (five instructions) that clamped coordinates never
/// need.
HWY_INLINE VI FloorBits(V x)
{
    const D d;
    return hn::BitCast(DI(), hn::Add(hn::Floor(x), hn::Set(d, 8388608.0f)));
}
/// Frame of row y (xf: set per group with LanesAt).
HWY_INLINE Frame RowFrame(const Gather &g, int y)
{
    const D d;
    return Frame{hn::Zero(d),
                 hn::Set(d, float(y) + 0.5f),
                 hn::Set(d, float(g.w) - 0.5f),
                 hn::Set(d, float(g.h) - 0.5f),
                 hn::Set(DI(), g.w),
                 hn::Set(DI(), std::int32_t(0x4B000000u * std::uint32_t(g.w + 1)))};
}
/// `f` at the pixel centres of columns xi.
HWY_INLINE Frame LanesAt(Frame f, VI xi)
{
    const D d;
    f.xf = hn::Add(hn::ConvertTo(d, xi), hn::Set(d, 0.5f));
    return f;
}
/// The row's part of the per-pixel hash hash4(x, y, 0, seed) = pcg_hash(x ^ key).
HWY_INLINE VU RowKey(const Gather &g, int y)
{
    return hn::Set(DU(), pcg_hash(std::uint32_t(y) ^ pcg_hash(0u ^ pcg_hash(g.o.seed))));
}
/// The per-pixel hash of columns xi (RowKey's row).
HWY_INLINE VU PixelHash(VI xi, VU key)
{
    return Pcg(hn::Xor(hn::BitCast(DU(), xi), key));
}
/// The index of the pixel at (px, py) clamped to the frame (a NaN coordinate clamps to 0). The
/// integer arithmetic wraps.
HWY_INLINE VI Index(const Frame &f, V px, V py)
{
    const D d;
    const V zero = hn::Zero(d);
    const V fx = hn::Min(hn::Max(px, zero), f.xmax);
    const V fy = hn::Min(hn::Max(py, zero), f.ymax);
    return hn::Sub(hn::Add(hn::Mul(FloorBits(fy), f.w), FloorBits(fx)), f.bias);
}
/// Gather::at on eight lanes: the index of x + 0.5 + t v clamped to the frame, rounded as there
/// (the product, then the sum).
HWY_INLINE VI Offset(const Frame &f, V t, V vx, V vy)
{
    return Index(f, hn::Add(f.xf, hn::Mul(t, vx)), hn::Add(f.yf, hn::Mul(t, vy)));
}
HWY_INLINE V GatherField(const Gather &g, int field, VI idx)
{
    return hn::GatherIndex(D(), g.f[field], idx);
}

/// A shared sample of a group (Gather::run_origin): where the run of eight pixels lies inside
/// its row, each field is one load; at the left and right edges, a gather of the clamped
/// columns.
struct RunAt {
    bool inside;
    std::size_t base;
    VI idx;
};
/// RunAt of the run starting at column bx of the row that starts at index `row`.
HWY_INLINE RunAt RunAtOrigin(const Gather &g, std::int32_t bx, std::int32_t row)
{
    const DI di;
    RunAt a{
        bx >= 0 && bx + 8 <= g.w, std::size_t(row) + std::size_t(std::max(bx, 0)), hn::Zero(di)};
    if (!a.inside) {
        const VI col = hn::Min(hn::Max(hn::Add(hn::Set(di, bx), hn::Iota(di, 0)), hn::Zero(di)),
                               hn::Set(di, g.w - 1));
        a.idx = hn::Add(hn::Set(di, row), col);
    }
    return a;
}
/// RunAt of sample t of the run (vx, vy) of the group at (x0, y).
HWY_INLINE RunAt RunAtSample(const Gather &g, int x0, int y, float t, float vx, float vy)
{
    int bx, by;
    g.run_origin(x0, y, t, vx, vy, bx, by);
    return RunAtOrigin(g, bx, by * g.w);
}
HWY_INLINE V Field(const Gather &g, int field, const RunAt &a)
{
    return a.inside ? hn::LoadU(D(), g.f[field] + a.base) : GatherField(g, field, a.idx);
}

/// The most samples of a run whose origins a plan tabulates (longer runs compute them as
/// they go).
constexpr int kTabulated = 32;

/// Gather::run_origin for samples t_i = -1 + (i + u) step, i < n <= kTabulated, eight at a
/// time: first columns (unclamped) and row offsets (clamped row x width). Tabulated in the
/// plan, a sample's loads no longer wait on its chain of float-to-int conversions. t and the
/// column are rounded as Gather::run_origin rounds them (the products first), so every target
/// reads the reference's pixels.
HWY_INLINE void Origins(const Gather &g,
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
    const D d;
    const DI di;
    const V lanef = hn::Iota(d, 0.0f);
    const V ox = hn::Set(d, float(x0) + 0.5f), oy = hn::Set(d, float(y) + 0.5f);
    for (int i = 0; i < n; i += 8) {
        const V t = hn::Add(
            hn::Set(d, -1.0f),
            hn::Mul(hn::Add(hn::Add(hn::Set(d, float(i)), lanef), hn::Set(d, u)), hn::Set(d, step)));
        const VI cx = hn::ConvertTo(di, hn::Floor(hn::Add(ox, hn::Mul(t, hn::Set(d, vx)))));
        VI cy = hn::ConvertTo(di, hn::Floor(hn::Add(oy, hn::Mul(t, hn::Set(d, vy)))));
        cy = hn::Min(hn::Max(cy, hn::Zero(di)), hn::Set(di, g.h - 1));
        hn::Store(cx, di, bx + i);
        hn::Store(hn::Mul(cy, hn::Set(di, g.w)), di, row + i);
    }
}

/// Gather::own for pixels x .. x + 7 of row y (columns xc: lanes past the row's end read its
/// last pixel): three loads where the eight lie inside the row.
HWY_INLINE void Own(const Gather &g, int x, int y, VI xc, V &vx, V &vy, V &len)
{
    const D d;
    V wx, wy;
    if (x + 8 <= g.w) {
        const std::size_t i0 = g.index(x, y);
        wx = hn::LoadU(d, g.f[kWx] + i0);
        wy = hn::LoadU(d, g.f[kWy] + i0);
        len = hn::LoadU(d, g.f[kLen] + i0);
    } else {
        const VI ci = hn::Add(hn::Set(DI(), int(g.index(0, y))), xc);
        wx = GatherField(g, kWx, ci);
        wy = GatherField(g, kWy, ci);
        len = GatherField(g, kLen, ci);
    }
    const V k = hn::Mul(hn::Mul(hn::Set(d, 2.0f), len), len);
    vx = hn::Mul(wx, k);
    vy = hn::Mul(wy, k);
}

/// Writes the first `lanes` results (r[channel][lane]) of row y from x; with `keep`, the lanes
/// not in it are copied from the input.
HWY_INLINE void Store(
    const Gather &g, Image &out, int x, int y, int lanes, const V *r, const M *keep)
{
    const D d;
    if ((!keep || hn::AllTrue(d, *keep)) && lanes == 8 && g.nc == 4 && out.channels() == 4) {
        hn::StoreInterleaved4(r[0], r[1], r[2], r[3], d, out.pixel(x, y));
        return;
    }
    HWY_ALIGN float v[4][8];
    for (int k = 0; k < 4; ++k) {
        hn::Store(r[k], d, v[k]);
    }
    std::uint8_t bits = 0xff;
    if (keep) {
        hn::StoreMaskBits(d, *keep, &bits);
    }
    for (int j = 0; j < lanes; ++j) {
        if (bits & (1u << j)) {
            float *po = out.pixel(x + j, y);
            for (int k = 0; k < g.nc; ++k) {
                po[k] = v[k][j];
            }
        } else {
            g.copy_pixel(out, x + j, y);
        }
    }
}

/// The eight lanes of a group: Gather::Lane, and the pixels' own records.
struct Lanes {
    VI xi;  ///< pixel columns
    M valid, own, shared;
    V cvx, cvy, clen, inv_own, vx, vy, len, dx, dy, clz, cc[4];
};

/// Gather::finish on eight lanes; stores the first `lanes`.
HWY_INLINE void Finish(const Gather &g,
                       Image &out,
                       int x,
                       int y,
                       int lanes,
                       const Lanes &p,
                       V F,
                       V B,
                       const V *fg,
                       const V *bg,
                       V own_weight)
{
    const D d;
    const V one = hn::Set(d, 1.0f);
    const M full = hn::Ge(F, one);
    const V wc = hn::IfThenElse(p.own, hn::Mul(hn::Set(d, 1e-3f), own_weight), one);
    B = hn::Add(B, wc);
    const V rest = hn::Div(hn::Sub(one, F), B);
    const V inv_f = hn::Div(one, F);
    V r[4];
    for (int k = 0; k < 4; ++k) {
        const V blend = hn::Add(fg[k], hn::Mul(rest, hn::Add(bg[k], hn::Mul(wc, p.cc[k]))));
        r[k] = hn::IfThenElse(full, hn::Mul(fg[k], inv_f), blend);
    }
    if (g.opaque) {
        r[3] = one;
    }
    Store(g, out, x, y, lanes, r, nullptr);
}

/// Gather::second_lane on the lanes in `second` (n: the front estimate's sample counts; hu: the
/// pixels' hashes); returns the weight of one sample.
HWY_INLINE V
SecondLanes(const Gather &g, const Frame &f, const Lanes &p, M second, V n, VU hu, V &B, V *bg)
{
    const D d;
    const V one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f), zero = hn::Zero(d);
    const V inv_soft = hn::Set(d, g.inv_soft);
    const V half_n = hn::Floor(hn::Mul(hn::Add(n, one), half));
    const V m = hn::IfThenElseZero(
        second,
        hn::Max(hn::Set(d, 2.0f), hn::Min(Count(p.clen, hn::Set(d, float(g.o.samples))), half_n)));
    const V mstep = hn::Div(hn::Set(d, 2.0f), hn::Max(m, one));
    const V wm = hn::Mul(hn::Mul(p.clen, mstep), p.inv_own);
    const V u2 = Unit(Pcg(hu));
    const int m_max = int(MaxLane(m));
    for (int i = 0; i < m_max; ++i) {
        const V fi = hn::Set(d, float(i));
        const M active = hn::Lt(fi, m);
        const V t = hn::Add(hn::Set(d, -1.0f), hn::Mul(hn::Add(fi, u2), mstep));
        const VI idx = Offset(f, t, p.cvx, p.cvy);
        const V fr = ClampToRange(
            hn::MulAdd(hn::Sub(p.clz, GatherField(g, kLogZ, idx)), inv_soft, half), zero, one);
        const V wb = hn::IfThenElseZero(active, hn::Mul(hn::Sub(one, fr), wm));
        B = hn::Add(B, wb);
        for (int k = 0; k < 4; ++k) {
            bg[k] = hn::MulAdd(wb, GatherField(g, kRed + k, idx), bg[k]);
        }
    }
    return wm;
}

/// Gather::reconstruct_lane on eight lanes: each follows its own plan and jitter (lanes past
/// their sample count add nothing).
HWY_INLINE void PerLane(
    const Gather &g, Image &out, int x, int y, int lanes, const Lanes &p, const Frame &fr, VU key)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V inv_soft = hn::Set(d, g.inv_soft);
    const Frame f = LanesAt(fr, p.xi);
    const V n = Count(p.len, hn::Set(d, float(g.o.samples)));
    const V step = hn::Div(hn::Set(d, 2.0f), n);
    const V delta = hn::Mul(p.len, step);
    const V own_w = hn::IfThenElseZero(p.shared, hn::Mul(delta, p.inv_own));
    const VU hu = PixelHash(p.xi, key);
    const V u = Unit(hu);
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const int n_max = int(MaxLane(n));
    for (int i = 0; i < n_max; ++i) {
        const V fi = hn::Set(d, float(i));
        const M active = hn::Lt(fi, n);
        const V t = hn::Add(hn::Set(d, -1.0f), hn::Mul(hn::Add(fi, u), step));
        const VI idx = Offset(f, t, p.vx, p.vy);
        const V T = hn::Mul(hn::Abs(t), p.len);
        const V fr_w = ClampToRange(
            hn::MulAdd(hn::Sub(p.clz, GatherField(g, kLogZ, idx)), inv_soft, half), zero, one);
        const V reach_s =
            ClampToRange(hn::Sub(hn::Add(GatherField(g, kLen, idx), half), T), zero, one);
        const V reach_c = ClampToRange(hn::Sub(hn::Add(p.clen, half), T), zero, one);
        const V along = hn::Abs(
            hn::MulAdd(GatherField(g, kWx, idx), p.dx, hn::Mul(GatherField(g, kWy, idx), p.dy)));
        const V wf =
            hn::IfThenElseZero(active, hn::Mul(hn::Mul(hn::Mul(fr_w, reach_s), along), delta));
        const V wb =
            hn::IfThenElseZero(active, hn::Mul(hn::Mul(hn::Sub(one, fr_w), reach_c), own_w));
        F = hn::Add(F, wf);
        B = hn::Add(B, wb);
        for (int k = 0; k < 4; ++k) {
            const V c = GatherField(g, kRed + k, idx);
            fg[k] = hn::MulAdd(wf, c, fg[k]);
            bg[k] = hn::MulAdd(wb, c, bg[k]);
        }
    }
    V own_weight = own_w;
    const M second = hn::AndNot(p.shared, p.own);
    if (!hn::AllFalse(d, second)) {
        own_weight = hn::IfThenElse(second, SecondLanes(g, f, p, second, n, hu, B, bg), own_weight);
    }
    Finish(g, out, x, y, lanes, p, F, B, fg, bg, own_weight);
}

}  // namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();
#endif  // POSTHASTE_MB_GROUP_LANES

#endif  // include guard
