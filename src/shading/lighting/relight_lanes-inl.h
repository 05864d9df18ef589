// The relight rows' lane vocabulary over Highway (relight_kernels.cpp only): loads of the
// G-buffer's interleaved channels, positions from depth, the toon-id set, the energy table's
// lookup. Each does prepare_pixel's or the EnergyTable's operations in their order (the rows
// promise the reference's bits). Like every Highway "-inl.h" it is compiled once per target
// (the toggle guard).

// clang-format off
#if defined(POSTHASTE_SHADING_RELIGHT_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef POSTHASTE_SHADING_RELIGHT_LANES_INL_H_
#undef POSTHASTE_SHADING_RELIGHT_LANES_INL_H_
#else
#define POSTHASTE_SHADING_RELIGHT_LANES_INL_H_
#endif
// clang-format on

#include <hwy/highway.h>

#include <cstdint>

#include "core/hwy_math-inl.h"
#include "shading/lighting/relight_pixel.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::relight::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using M = hn::Mask<D>;
constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// Channels 0..2 of pixels x .. x + n - 1 of row y, de-interleaved; missing lanes are 0.
HWY_INLINE void Load3(const Image &img, int x, int y, int n, V &a, V &b, V &c)
{
    const D d;
    const float *p = img.pixel(x, y);
    const int ch = img.channels();
    if (n == int(hn::Lanes(d)) && ch == 3) {
        simd::HWY_NAMESPACE::LoadXyz(d, p, a, b, c);
        return;
    }
    if (n == int(hn::Lanes(d)) && ch == 4) {
        V w;
        hn::LoadInterleaved4(d, p, a, b, c, w);
        return;
    }
    HWY_ALIGN float t[3][kMaxLanes] = {};
    for (int i = 0; i < n; ++i) {
        t[0][i] = p[i * ch];
        t[1][i] = p[i * ch + 1];
        t[2][i] = p[i * ch + 2];
    }
    a = hn::Load(d, t[0]);
    b = hn::Load(d, t[1]);
    c = hn::Load(d, t[2]);
}

/// Channel 0 of pixels x .. x + n - 1 of row y; missing lanes are 0.
HWY_INLINE V Load1(const Image &img, int x, int y, int n)
{
    const D d;
    if (n == int(hn::Lanes(d)) && img.channels() == 1) {
        return hn::LoadU(d, img.pixel(x, y));
    }
    HWY_ALIGN float t[kMaxLanes] = {};
    for (int i = 0; i < n; ++i) {
        t[i] = img.at(x + i, y, 0);
    }
    return hn::Load(d, t);
}

/// c * m for a camera point (qx, qy, z, 1) as glm's mat4 * vec4: (c0 qx + c1 qy) + (c2 z + c3).
HWY_INLINE V Transform(const glm::mat4 &c, int row, V qx, V qy, V z)
{
    const D d;
    const V a0 = hn::Add(hn::Mul(hn::Set(d, c[0][row]), qx), hn::Mul(hn::Set(d, c[1][row]), qy));
    const V a1 = hn::Add(hn::Mul(hn::Set(d, c[2][row]), z), hn::Set(d, c[3][row]));
    return hn::Add(a0, a1);
}

/// World positions from depth, as prepare_pixel: the 2x2 solve of the NDC equations for the
/// camera point (X, Y, z, 1), then camera to world. `ok` clears lanes with a depth that is not
/// finite (background) or a singular system.
HWY_INLINE void PositionFromDepth(const Inputs &sh, int x, int y, int n, V &px, V &py, V &pz, M &ok)
{
    const D d;
    const V z = Load1(*sh.depth, x, y, n);
    const V u =
        hn::Div(hn::Add(hn::Iota(d, float(x)), hn::Set(d, 0.5f)), hn::Set(d, float(sh.width)));
    const float v = (float(y) + 0.5f) / float(sh.height);
    const glm::mat4 &m = sh.cam_to_ndc;
    const auto s = [&](float f) { return hn::Set(d, f); };
    const V a00 = hn::Sub(s(m[0][0]), hn::Mul(u, s(m[0][3])));
    const V a01 = hn::Sub(s(m[1][0]), hn::Mul(u, s(m[1][3])));
    const V a10 = s(m[0][1] - v * m[0][3]), a11 = s(m[1][1] - v * m[1][3]);
    const V b0 = hn::Neg(
        hn::Sub(hn::Add(hn::Mul(hn::Sub(s(m[2][0]), hn::Mul(u, s(m[2][3]))), z), s(m[3][0])),
                hn::Mul(u, s(m[3][3]))));
    const V b1 =
        hn::Neg(hn::Sub(hn::Add(hn::Mul(s(m[2][1] - v * m[2][3]), z), s(m[3][1])), s(v * m[3][3])));
    const V det = hn::Sub(hn::Mul(a00, a11), hn::Mul(a01, a10));
    ok = hn::And(hn::IsFinite(z), hn::Ne(det, hn::Zero(d)));
    const V qx = hn::Div(hn::Sub(hn::Mul(b0, a11), hn::Mul(a01, b1)), det);
    const V qy = hn::Div(hn::Sub(hn::Mul(a00, b1), hn::Mul(a10, b0)), det);
    px = Transform(sh.c2w, 0, qx, qy, z);
    py = Transform(sh.c2w, 1, qx, qy, z);
    pz = Transform(sh.c2w, 2, qx, qy, z);
}

/// Lanes whose material id is a toon id, as prepare_pixel: ids in [0.5, 255.5) round to
/// 1..255 and index the 256-bit set `words` (Inputs::toon_words); the rest (and NaN) are not
/// toon.
HWY_INLINE M ToonMask(const Image &id, int x, int y, int n, const std::uint32_t *words)
{
    const D d;
    const DI di;
    const V m = Load1(id, x, y, n);
    const M in_range = hn::And(hn::Ge(m, hn::Set(d, 0.5f)), hn::Lt(m, hn::Set(d, 255.5f)));
    const VI k = hn::ConvertTo(di, hn::IfThenElseZero(in_range, hn::Add(m, hn::Set(d, 0.5f))));
    const VI wi = hn::ShiftRight<5>(k);
    const std::int32_t *table = reinterpret_cast<const std::int32_t *>(words);
#if HWY_TARGET == HWY_SCALAR || HWY_TARGET == HWY_EMU128 || HWY_TARGET == HWY_SSE4 || \
    HWY_TARGET == HWY_SSSE3
    // Fewer than 8 lanes: the set does not fit in a vector.
    const VI word = hn::GatherIndex(di, table, wi);
#else
    // The 8 words in one vector (Inputs::toon_words is zero-padded to 16), picked per lane in
    // registers.
    const VI word = hn::TableLookupLanes(hn::LoadU(di, table), hn::IndicesFromVec(di, wi));
#endif
    const VI bit = hn::And(hn::Shr(word, hn::And(k, hn::Set(di, 31))), hn::Set(di, 1));
    return hn::And(in_range, hn::RebindMask(d, hn::Eq(bit, hn::Set(di, 1))));
}

/// EnergyTable::lookup_e at mu = min(n.l, 1) for the lanes' roughness rows: `row0` = j0 kMu
/// and the weight tr are fixed per pixel. Lanes with n.l <= 0 (or NaN) read a clamped, valid
/// entry.
HWY_INLINE V EnergyE(const shading::EnergyTable &t, VI row0, V tr, V nl)
{
    constexpr int kMu = shading::EnergyTable::kMu;
    const D d;
    const DI di;
    const V mu = hn::Min(nl, hn::Set(d, 1.0f));
    // max(x, 0) gives 0 for a NaN x (the second operand on x86; the clamp in lookup_e).
    const V fm = hn::Min(
        hn::Max(hn::Sub(hn::Mul(mu, hn::Set(d, float(kMu))), hn::Set(d, 0.5f)), hn::Zero(d)),
        hn::Set(d, float(kMu - 1)));
    const VI i0 = hn::Min(hn::ConvertTo(di, fm), hn::Set(di, kMu - 2));
    const V tm = hn::Sub(fm, hn::ConvertTo(d, i0));
    const VI idx = hn::Add(row0, i0);
    const float *e = t.e.data();
    const V r00 = hn::GatherIndex(d, e, idx), r01 = hn::GatherIndex(d, e + 1, idx);
    const V r10 = hn::GatherIndex(d, e + kMu, idx), r11 = hn::GatherIndex(d, e + kMu + 1, idx);
    const V a = hn::Add(r00, hn::Mul(hn::Sub(r01, r00), tm));
    const V b = hn::Add(r10, hn::Mul(hn::Sub(r11, r10), tm));
    return hn::Add(a, hn::Mul(hn::Sub(b, a), tr));
}

}  // namespace posthaste::shading::relight::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // include guard
