// The sun's shadow for a row of surface lanes (color_row.h), one source over Highway's lane
// types. Compiled without FMA contraction (CMakeLists.txt), so the map coordinates round as in
// shadow_lookup (render_shadow.cpp): one ulp of a 2048-texel coordinate moves the PCF weights by
// ~1e-4, which would make the lanes disagree visibly with the per-pixel reference.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "raster/render_shadow_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "raster/color_row.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::raster::render_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void ShadowLanes(const ShadowMap &sm, SurfaceLanes &s, int count)
{
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const int lanes = int(hn::Lanes(d));
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V offset = hn::Set(d, 1.5f * sm.texel_m), bias = hn::Set(d, 0.5f * sm.texel_m);
    const V limit = hn::Set(d, float(sm.size)), minus_one = hn::Set(d, -1.0f);
    const auto size = hn::Set(di, sm.size);
    const glm::mat4 &r = sm.raster;
    for (int i = 0; i < count; i += lanes) {
        const V vis = hn::LoadU(d, &s.vis[std::size_t(i)]);
        const auto lit_mask = hn::Gt(vis, zero);
        if (hn::AllFalse(d, lit_mask)) {
            continue;
        }
        // The normal offset against acne, then the map's raster transform in mul()'s order.
        const V qx = hn::Add(hn::LoadU(d, &s.px[std::size_t(i)]),
                             hn::Mul(hn::LoadU(d, &s.nx[std::size_t(i)]), offset));
        const V qy = hn::Add(hn::LoadU(d, &s.py[std::size_t(i)]),
                             hn::Mul(hn::LoadU(d, &s.ny[std::size_t(i)]), offset));
        const V qz = hn::Add(hn::LoadU(d, &s.pz[std::size_t(i)]),
                             hn::Mul(hn::LoadU(d, &s.nz[std::size_t(i)]), offset));
        V h[3];
        for (int c = 0; c < 3; ++c) {
            h[c] =
                hn::Add(hn::Add(hn::Mul(hn::Set(d, r[0][c]), qx), hn::Mul(hn::Set(d, r[1][c]), qy)),
                        hn::Add(hn::Mul(hn::Set(d, r[2][c]), qz), hn::Set(d, r[3][c])));
        }
        const V x = hn::Sub(h[0], half), y = hn::Sub(h[1], half);
        const auto inside = hn::And(hn::And(hn::Gt(x, minus_one), hn::Gt(y, minus_one)),
                                    hn::And(hn::Lt(x, limit), hn::Lt(y, limit)));
        const auto use = hn::And(inside, lit_mask);
        if (hn::AllFalse(d, use)) {
            continue;  // outside the map: nothing there casts a shadow
        }
        const V fx0 = hn::Floor(x), fy0 = hn::Floor(y);
        const V fx = hn::Sub(x, fx0), fy = hn::Sub(y, fy0);
        // Out-of-map lanes are masked below; clamp first so the conversion stays in range.
        const auto x0 = hn::ConvertTo(di, hn::Min(hn::Max(fx0, hn::Set(d, -2.0f)), limit));
        const auto y0 = hn::ConvertTo(di, hn::Min(hn::Max(fy0, hn::Set(d, -2.0f)), limit));
        const V depth = hn::Add(h[2], bias);
        V lit[4];
        for (int k = 0; k < 4; ++k) {
            const auto xi = hn::Add(x0, hn::Set(di, k & 1));
            const auto yi = hn::Add(y0, hn::Set(di, k >> 1));
            const auto in_x = hn::AndNot(hn::Lt(xi, hn::Zero(di)), hn::Lt(xi, size));
            const auto in_y = hn::AndNot(hn::Lt(yi, hn::Zero(di)), hn::Lt(yi, size));
            const auto valid = hn::And(hn::RebindMask(d, hn::And(in_x, in_y)), use);
            // Lanes off the map read texel 0 and are masked out.
            const auto index =
                hn::IfThenElseZero(hn::RebindMask(di, valid), hn::Add(hn::Mul(yi, size), xi));
            const V key = hn::GatherIndex(d, sm.keys.data(), index);
            const auto shadowed = hn::And(valid, hn::Gt(key, depth));
            lit[k] = hn::IfThenZeroElse(shadowed, one);
        }
        const V one_fx = hn::Sub(one, fx), one_fy = hn::Sub(one, fy);
        const V pcf =
            hn::Add(hn::Mul(hn::Add(hn::Mul(lit[0], one_fx), hn::Mul(lit[1], fx)), one_fy),
                    hn::Mul(hn::Add(hn::Mul(lit[2], one_fx), hn::Mul(lit[3], fx)), fy));
        hn::StoreU(hn::IfThenElse(use, hn::Mul(vis, pcf), vis), d, &s.vis[std::size_t(i)]);
    }
}

}  // namespace posthaste::raster::render_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::raster::render_detail {

HWY_EXPORT(ShadowLanes);

void shadow_lanes(const ShadowMap &sm, SurfaceLanes &s, int count)
{
    HWY_DYNAMIC_DISPATCH(ShadowLanes)(sm, s, count);
}

}  // namespace posthaste::raster::render_detail
#endif
