// GTAO's depth-aware upsample of a row (gtao.h, gtao_upsample), one source over Highway's lane
// types: one output pixel a lane, its four reduced-resolution taps gathered. Compiled without
// FMA contraction (CMakeLists.txt), so every target gives the bits of the scalar loop it
// replaced (which had no FMA to use).

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/ao/gtao_upsample_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include <algorithm>
#include <limits>

#include "shading/ao/gtao_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;
constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// What the four taps of a pixel add up: the weighted AO and the weights, and the tap closest
/// in depth with its AO.
struct TapSums {
    V sum, wsum, best, nearest;
};

/// One tap (reduced row zr, ar at indices idx, bilinear weight bw): its weight (bilinear times
/// the depth tent; NaN, no surface, gives 0) added in, and the closest tap in depth kept for a
/// pixel that no tap's surface reaches.
HWY_INLINE void Tap(V bw,
                    const float *zr,
                    const float *ar,
                    hn::Vec<hn::RebindToSigned<D>> idx,
                    V z,
                    V inv_scale,
                    TapSums &s)
{
    const D d;
    const V lz = hn::GatherIndex(d, zr, idx), lv = hn::GatherIndex(d, ar, idx);
    const V dz = hn::Abs(hn::Sub(lz, z));
    const V t = hn::Sub(hn::Set(d, 1.0f), hn::Mul(dz, inv_scale));
    const V wt = hn::Mul(bw, hn::IfThenElseZero(hn::Lt(hn::Zero(d), t), t));
    s.sum = hn::Add(s.sum, hn::Mul(wt, lv));
    s.wsum = hn::Add(s.wsum, wt);
    const M closer = hn::Lt(dz, s.best);  // false for NaN
    s.best = hn::IfThenElse(closer, dz, s.best);
    s.nearest = hn::IfThenElse(closer, lv, s.nearest);
}

/// The upsampled AO of one vector of pixels.
HWY_INLINE V UpsampleVector(const GtaoUpsampleRow &r,
                            V z,
                            hn::Vec<hn::RebindToSigned<D>> l,
                            hn::Vec<hn::RebindToSigned<D>> rt,
                            V ax)
{
    const D d;
    const V one = hn::Set(d, 1.0f), fy = hn::Set(d, r.fy), one_fy = hn::Set(d, 1.0f - r.fy);
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    const V inv_scale = hn::Div(one, hn::Mul(hn::Set(d, 0.1f), z));
    const V one_ax = hn::Sub(one, ax);
    TapSums s{hn::Zero(d), hn::Zero(d), inf, one};
    Tap(hn::Mul(one_ax, one_fy), r.z0, r.a0, l, z, inv_scale, s);
    Tap(hn::Mul(ax, one_fy), r.z0, r.a0, rt, z, inv_scale, s);
    Tap(hn::Mul(one_ax, fy), r.z1, r.a1, l, z, inv_scale, s);
    Tap(hn::Mul(ax, fy), r.z1, r.a1, rt, z, inv_scale, s);
    const M surface = hn::And(hn::Gt(z, hn::Zero(d)), hn::Lt(z, inf));
    const V blended =
        hn::IfThenElse(hn::Gt(s.wsum, hn::Set(d, 1e-6f)), hn::Div(s.sum, s.wsum), s.nearest);
    return hn::IfThenElse(surface, blended, one);
}

void UpsampleRow(const GtaoUpsampleRow &r, int w, float *out)
{
    const D d;
    const hn::RebindToSigned<D> di;
    const int lanes = int(hn::Lanes(d));
    int x = 0;
    for (; x + lanes <= w; x += lanes) {
        const V o = UpsampleVector(r,
                                   hn::LoadU(d, r.z + x),
                                   hn::LoadU(di, r.i0 + x),
                                   hn::LoadU(di, r.i1 + x),
                                   hn::LoadU(d, r.fx + x));
        hn::StoreU(o, d, out + x);
    }
    if (x == w) {
        return;
    }
    // The row's last pixels through the same vector code on padded copies (tap 0, depth 0:
    // results not stored).
    const int m = w - x;
    HWY_ALIGN float z[kMaxLanes] = {}, fx[kMaxLanes] = {}, o[kMaxLanes];
    HWY_ALIGN std::int32_t i0[kMaxLanes] = {}, i1[kMaxLanes] = {};
    std::copy_n(r.z + x, m, z);
    std::copy_n(r.fx + x, m, fx);
    std::copy_n(r.i0 + x, m, i0);
    std::copy_n(r.i1 + x, m, i1);
    hn::Store(
        UpsampleVector(r, hn::Load(d, z), hn::Load(di, i0), hn::Load(di, i1), hn::Load(d, fx)),
        d,
        o);
    std::copy_n(o, m, out + x);
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(UpsampleRow);

void gtao_upsample_row(const GtaoUpsampleRow &r, int w, float *out)
{
    HWY_DYNAMIC_DISPATCH(UpsampleRow)(r, w, out);
}

}  // namespace posthaste::shading
#endif
