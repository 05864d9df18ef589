// The hatching kernel's lane vocabulary over Highway (hatch_kernels.cpp only): texel pair loads,
// the tone curve and TAM lookups, the edge and footprint tests on sample planes, and the
// triplanar ink. Like every Highway "-inl.h" it is compiled once per target (the toggle guard).
//
// No fused multiply-adds: hatch_kernels.cpp is compiled with -ffp-contract=off (CMakeLists.txt)
// and these functions use Mul then Add, so every target rounds the same way
// and a pixel's thresholds (edges, mip levels, tone segments) fall on the same side everywhere.

// clang-format off
#if defined(POSTHASTE_SHADING_HATCH_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef POSTHASTE_SHADING_HATCH_LANES_INL_H_
#undef POSTHASTE_SHADING_HATCH_LANES_INL_H_
#else
#define POSTHASTE_SHADING_HATCH_LANES_INL_H_
#endif
// clang-format on

#include <hwy/cache_control.h>
#include <hwy/contrib/math/math-inl.h>
#include <hwy/highway.h>

#include <cstdint>
#include <cstring>

#include "core/hwy_math-inl.h"
#include "shading/hatching/hatch_kernel.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::hatch_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using M = hn::Mask<D>;

constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

using simd::HWY_NAMESPACE::ClampToRange;
using simd::HWY_NAMESPACE::Dot3Unfused;
using simd::HWY_NAMESPACE::Finite;
using simd::HWY_NAMESPACE::LoadXyz;

/// Truncation to int32 of lanes in [0, 2^23) (NaN and larger lanes give some int32; callers clamp
/// or mask them): floor, then the bits of floor + 2^23, without ConvertTo's overflow fix-up.
HWY_INLINE VI TruncSmall(V v)
{
    const D d;
    const DI di;
    const V magic = hn::Set(d, 8388608.0f);
    return hn::Sub(hn::BitCast(di, hn::Add(hn::Floor(v), magic)), hn::BitCast(di, magic));
}

/// log2(x) for x > 0 within 0.005, continuous and increasing: the exponent plus a quadratic on
/// the mantissa (exact at powers of two). For mip levels, where a libm log2 was a hot spot.
HWY_INLINE V FastLog2(V x)
{
    const D d;
    const DI di;
    const VI bits = hn::BitCast(di, x);
    const V e = hn::ConvertTo(
        d, hn::Sub(hn::And(hn::ShiftRight<23>(bits), hn::Set(di, 0xff)), hn::Set(di, 127)));
    const V m =
        hn::BitCast(d, hn::Or(hn::And(bits, hn::Set(di, 0x007fffff)), hn::Set(di, 0x3f800000)));
    const V t = hn::Sub(m, hn::Set(d, 1.0f));
    return hn::Add(e, hn::Mul(t, hn::Sub(hn::Set(d, 1.3466f), hn::Mul(hn::Set(d, 0.3466f), t))));
}

/// The float pairs (base[i], base[i + 1]) of the lanes' float indices i: a gets the first, b the
/// second. Where the target gathers, as one 64-bit gather per half (the pairs are not 8-byte
/// aligned, hence byte offsets); elsewhere through a staging buffer.
HWY_INLINE void GatherPairs(const float *base, VI idx, V &a, V &b)
{
    const D d;
#if HWY_TARGET == HWY_AVX2
    // Eight 64-bit loads put together in registers: on the development machine (AMD EPYC) a
    // tenth faster than two 64-bit gathers here. Pairs 0, 1, 4, 5 go to g0 and 2, 3, 6, 7 to g1,
    // so that de-interleaving stays within 128-bit blocks.
    // The indices as unsigned (they are not negative): extracting one to a 32-bit register
    // then zero-extends it for free, where a signed one took a sign extension per pair.
    const hn::RebindToUnsigned<D> du;
    HWY_ALIGN std::uint32_t i[8];
    hn::Store(hn::BitCast(du, idx), du, i);
    const hn::Full64<float> d2;
    const hn::Full128<float> d4;
    auto two = [&](int l0, int l1) {
        return hn::Combine(d4, hn::LoadU(d2, base + i[l1]), hn::LoadU(d2, base + i[l0]));
    };
    const V g0 = hn::Combine(d, two(4, 5), two(0, 1));  // a0 b0 a1 b1 | a4 b4 a5 b5
    const V g1 = hn::Combine(d, two(6, 7), two(2, 3));  // a2 b2 a3 b3 | a6 b6 a7 b7
    const V t0 = hn::InterleaveLower(d, g0, g1), t1 = hn::InterleaveUpper(d, g0, g1);
    a = hn::InterleaveLower(d, t0, t1);
    b = hn::InterleaveUpper(d, t0, t1);
#elif HWY_ARCH_X86 && HWY_TARGET <= HWY_AVX3
    const hn::Repartition<double, D> dd;
    const hn::RebindToSigned<decltype(dd)> dd64;
    const hn::Half<DI> dh;
    const auto lo = hn::ShiftLeft<2>(hn::PromoteTo(dd64, hn::LowerHalf(dh, idx)));
    const auto hi = hn::ShiftLeft<2>(hn::PromoteTo(dd64, hn::UpperHalf(dh, idx)));
    const double *base64 = reinterpret_cast<const double *>(base);
    const V g0 = hn::BitCast(d, hn::GatherOffset(dd, base64, lo));
    const V g1 = hn::BitCast(d, hn::GatherOffset(dd, base64, hi));
    a = hn::ConcatEven(d, g1, g0);
    b = hn::ConcatOdd(d, g1, g0);
#else
    const DI di;
    HWY_ALIGN std::int32_t i[kMaxLanes];
    HWY_ALIGN float pairs[2 * kMaxLanes];
    hn::Store(idx, di, i);
    for (std::size_t l = 0; l < hn::Lanes(d); ++l) {
        std::memcpy(pairs + 2 * l, base + i[l], 2 * sizeof(float));
    }
    hn::LoadInterleaved2(d, pairs, a, b);
#endif
}

/// The lanes' r, g, b, a stored as interleaved RGBA pixels at p. On AVX2, where p is 16-byte
/// aligned, with non-temporal 16-byte stores (the hand-written kernel before this one did the
/// same): the output is written once and not read here, so its lines need not be read into the
/// cache first; the caller ends the tile with hwy::FlushStream(). The same values either way.
HWY_INLINE void StoreRgba(V r, V g, V b, V a, float *p)
{
    const D d;
#if HWY_TARGET == HWY_AVX2
    if ((reinterpret_cast<std::uintptr_t>(p) & 15) == 0) {
        const hn::Repartition<double, D> dd;
        const hn::Full128<float> d4;
        // Within each 128-bit block: t0 = r g r g of pixels 0, 1 (4, 5 in the upper block) ...
        const auto t0 = hn::BitCast(dd, hn::InterleaveLower(d, r, g));
        const auto t1 = hn::BitCast(dd, hn::InterleaveLower(d, b, a));
        const auto t2 = hn::BitCast(dd, hn::InterleaveUpper(d, r, g));
        const auto t3 = hn::BitCast(dd, hn::InterleaveUpper(d, b, a));
        // ... then q[j] = pixel j in the lower block and pixel j + 4 in the upper.
        const V q[4] = {hn::BitCast(d, hn::InterleaveLower(dd, t0, t1)),
                        hn::BitCast(d, hn::InterleaveUpper(dd, t0, t1)),
                        hn::BitCast(d, hn::InterleaveLower(dd, t2, t3)),
                        hn::BitCast(d, hn::InterleaveUpper(dd, t2, t3))};
        for (int j = 0; j < 4; ++j) {
            hn::Stream(hn::LowerHalf(d4, q[j]), d4, p + 4 * j);
            hn::Stream(hn::UpperHalf(d4, q[j]), d4, p + 16 + 4 * j);
        }
        return;
    }
#endif
    hn::StoreInterleaved4(r, g, b, a, d, p);
}

/// ToneCurve::operator() on the lanes (NaN reads as 1, paper).
HWY_INLINE V ToneCurveV(const float *table, V linear)
{
    const D d;
    const DI di;
    const M nan = hn::IsNaN(linear);
    const V one = hn::Set(d, 1.0f);
    const V q = hn::Mul(hn::Sqrt(ClampToRange(linear, hn::Zero(d), one)),
                        hn::Set(d, float(ToneCurve::kSegments)));
    const VI i = hn::Min(TruncSmall(q), hn::Set(di, ToneCurve::kSegments - 1));
    const V f = hn::Sub(q, hn::ConvertTo(d, i));
    V t0, t1;
    GatherPairs(table, hn::IfThenZeroElse(hn::RebindMask(di, nan), i), t0, t1);
    return hn::IfThenElse(nan, one, hn::Add(t0, hn::Mul(f, hn::Sub(t1, t0))));
}

/// Ramp entries k and k + 1 of texel row + col of the packed texels, blended by f.
HWY_INLINE V TexelV(const float *packed, VI row, VI col, VI k, V f)
{
    static_assert(Tam::kPacked == 8, "the shift below multiplies by kPacked");
    V a, b;
    GatherPairs(packed, hn::Add(hn::ShiftLeft<3>(hn::Add(row, col)), k), a, b);
    return hn::Add(a, hn::Mul(f, hn::Sub(b, a)));
}

/// Tam::ramp_level on the lanes: per-lane level, ramp entry k and blend f, texel coordinates in
/// 16.16 fixed point at the finest level (fu, fv).
HWY_INLINE V RampLevelV(const float *packed, int size, VI level, VI k, V f, VI fu, VI fv)
{
    const D d;
    const DI di;
    const hn::RebindToUnsigned<D> du;
    const VI one = hn::Set(di, 1);
    const VI s = hn::Set(di, size) >> level;
    const VI mask = hn::Sub(s, one);
    const VI half = hn::Set(di, 32768), frac = hn::Set(di, 0xffff);
    const VI x = hn::Sub(fu >> level, half), y = hn::Sub(fv >> level, half);
    const VI x0 = hn::And(hn::ShiftRight<16>(x), mask), y0 = hn::And(hn::ShiftRight<16>(y), mask);
    const V inv = hn::Set(d, 1.0f / 65536.0f);
    const V fx = hn::Mul(hn::ConvertTo(d, hn::And(x, frac)), inv);
    const V fy = hn::Mul(hn::ConvertTo(d, hn::And(y, frac)), inv);
    const VI x1 = hn::And(hn::Add(x0, one), mask), y1 = hn::And(hn::Add(y0, one), mask);
    // First texel of the level: the sum of (size >> j)^2 for j < level = 4 (size^2 - s^2) / 3,
    // divided exactly by multiplying with the inverse of 3 modulo 2^32 (unsigned: it wraps).
    const auto su = hn::BitCast(du, s);
    const auto base4 = hn::ShiftLeft<2>(
        hn::Sub(hn::Set(du, std::uint32_t(size) * std::uint32_t(size)), hn::Mul(su, su)));
    const VI base = hn::BitCast(di, hn::Mul(base4, hn::Set(du, 0xaaaaaaabu)));
    const VI row0 = hn::Add(base, hn::Mul(y0, s)), row1 = hn::Add(base, hn::Mul(y1, s));
    const V t00 = TexelV(packed, row0, x0, k, f), t10 = TexelV(packed, row0, x1, k, f);
    const V t01 = TexelV(packed, row1, x0, k, f), t11 = TexelV(packed, row1, x1, k, f);
    const V a = hn::Add(t00, hn::Mul(fx, hn::Sub(t10, t00)));
    const V c = hn::Add(t01, hn::Mul(fx, hn::Sub(t11, t01)));
    return hn::Add(a, hn::Mul(fy, hn::Sub(c, a)));
}

/// Tam::ramp on the lanes; lanes outside `live` (or with darkness <= 0) give 0.
HWY_INLINE V RampV(const Tam &tam, M live, V darkness, V u, V v, V lod)
{
    const D d;
    const DI di;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const M active = hn::And(live, hn::Gt(darkness, zero));
    if (hn::AllFalse(d, active)) {
        return zero;
    }
    const V sv = hn::Mul(hn::Min(darkness, one), hn::Set(d, float(kTamTones)));
    // Max with 0: inactive lanes (darkness <= 0 or NaN) must still address valid texels.
    const VI k = hn::Max(hn::Min(TruncSmall(sv), hn::Set(di, kTamTones - 1)), hn::Zero(di));
    const V f = hn::Sub(sv, hn::ConvertTo(d, k));
    // ramp_at: a NaN lod reads the coarsest level.
    const V top = hn::Set(d, float(tam.levels() - 1));
    const V l = hn::IfThenElse(hn::IsNaN(lod), top, ClampToRange(lod, zero, top));
    const VI l0 = TruncSmall(l);
    const V fl = hn::Sub(l, hn::ConvertTo(d, l0));
    u = hn::Sub(u, hn::Floor(u));
    v = hn::Sub(v, hn::Floor(v));
    const V fixed = hn::Set(d, float(tam.size()) * 65536.0f);
    const VI fu = hn::ConvertTo(di, hn::Mul(u, fixed)), fv = hn::ConvertTo(di, hn::Mul(v, fixed));
    const V b = ClampToRange(hn::Sub(hn::Mul(hn::Set(d, 2.0f), fl), hn::Set(d, 0.5f)), zero, one);
    const M only0 = hn::Le(b, zero), only1 = hn::Ge(b, one);
    V c0 = zero, c1 = zero;
    if (!hn::AllFalse(d, hn::AndNot(only1, active))) {
        c0 = RampLevelV(tam.packed(), tam.size(), l0, k, f, fu, fv);
    }
    if (!hn::AllFalse(d, hn::AndNot(only0, active))) {
        const VI l1 = hn::Min(hn::Add(l0, hn::Set(di, 1)), hn::Set(di, tam.levels() - 1));
        c1 = RampLevelV(tam.packed(), tam.size(), l1, k, f, fu, fv);
    }
    const V r = hn::IfThenElse(
        only0, c0, hn::IfThenElse(only1, c1, hn::Add(c0, hn::Mul(b, hn::Sub(c1, c0)))));
    return hn::IfThenElseZero(active, r);
}

/// Tile-local planes of the kernel, in one buffer: samples over the tile plus the outline reach
/// plus one pixel, with coordinates clamped to the image (at the border a pixel stands in for
/// its missing neighbour), and edge flags. Flags are stored as all-ones or zero bits.
enum Plane { kZ, kPx, kPy, kPz, kNx, kNy, kNz, kHit, kNrm, kEdge, kPlaneCount };

/// A pixel's samples on the lanes: depth, world position and unit normal (0 where unusable),
/// hit (finite positive depth and finite position) and nrm (hit with a usable normal).
struct SampleV {
    V z, px, py, pz, nx, ny, nz;
    M hit, nrm;
};

HWY_INLINE SampleV LoadSample(const float *buf, std::size_t plane, std::size_t i)
{
    const D d;
    const float *p = buf + i;
    return {hn::LoadU(d, p + kZ * plane),
            hn::LoadU(d, p + kPx * plane),
            hn::LoadU(d, p + kPy * plane),
            hn::LoadU(d, p + kPz * plane),
            hn::LoadU(d, p + kNx * plane),
            hn::LoadU(d, p + kNy * plane),
            hn::LoadU(d, p + kNz * plane),
            hn::MaskFromVec(hn::LoadU(d, p + kHit * plane)),
            hn::MaskFromVec(hn::LoadU(d, p + kNrm * plane))};
}

/// Whether pixel c carries an outline against neighbour q (one side only, so lines stay thin),
/// without the c.hit test (the caller masks by it): a silhouette against the sky, the nearer
/// side of a depth gap (along c's normal where it has one), or a crease towards q_after
/// neighbours.
HWY_INLINE M IsEdgeV(const SampleV &c, const SampleV &q, bool q_after, V dt_z, V cos_thr)
{
    const V dn = Dot3Unfused(
        c.nx, c.ny, c.nz, hn::Sub(q.px, c.px), hn::Sub(q.py, c.py), hn::Sub(q.pz, c.pz));
    const V gap = hn::IfThenElse(c.nrm, hn::Abs(dn), hn::Abs(hn::Sub(q.z, c.z)));
    const M far = hn::Gt(gap, dt_z);
    const M nearer = hn::Le(c.z, q.z);
    M crease = hn::FirstN(D(), 0);
    if (q_after) {
        const V cn = Dot3Unfused(c.nx, c.ny, c.nz, q.nx, q.ny, q.nz);
        crease = hn::And(hn::And(c.nrm, q.nrm), hn::Lt(cn, cos_thr));
    }
    const M gap_or_crease = hn::Or(hn::And(far, nearer), hn::AndNot(far, crease));
    return hn::Or(hn::AndNot(q.hit, c.hit), hn::And(q.hit, gap_or_crease));
}

/// World-space step to a neighbour usable for footprints (on the same smooth surface); at image
/// borders the pixel stands in for q and gives a zero step, which does not count.
HWY_INLINE M NeighbourStepV(const SampleV &c, const SampleV &q, V &sx, V &sy, V &sz)
{
    const D d;
    const V cn = Dot3Unfused(c.nx, c.ny, c.nz, q.nx, q.ny, q.nz);
    const M ok = hn::AndNot(hn::Lt(cn, hn::Set(d, 0.7f)), hn::And(q.hit, q.nrm));
    sx = hn::Sub(q.px, c.px);
    sy = hn::Sub(q.py, c.py);
    sz = hn::Sub(q.pz, c.pz);
    return hn::And(ok, hn::Gt(Dot3Unfused(sx, sy, sz, sx, sy, sz), hn::Zero(d)));
}

/// The smaller of the forward (a) and backward (b) steps that are usable.
HWY_INLINE M PickStepV(const SampleV &c, const SampleV &a, const SampleV &b, V &x, V &y, V &z)
{
    V ax, ay, az, bx, by, bz;
    const M ha = NeighbourStepV(c, a, ax, ay, az), hb = NeighbourStepV(c, b, bx, by, bz);
    const V la = Dot3Unfused(ax, ay, az, ax, ay, az), lb = Dot3Unfused(bx, by, bz, bx, by, bz);
    const M take_a = hn::And(ha, hn::Or(hn::Not(hb), hn::Le(la, lb)));
    x = hn::IfThenElse(take_a, ax, bx);
    y = hn::IfThenElse(take_a, ay, by);
    z = hn::IfThenElse(take_a, az, bz);
    return hn::Or(ha, hb);
}

/// Mip level from the world steps to the x and y neighbours projected on a plane (u, v
/// components): 0.5 log2(max |step|^2) + log2(texels per metre).
HWY_INLINE V PlaneLod(const KernelCtx &k, V ux, V vx, V uy, V vy)
{
    const D d;
    const V len2 = hn::Max(hn::Add(hn::Mul(uy, uy), hn::Mul(vy, vy)),
                           hn::Add(hn::Mul(ux, ux), hn::Mul(vx, vx)));
    return hn::Add(hn::Mul(hn::Set(d, 0.5f), FastLog2(hn::Max(hn::Set(d, 1e-30f), len2))),
                   hn::Set(d, k.lod_offset));
}

/// Three lanes vectors (x, y, z).
struct V3 {
    V v[3];
};

/// Three planar lookups blended by max(|n_i| - 0.2, 0)^sharpness (normalised); lanes without a
/// usable normal (`flat`) take the flat tone, sky lanes 0. The weights' power is Highway's
/// exp(y log x) (a few ulp).
HWY_INLINE V TriplanarInk(const KernelCtx &k,
                          const SampleV &c,
                          M flat,
                          M footprint,
                          V darkness,
                          const V3 &an,
                          const V3 &dpx,
                          const V3 &dpy)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    V w[3];
    for (int a = 0; a < 3; ++a) {
        const V x = hn::Max(hn::Sub(an.v[a], hn::Set(d, 0.2f)), zero);
        const M pos = hn::Gt(x, zero);
        // The power takes x > 0 only; pow(0, sharpness) comes from std::pow once.
        const V power = hn::Exp(
            d, hn::Mul(hn::Set(d, k.triplanar_sharpness), hn::Log(d, hn::IfThenElse(pos, x, one))));
        w[a] = hn::IfThenElse(pos, power, hn::Set(d, k.zero_pow));
    }
    const V sum = hn::Add(hn::Add(w[0], w[1]), w[2]);
    const M surface = hn::AndNot(flat, c.hit);
    const V p[3] = {c.px, c.py, c.pz};
    static constexpr int kU[3] = {2, 0, 0}, kV[3] = {1, 2, 1};
    V ink = zero;
    for (int a = 0; a < 3; ++a) {
        const V wa = hn::Div(w[a], sum);
        const int iu = kU[a], iv = kV[a];
        const V lod = hn::IfThenElse(footprint,
                                     PlaneLod(k, dpx.v[iu], dpx.v[iv], dpy.v[iu], dpy.v[iv]),
                                     hn::Set(d, k.flat_lod));
        const M live = hn::And(surface, hn::Gt(wa, zero));
        const V r = RampV(*k.tam,
                          live,
                          darkness,
                          hn::Mul(p[iu], hn::Set(d, k.inv_scale)),
                          hn::Mul(p[iv], hn::Set(d, k.inv_scale)),
                          lod);
        ink = hn::Add(ink, hn::IfThenElseZero(live, hn::Mul(wa, r)));
    }
    const V flat_ink = RampV(*k.tam, flat, darkness, zero, zero, hn::Set(d, k.flat_lod));
    return hn::IfThenElseZero(c.hit, hn::IfThenElse(flat, flat_ink, ink));
}

}  // namespace posthaste::shading::hatch_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // include guard
