// ssgi's depth- and normal-aware upsample of a row (ssgi_resolve_kernels.h), one source over
// Highway's lane types: one output pixel a lane, its four reduced-resolution taps permuted from
// the reduced rows' columns (gathered where a vector's taps span more columns than lanes).
// Compiled without FMA contraction (CMakeLists.txt), so every target gives the bits of the
// scalar loop it replaced: the same operations in the same order.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/gi/ssgi_resolve_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "shading/gi/ssgi_resolve_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>

#include "core/sanitize.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using M = hn::Mask<D>;
using Idx = decltype(hn::IndicesFromVec(D(), hn::Zero(DI())));
constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// v, or 0 where it is not finite (the values a scan replacing them would give).
HWY_INLINE V FiniteOrZero(V v)
{
    return hn::IfThenElseZero(hn::IsFinite(v), v);
}

/// The full-resolution pixel a lane stands for.
struct Pixel {
    V z, inv, nx, ny, nz, inv_len2;
    M known;  ///< Its normal is known (non-zero, finite).
};

/// What the four taps add up.
struct Sums {
    V r, g, b, w, best, nr, ng, nb;
};

/// A tap's values per lane: the reduced pixel's depth, normal and light.
struct TapValues {
    V z, nx, ny, nz, r, g, b;
};

/// A tap's values gathered from a reduced row (z, n, v) at the columns idx.
HWY_INLINE TapValues GatherTap(const float *zr, const float *nr, const float *vr, VI idx)
{
    const D d;
    const VI i3 = hn::Mul(idx, hn::Set(DI(), 3));
    return {hn::GatherIndex(d, zr, idx),
            hn::GatherIndex(d, nr, i3),
            hn::GatherIndex(d, nr + 1, i3),
            hn::GatherIndex(d, nr + 2, i3),
            hn::GatherIndex(d, vr, i3),
            hn::GatherIndex(d, vr + 1, i3),
            hn::GatherIndex(d, vr + 2, i3)};
}

/// A reduced row's columns base .. base + lanes - 1, loaded once: where a vector's taps all lie
/// among them (the upsample's columns step by one every stride pixels), each tap is a lane
/// permutation of these instead of seven gathers. The same values, so the same bits.
HWY_INLINE TapValues LoadColumns(const float *zr, const float *nr, const float *vr, int base)
{
    const D d;
    TapValues t;
    t.z = hn::LoadU(d, zr + base);
    hn::LoadInterleaved3(d, nr + 3 * std::size_t(base), t.nx, t.ny, t.nz);
    hn::LoadInterleaved3(d, vr + 3 * std::size_t(base), t.r, t.g, t.b);
    return t;
}

HWY_INLINE TapValues LookupTap(const TapValues &c, Idx idx)
{
    return {hn::TableLookupLanes(c.z, idx),
            hn::TableLookupLanes(c.nx, idx),
            hn::TableLookupLanes(c.ny, idx),
            hn::TableLookupLanes(c.nz, idx),
            hn::TableLookupLanes(c.r, idx),
            hn::TableLookupLanes(c.g, idx),
            hn::TableLookupLanes(c.b, idx)};
}

/// One tap of values tv, bilinear weight bw.
HWY_INLINE void Tap(const Pixel &p, V bw, const TapValues &tv, Sums &s)
{
    const D d;
    const V zero = hn::Zero(d);
    const V tz = tv.z, tnx = tv.nx, tny = tv.ny, tnz = tv.nz;
    const V dz = hn::Abs(hn::Sub(tz, p.z));
    // max(0, n.m)^2 / |n|^2, to the 4th: max(0, n.m / |n|)^8; 1 where either is unknown.
    const M tap_known = hn::Or(hn::Or(hn::Ne(tnx, zero), hn::Ne(tny, zero)), hn::Ne(tnz, zero));
    const V dot = hn::Add(hn::Add(hn::Mul(p.nx, tnx), hn::Mul(p.ny, tny)), hn::Mul(p.nz, tnz));
    const V t = hn::IfThenElse(hn::Lt(zero, dot), dot, zero);  // std::max(0, dot)
    const V t2 = hn::Mul(hn::Mul(t, t), p.inv_len2);
    V nw = hn::Mul(t2, t2);
    nw = hn::Mul(nw, nw);
    nw = hn::IfThenElse(hn::And(p.known, tap_known), nw, hn::Set(d, 1.0f));
    const V tent = hn::Sub(hn::Set(d, 1.0f), hn::Mul(dz, p.inv));
    const V wt = hn::Mul(hn::Mul(bw, hn::IfThenElseZero(hn::Lt(zero, tent), tent)), nw);
    const V vr_ = tv.r, vg = tv.g, vb = tv.b;
    s.r = hn::Add(s.r, hn::Mul(wt, vr_));
    s.g = hn::Add(s.g, hn::Mul(wt, vg));
    s.b = hn::Add(s.b, hn::Mul(wt, vb));
    s.w = hn::Add(s.w, wt);
    const M closer = hn::Lt(dz, s.best);  // false for NaN
    s.best = hn::IfThenElse(closer, dz, s.best);
    s.nr = hn::IfThenElse(closer, vr_, s.nr);
    s.ng = hn::IfThenElse(closer, vg, s.ng);
    s.nb = hn::IfThenElse(closer, vb, s.nb);
}

/// The four taps of a vector of pixels: (row 0, i0), (row 0, i1), (row 1, i0), (row 1, i1).
struct Taps {
    TapValues t00, t01, t10, t11;
};

HWY_INLINE Taps GatherTaps(const SsgiUpsampleRow &r, VI i0, VI i1)
{
    return {GatherTap(r.z0, r.n0, r.v0, i0),
            GatherTap(r.z0, r.n0, r.v0, i1),
            GatherTap(r.z1, r.n1, r.v1, i0),
            GatherTap(r.z1, r.n1, r.v1, i1)};
}

/// The upsampled light of one vector of pixels starting at x (lanes past the row padded).
HWY_INLINE void UpsampleVector(
    const SsgiUpsampleRow &r, V z, V nx, V ny, V nz, const Taps &taps, V fx, V &o0, V &o1, V &o2)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    Pixel p;
    p.z = z;
    p.inv = hn::Div(one, hn::Mul(hn::Set(d, 0.1f), z));
    p.nx = nx;
    p.ny = ny;
    p.nz = nz;
    const V len2 = hn::Add(hn::Add(hn::Mul(nx, nx), hn::Mul(ny, ny)), hn::Mul(nz, nz));
    // len2 > 1e-12 and finite (NaN fails both compares).
    p.known = hn::And(hn::Gt(len2, hn::Set(d, 1e-12f)), hn::Lt(len2, inf));
    p.inv_len2 = hn::IfThenElseZero(p.known, hn::Div(one, len2));
    const V fy = hn::Set(d, r.fy), one_fy = hn::Set(d, 1.0f - r.fy), one_fx = hn::Sub(one, fx);
    Sums s{zero, zero, zero, zero, inf, zero, zero, zero};
    Tap(p, hn::Mul(one_fx, one_fy), taps.t00, s);
    Tap(p, hn::Mul(fx, one_fy), taps.t01, s);
    Tap(p, hn::Mul(one_fx, fy), taps.t10, s);
    Tap(p, hn::Mul(fx, fy), taps.t11, s);
    const V rw = hn::Div(one, s.w);
    const M weighs = hn::Gt(s.w, hn::Set(d, 1e-6f));
    const M near = hn::Lt(s.best, inf);
    // The sky (depth not > 0, or not finite): 0.
    const M surface = hn::And(hn::Gt(z, zero), hn::Lt(hn::Abs(z), inf));
    o0 = hn::IfThenElseZero(
        surface, hn::IfThenElse(weighs, hn::Mul(s.r, rw), hn::IfThenElseZero(near, s.nr)));
    o1 = hn::IfThenElseZero(
        surface, hn::IfThenElse(weighs, hn::Mul(s.g, rw), hn::IfThenElseZero(near, s.ng)));
    o2 = hn::IfThenElseZero(
        surface, hn::IfThenElse(weighs, hn::Mul(s.b, rw), hn::IfThenElseZero(near, s.nb)));
}

/// The albedo (and intensity, and 1 - metallic) of the pixels x .. x + lanes - 1 on o.
HWY_INLINE void Apply(const SsgiUpsampleRow &r, int x, V &o0, V &o1, V &o2)
{
    const D d;
    const DI di;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    V k = hn::Set(d, r.intensity);
    const VI xi = hn::Add(hn::Set(di, x), hn::Iota(di, 0));
    if (r.material) {
        // Channel 1 of mc: loaded where mc is 2, 3 or 4, gathered otherwise.
        const float *m = r.material + std::size_t(x) * std::size_t(r.mc);
        V m0, metal, m2, m3;
        if (r.mc == 3) {
            hn::LoadInterleaved3(d, m, m0, metal, m2);
        } else if (r.mc == 4) {
            hn::LoadInterleaved4(d, m, m0, metal, m2, m3);
        } else if (r.mc == 2) {
            hn::LoadInterleaved2(d, m, m0, metal);
        } else {
            metal = hn::GatherIndex(d, r.material + 1, hn::Mul(xi, hn::Set(di, r.mc)));
        }
        // std::clamp(metal, 0, 1), then 1 - it where metal is finite, else 1.
        const V lo = hn::IfThenElse(hn::Lt(metal, zero), zero, metal);
        const V clamped = hn::IfThenElse(hn::Lt(one, lo), one, lo);
        const M finite = hn::Lt(hn::Abs(metal), hn::Set(d, std::numeric_limits<float>::infinity()));
        k = hn::Mul(k, hn::IfThenElse(finite, hn::Sub(one, clamped), one));
    }
    V a0, a1, a2;
    if (r.na == 3) {
        hn::LoadInterleaved3(d, r.albedo + 3 * std::size_t(x), a0, a1, a2);
    } else {
        const VI ai = hn::Mul(xi, hn::Set(di, r.na));
        a0 = hn::GatherIndex(d, r.albedo, ai);
        a1 = hn::GatherIndex(d, r.albedo + std::min(1, r.na - 1), ai);
        a2 = hn::GatherIndex(d, r.albedo + std::min(2, r.na - 1), ai);
    }
    // A negative albedo (no surface has one) reflects nothing.
    a0 = hn::Max(FiniteOrZero(a0), zero);
    a1 = hn::Max(FiniteOrZero(a1), zero);
    a2 = hn::Max(FiniteOrZero(a2), zero);
    // k a max(0, o), in that order, at most float's largest.
    const V top = hn::Set(d, std::numeric_limits<float>::max());
    o0 = hn::Min(hn::Mul(hn::Mul(k, a0), hn::IfThenElseZero(hn::Lt(zero, o0), o0)), top);
    o1 = hn::Min(hn::Mul(hn::Mul(k, a1), hn::IfThenElseZero(hn::Lt(zero, o1), o1)), top);
    o2 = hn::Min(hn::Mul(hn::Mul(k, a2), hn::IfThenElseZero(hn::Lt(zero, o2), o2)), top);
}

void UpsampleRow(const SsgiUpsampleRow &r, int w, float *out)
{
    const D d;
    const DI di;
    const int lanes = int(hn::Lanes(d));
    V o0, o1, o2, nx, ny, nz;
    int x = 0;
    for (; x + lanes <= w; x += lanes) {
        if (r.n3) {
            hn::LoadInterleaved3(d, r.n3 + 3 * std::size_t(x), nx, ny, nz);
        } else {
            nx = hn::LoadU(d, r.nx + x);
            ny = hn::LoadU(d, r.ny + x);
            nz = hn::LoadU(d, r.nz + x);
        }
        nx = FiniteOrZero(nx);
        ny = FiniteOrZero(ny);
        nz = FiniteOrZero(nz);
        const VI i0 = hn::LoadU(di, r.i0 + x), i1 = hn::LoadU(di, r.i1 + x);
        // The columns are non-decreasing: the vector's taps lie in [i0[x], i1[x + lanes - 1]].
        const int base = r.i0[x];
        Taps taps;
        if (r.i1[x + lanes - 1] - base < lanes && base + lanes <= r.ow) {
            const VI vbase = hn::Set(di, base);
            const Idx l0 = hn::IndicesFromVec(d, hn::Sub(i0, vbase));
            const Idx l1 = hn::IndicesFromVec(d, hn::Sub(i1, vbase));
            const TapValues c0 = LoadColumns(r.z0, r.n0, r.v0, base);
            const TapValues c1 = LoadColumns(r.z1, r.n1, r.v1, base);
            taps = {LookupTap(c0, l0), LookupTap(c0, l1), LookupTap(c1, l0), LookupTap(c1, l1)};
        } else {
            taps = GatherTaps(r, i0, i1);
        }
        UpsampleVector(
            r, hn::LoadU(d, r.z + x), nx, ny, nz, taps, hn::LoadU(d, r.fx + x), o0, o1, o2);
        if (r.albedo) {
            Apply(r, x, o0, o1, o2);
        }
        hn::StoreInterleaved3(o0, o1, o2, d, out + 3 * std::size_t(x));
    }
    if (x == w) {
        return;
    }
    // The row's last pixels through the same vector code on padded copies (tap 0, depth 0:
    // results not stored), the albedo as Apply does it, one pixel at a time.
    const int m = w - x;
    HWY_ALIGN float z[kMaxLanes] = {}, pnx[kMaxLanes] = {}, pny[kMaxLanes] = {},
                    pnz[kMaxLanes] = {}, fx[kMaxLanes] = {}, o[3 * kMaxLanes];
    HWY_ALIGN std::int32_t i0[kMaxLanes] = {}, i1[kMaxLanes] = {};
    for (int j = 0; j < m; ++j) {
        const std::size_t i = std::size_t(x + j);
        pnx[j] = finite_or_zero(r.n3 ? r.n3[3 * i] : r.nx[i]);
        pny[j] = finite_or_zero(r.n3 ? r.n3[3 * i + 1] : r.ny[i]);
        pnz[j] = finite_or_zero(r.n3 ? r.n3[3 * i + 2] : r.nz[i]);
    }
    std::copy_n(r.z + x, m, z);
    std::copy_n(r.fx + x, m, fx);
    std::copy_n(r.i0 + x, m, i0);
    std::copy_n(r.i1 + x, m, i1);
    UpsampleVector(r,
                   hn::Load(d, z),
                   hn::Load(d, pnx),
                   hn::Load(d, pny),
                   hn::Load(d, pnz),
                   GatherTaps(r, hn::Load(di, i0), hn::Load(di, i1)),
                   hn::Load(d, fx),
                   o0,
                   o1,
                   o2);
    hn::StoreInterleaved3(o0, o1, o2, d, o);
    for (int j = 0; j < m && r.albedo; ++j) {
        const std::size_t i = std::size_t(x + j);
        float k = r.intensity;
        if (r.material) {
            const float metal = r.material[i * std::size_t(r.mc) + 1];
            k *= std::isfinite(metal) ? 1.0f - std::clamp(metal, 0.0f, 1.0f) : 1.0f;
        }
        const float *a = r.albedo + i * std::size_t(r.na);
        for (int c = 0; c < 3; ++c) {
            float &v = o[3 * j + c];
            v = std::min(
                k * std::max(finite_or_zero(a[std::min(c, r.na - 1)]), 0.0f) * std::max(0.0f, v),
                std::numeric_limits<float>::max());
        }
    }
    std::copy_n(o, 3 * m, out + 3 * x);
}

int DenoiseRow(const SsgiDenoiseRow &r, int x_begin, int x_end)
{
    const D d;
    const int lanes = int(hn::Lanes(d));
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const std::size_t ow = std::size_t(r.ow);
    int x = x_begin;
    for (; x + lanes <= x_end; x += lanes) {
        const std::size_t c0 = std::size_t(r.y) * ow + std::size_t(x);
        const V z = hn::LoadU(d, r.z + c0);
        V nx, ny, nz;
        hn::LoadInterleaved3(d, r.n + 3 * c0, nx, ny, nz);
        const M n_zero = hn::And(hn::And(hn::Eq(nx, zero), hn::Eq(ny, zero)), hn::Eq(nz, zero));
        const V inv = hn::Div(one, hn::Mul(hn::Set(d, 0.1f), z));
        V s0 = zero, s1 = zero, s2 = zero, ws = zero;
        for (int j = std::max(0, r.y - 2); j <= std::min(r.oh - 1, r.y + 2); ++j) {
            for (int i = -2; i <= 2; ++i) {
                const std::size_t t = std::size_t(j) * ow + std::size_t(x + i);
                const V tz = hn::LoadU(d, r.z + t);
                V tx, ty, tz_n;
                hn::LoadInterleaved3(d, r.n + 3 * t, tx, ty, tz_n);
                // The depth tent: 1 - |dz| / (0.1 z), at least 0 (NaN: 0).
                const V tent = hn::Sub(one, hn::Mul(hn::Abs(hn::Sub(tz, z)), inv));
                const V tw = hn::IfThenElseZero(hn::Lt(zero, tent), tent);
                // max(0, a.b)^8, 1 where either normal is zero.
                const M t_zero =
                    hn::And(hn::And(hn::Eq(tx, zero), hn::Eq(ty, zero)), hn::Eq(tz_n, zero));
                const V dot = hn::Add(hn::Add(hn::Mul(nx, tx), hn::Mul(ny, ty)), hn::Mul(nz, tz_n));
                V nw = hn::IfThenElse(hn::Lt(zero, dot), dot, zero);
                nw = hn::Mul(nw, nw);
                nw = hn::Mul(nw, nw);
                nw = hn::Mul(nw, nw);
                nw = hn::IfThenElse(hn::Or(n_zero, t_zero), one, nw);
                const V wt = hn::Mul(tw, nw);
                V v0, v1, v2;
                hn::LoadInterleaved3(d, r.light + 3 * t, v0, v1, v2);
                s0 = hn::Add(s0, hn::Mul(wt, v0));
                s1 = hn::Add(s1, hn::Mul(wt, v1));
                s2 = hn::Add(s2, hn::Mul(wt, v2));
                ws = hn::Add(ws, wt);
            }
        }
        // No surface at the centre: kept.
        const M surface = hn::Gt(z, zero);
        V l0, l1, l2;
        hn::LoadInterleaved3(d, r.light + 3 * c0, l0, l1, l2);
        hn::StoreInterleaved3(hn::IfThenElse(surface, hn::Div(s0, ws), l0),
                              hn::IfThenElse(surface, hn::Div(s1, ws), l1),
                              hn::IfThenElse(surface, hn::Div(s2, ws), l2),
                              d,
                              r.out + 3 * std::size_t(x));
    }
    return x;
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(UpsampleRow);
HWY_EXPORT(DenoiseRow);

int ssgi_denoise_row(const SsgiDenoiseRow &r, int x_begin, int x_end)
{
    return HWY_DYNAMIC_DISPATCH(DenoiseRow)(r, x_begin, x_end);
}

void ssgi_upsample_row(const SsgiUpsampleRow &r, int w, float *out)
{
    HWY_DYNAMIC_DISPATCH(UpsampleRow)(r, w, out);
}

}  // namespace posthaste::shading
#endif
