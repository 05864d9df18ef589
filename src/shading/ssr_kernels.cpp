// The screen-space reflection march's depth tests over Highway (see ssr_kernels.h; the method
// and the scalar march it follows in ssr.cpp). Compiled without FP contraction (CMakeLists.txt):
// every step is rounded as the scalar march rounds it.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/ssr_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "shading/ssr_kernels.h"

#include <cstddef>
#include <limits>

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// The grid cell index of coordinates (x, y) in pixels: ssr.cpp's clamp_index in each axis
/// (clamped in float, then truncated).
template <class D, class V = hn::Vec<D>>
HWY_INLINE hn::Vec<hn::RebindToSigned<D>> CellIndex(D d, const SsrDepthGrid &g, V x, V y)
{
    const hn::RebindToSigned<D> di;
    const V zero = hn::Zero(d);
    const V inv_stride = hn::Set(d, g.inv_stride);
    const auto cx = hn::ConvertTo(
        di, hn::Min(hn::Max(hn::Mul(x, inv_stride), zero), hn::Set(d, float(g.w - 1))));
    const auto cy = hn::ConvertTo(
        di, hn::Min(hn::Max(hn::Mul(y, inv_stride), zero), hn::Set(d, float(g.h - 1))));
    return hn::Add(hn::Mul(cy, hn::Set(di, g.w)), cx);
}

void MarchSteps(const SsrDepthGrid &g, const SsrSegment &s, float *t_out, float *crossed_out)
{
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const V steps = hn::Set(d, float(s.steps));
    const V jitter = hn::Set(d, s.jitter);
    const V t_start = hn::Set(d, s.t_start);
    const V span = hn::Set(d, s.t_end - s.t_start);
    const V ax = hn::Set(d, s.ax), ay = hn::Set(d, s.ay), az = hn::Set(d, s.a_inv_z);
    const V dx = hn::Set(d, s.bx - s.ax), dy = hn::Set(d, s.by - s.ay),
            dz = hn::Set(d, s.b_inv_z - s.a_inv_z);
    const V one = hn::Set(d, 1.0f);
    const V thickness = hn::Set(d, g.thickness);
    // t of step i, as the scalar march computes it (its running max with the previous t changes
    // nothing: the formula rises with i).
    const auto t_of = [&](V i) {
        const V sv = hn::Div(hn::Add(i, jitter), steps);
        return hn::Add(t_start, hn::Mul(hn::Mul(sv, sv), span));
    };
    const std::size_t n = hn::Lanes(d);
    for (int i0 = 0; i0 < s.steps; i0 += int(n)) {
        const V i = hn::Iota(d, float(i0));
        const V t = t_of(i);
        // The previous sample: the origin (t 0) before the first step.
        const V t_prev = hn::IfThenZeroElse(hn::Eq(i, hn::Zero(d)), t_of(hn::Sub(i, one)));
        const V qx = hn::Add(ax, hn::Mul(dx, t));
        const V qy = hn::Add(ay, hn::Mul(dy, t));
        const V qz = hn::Add(az, hn::Mul(dz, t));
        const V prev_z = hn::Add(az, hn::Mul(dz, t_prev));
        const V scene = hn::GatherIndex(d, g.inv_depth, CellIndex(d, g, qx, qy));
        const auto behind = hn::Le(qz, scene);
        const V nearest = hn::Min(hn::Div(one, prev_z), hn::Div(one, qz));
        const auto overlaps = hn::Le(nearest, hn::Add(hn::Div(one, scene), thickness));
        hn::StoreU(t, d, t_out + i0);
        hn::StoreU(hn::IfThenElseZero(hn::And(behind, overlaps), one), d, crossed_out + i0);
    }
    (void)di;
}

void WeightRow(const SsrWeightRow &r, float *wr, float *wg, float *wb)
{
    const hn::ScalableTag<float> d;
    using V = hn::Vec<decltype(d)>;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V width = hn::Set(d, float(r.width)), v = hn::Set(d, r.v);
    // The row's part of depth_ray(u, v): origin + u du + v dv, rounded as glm rounds it.
    const V ox = hn::Set(d, r.origin[0]), oy = hn::Set(d, r.origin[1]),
            oz = hn::Set(d, r.origin[2]);
    const V dux = hn::Set(d, r.du[0]), duy = hn::Set(d, r.du[1]), duz = hn::Set(d, r.du[2]);
    const V vdx = hn::Mul(v, hn::Set(d, r.dv[0])), vdy = hn::Mul(v, hn::Set(d, r.dv[1])),
            vdz = hn::Mul(v, hn::Set(d, r.dv[2]));
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    const V max_roughness = hn::Set(d, r.max_roughness);
    const V f0_dielectric = hn::Set(d, 0.04f);
    const auto dot = [](V ax, V ay, V az, V bx, V by, V bz) {
        return hn::Add(hn::Add(hn::Mul(ax, bx), hn::Mul(ay, by)), hn::Mul(az, bz));
    };
    const std::size_t lanes = hn::Lanes(d);
    for (int x = 0; x < r.n; x += int(lanes)) {
        const V z = hn::LoadU(d, r.z + x);
        const V rough = hn::LoadU(d, r.roughness + x);
        V nx = hn::LoadU(d, r.nx + x), ny = hn::LoadU(d, r.ny + x), nz = hn::LoadU(d, r.nz + x);
        const V nlen = hn::Sqrt(dot(nx, ny, nz, nx, ny, nz));
        const V gloss = hn::Mul(hn::Sub(one, rough), hn::Sub(one, rough));
        const auto glossy =
            hn::And(hn::And(hn::Gt(z, zero), hn::Lt(z, inf)),
                    hn::And(hn::And(hn::Le(rough, max_roughness), hn::Gt(nlen, zero)),
                            hn::Ge(gloss, hn::Set(d, 0.05f))));
        if (hn::AllFalse(d, glossy)) {
            hn::StoreU(zero, d, wr + x);
            hn::StoreU(zero, d, wg + x);
            hn::StoreU(zero, d, wb + x);
            continue;
        }
        nx = hn::Div(nx, nlen);
        ny = hn::Div(ny, nlen);
        nz = hn::Div(nz, nlen);
        // The view direction: -normalize(depth_ray(u, v)), normalize as v * (1 / sqrt(v.v)).
        const V u = hn::Div(hn::Add(hn::Iota(d, float(x)), half), width);
        const V rx = hn::Add(hn::Add(ox, hn::Mul(u, dux)), vdx);
        const V ry = hn::Add(hn::Add(oy, hn::Mul(u, duy)), vdy);
        const V rz = hn::Add(hn::Add(oz, hn::Mul(u, duz)), vdz);
        const V inv_len = hn::Div(one, hn::Sqrt(dot(rx, ry, rz, rx, ry, rz)));
        const V vx = hn::Neg(hn::Mul(rx, inv_len)), vy = hn::Neg(hn::Mul(ry, inv_len)),
                vz = hn::Neg(hn::Mul(rz, inv_len));
        // The side the camera sees.
        const auto back = hn::Lt(dot(nx, ny, nz, vx, vy, vz), zero);
        nx = hn::IfThenElse(back, hn::Neg(nx), nx);
        ny = hn::IfThenElse(back, hn::Neg(ny), ny);
        nz = hn::IfThenElse(back, hn::Neg(nz), nz);
        const V nv = hn::Max(dot(nx, ny, nz, vx, vy, vz), zero);
        const V m = hn::Sub(one, hn::Min(hn::Max(nv, zero), one));
        const V m2 = hn::Mul(m, m);
        const V m5 = hn::Mul(hn::Mul(m2, m2), m);
        // F0 = mix(0.04, albedo, metallic) = 0.04 (1 - metallic) + albedo metallic.
        const V metal = hn::LoadU(d, r.metallic + x);
        const V base = hn::Mul(f0_dielectric, hn::Sub(one, metal));
        const auto weight = [&](const float *albedo) {
            const V f0 = hn::Add(base, hn::Mul(hn::LoadU(d, albedo + x), metal));
            const V f = hn::Add(f0, hn::Mul(hn::Sub(one, f0), m5));
            return hn::IfThenElseZero(glossy, hn::Mul(f, gloss));
        };
        hn::StoreU(weight(r.ar), d, wr + x);
        hn::StoreU(weight(r.ag), d, wg + x);
        hn::StoreU(weight(r.ab), d, wb + x);
    }
}

void ResolveRow(const SsrResolveRow &r, float *dr, float *dg, float *db, float *apply)
{
    const hn::ScalableTag<float> d;
    using V = hn::Vec<decltype(d)>;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V radius = hn::Set(d, float(r.radius)), depth_tolerance = hn::Set(d, 0.05f),
            min_cos = hn::Set(d, 0.9f), intensity = hn::Set(d, r.intensity);
    // The window's cells relative to the pixel's own: stride k - (x mod stride) in
    // [-radius, radius].
    const int k0 = -(r.radius / r.stride), k1 = (r.stride - 1 + r.radius) / r.stride;
    const std::size_t lanes = hn::Lanes(d);
    const std::size_t pitch = std::size_t(r.pitch);
    for (int x = 0; x < r.n; x += int(lanes)) {
        const V wr = hn::LoadU(d, r.wr + x), wg = hn::LoadU(d, r.wg + x),
                wb = hn::LoadU(d, r.wb + x);
        const auto weighted = hn::Or(hn::Or(hn::Ne(wr, zero), hn::Ne(wg, zero)), hn::Ne(wb, zero));
        if (hn::AllFalse(d, weighted)) {
            hn::StoreU(zero, d, apply + x);
            continue;
        }
        const V xf = hn::Iota(d, float(x));
        const V z = hn::LoadU(d, r.z + x);
        const V nx = hn::LoadU(d, r.nx + x), ny = hn::LoadU(d, r.ny + x),
                nz = hn::LoadU(d, r.nz + x);
        const V near_depth = hn::Mul(depth_tolerance, z);
        V sr = zero, sg = zero, sb = zero, count = zero;
        for (int row = 0; row < r.row_count; ++row) {
            const float *c = r.rows[row];
            for (int k = k0; k <= k1; ++k) {
                const std::ptrdiff_t e = std::ptrdiff_t(x) + std::ptrdiff_t(r.stride) * k;
                const V cz = hn::LoadU(d, c + e);
                const V cx = hn::LoadU(d, r.cell_x + e);
                const V dot = hn::Add(hn::Add(hn::Mul(hn::LoadU(d, c + pitch + e), nx),
                                              hn::Mul(hn::LoadU(d, c + 2 * pitch + e), ny)),
                                      hn::Mul(hn::LoadU(d, c + 3 * pitch + e), nz));
                const auto take = hn::And(hn::And(hn::Le(hn::Abs(hn::Sub(cx, xf)), radius),
                                                  hn::Le(hn::Abs(hn::Sub(cz, z)), near_depth)),
                                          hn::Not(hn::Lt(dot, min_cos)));
                sr = hn::IfThenElse(take, hn::Add(sr, hn::LoadU(d, c + 4 * pitch + e)), sr);
                sg = hn::IfThenElse(take, hn::Add(sg, hn::LoadU(d, c + 5 * pitch + e)), sg);
                sb = hn::IfThenElse(take, hn::Add(sb, hn::LoadU(d, c + 6 * pitch + e)), sb);
                count = hn::IfThenElse(take, hn::Add(count, one), count);
            }
        }
        const auto ok = hn::And(weighted, hn::Ne(count, zero));
        // weight * (sum / count) * intensity, rounded as the scalar resolve rounds it.
        hn::StoreU(hn::Mul(hn::Mul(wr, hn::Div(sr, count)), intensity), d, dr + x);
        hn::StoreU(hn::Mul(hn::Mul(wg, hn::Div(sg, count)), intensity), d, dg + x);
        hn::StoreU(hn::Mul(hn::Mul(wb, hn::Div(sb, count)), intensity), d, db + x);
        hn::StoreU(hn::IfThenElseZero(ok, one), d, apply + x);
    }
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(MarchSteps);
HWY_EXPORT(WeightRow);
HWY_EXPORT(ResolveRow);

void ssr_resolve_row(const SsrResolveRow &r, float *dr, float *dg, float *db, float *apply)
{
    HWY_DYNAMIC_DISPATCH(ResolveRow)(r, dr, dg, db, apply);
}

void ssr_weight_row(const SsrWeightRow &r, float *wr, float *wg, float *wb)
{
    HWY_DYNAMIC_DISPATCH(WeightRow)(r, wr, wg, wb);
}

void ssr_march_steps(const SsrDepthGrid &g, const SsrSegment &s, float *t, float *crossed)
{
    HWY_DYNAMIC_DISPATCH(MarchSteps)(g, s, t, crossed);
}

}  // namespace posthaste::shading
#endif
