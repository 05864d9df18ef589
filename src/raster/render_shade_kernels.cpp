// The rasterizer's vector beauty for a row of surface lanes (color_row.h), one source over
// Highway's lane types: the expressions of shading::evaluate (isotropic, height-correlated
// Smith, from brdf_lanes-inl.h, the relight kernel's too) and shading::add_sky_light.
// ColorRow::add_surface does everything per pixel that branches or looks up tables; this does the
// BRDF and the sky light.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "raster/render_shade_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "core/hwy_math-inl.h"
#include "shading/lighting/brdf_lanes-inl.h"
// clang-format on

#include "raster/color_row.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::raster::render_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using V = hn::Vec<D>;

using simd::HWY_NAMESPACE::ClampToRange;
using simd::HWY_NAMESPACE::Dot3Unfused;

using shading::HWY_NAMESPACE::FresnelSchlick;
using shading::HWY_NAMESPACE::GgxSmithDV;
using shading::HWY_NAMESPACE::SchlickWeight;
using shading::HWY_NAMESPACE::SinSquaredAcross;
using shading::HWY_NAMESPACE::SmithRoot;

void ShadeLanes(SurfaceLanes &s, int count, const KernelLight &kl)
{
    const D d;
    const int lanes = int(hn::Lanes(d));
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V lx = hn::Set(d, kl.l.x), ly = hn::Set(d, kl.l.y), lz = hn::Set(d, kl.l.z);
    const V inv_pi = hn::Set(d, 1.0f / shading::kPi);
    const V min_cos = hn::Set(d, shading::kMinCosine), f0d = hn::Set(d, 0.04f);
    const V scale = hn::Set(d, kl.scale);
    const V sun[3] = {hn::Set(d, kl.sun_rgb.x), hn::Set(d, kl.sun_rgb.y), hn::Set(d, kl.sun_rgb.z)};
    for (int i = 0; i < count; i += lanes) {
        const std::size_t k = std::size_t(i);
        const V nx = hn::LoadU(d, &s.nx[k]), ny = hn::LoadU(d, &s.ny[k]),
                nz = hn::LoadU(d, &s.nz[k]);
        const V vx = hn::LoadU(d, &s.vx[k]), vy = hn::LoadU(d, &s.vy[k]),
                vz = hn::LoadU(d, &s.vz[k]);
        const V rough = hn::LoadU(d, &s.rough[k]), metal = hn::LoadU(d, &s.metal[k]);
        const V vis = hn::LoadU(d, &s.vis[k]);
        const V alb[3] = {hn::LoadU(d, &s.ar[k]), hn::LoadU(d, &s.ag[k]), hn::LoadU(d, &s.ab[k])};

        const V nl = Dot3Unfused(nx, ny, nz, lx, ly, lz);
        const V nv_raw = Dot3Unfused(nx, ny, nz, vx, vy, vz);
        const V nv = hn::Max(nv_raw, min_cos);
        // The half vector; n where v = -l.
        V hx = hn::Add(vx, lx), hy = hn::Add(vy, ly), hz = hn::Add(vz, lz);
        const V hlen = hn::Sqrt(Dot3Unfused(hx, hy, hz, hx, hy, hz));
        const auto hok = hn::Gt(hlen, hn::Set(d, 1e-8f));
        // Times 1 / |v + l|, as evaluate() for the default masking term.
        const V inv_h = hn::Div(one, hlen);
        hx = hn::IfThenElse(hok, hn::Mul(hx, inv_h), nx);
        hy = hn::IfThenElse(hok, hn::Mul(hy, inv_h), ny);
        hz = hn::IfThenElse(hok, hn::Mul(hz, inv_h), nz);
        const V nh_raw = Dot3Unfused(nx, ny, nz, hx, hy, hz);
        const V nh = hn::Max(nh_raw, zero);
        const V vh = hn::Max(Dot3Unfused(vx, vy, vz, hx, hy, hz), zero);
        const V r = ClampToRange(rough, hn::Set(d, shading::kMinRoughness), one);
        const V alpha = hn::Mul(r, r);
        const V a2 = hn::Mul(alpha, alpha);
        // D (zero for n.h <= 0) times the correlated Smith V.
        const V nlc = hn::Max(nl, min_cos);
        const V one_a2 = hn::Sub(one, a2);
        const V dv = GgxSmithDV(nh,
                                SinSquaredAcross(nx, ny, nz, hx, hy, hz, nh_raw),
                                a2,
                                one_a2,
                                nv,
                                nlc,
                                SmithRoot(nv, a2, one_a2),
                                SmithRoot(nlc, a2, one_a2));
        // Schlick at v.h (direct) and at n.v (sky).
        const V mh5 = SchlickWeight(vh);
        const V mv5 = SchlickWeight(hn::Max(nv_raw, zero));
        const auto lit = hn::Gt(vis, zero);  // vis > 0 implies n.l > 0
        const V gloss = hn::Mul(hn::Sub(one, rough), hn::Sub(one, rough));
        const auto glossy = hn::Ge(gloss, hn::Set(d, 0.05f));
        const V one_metal = hn::Sub(one, metal);
        const V amb_in[3] = {
            hn::LoadU(d, &s.amb_r[k]), hn::LoadU(d, &s.amb_g[k]), hn::LoadU(d, &s.amb_b[k])};
        const V env_in[3] = {
            hn::LoadU(d, &s.env_r[k]), hn::LoadU(d, &s.env_g[k]), hn::LoadU(d, &s.env_b[k])};
        float *out[3] = {&s.out_r[k], &s.out_g[k], &s.out_b[k]};
        float *dif[3] = {&s.dif_r[k], &s.dif_g[k], &s.dif_b[k]};
        for (int c = 0; c < 3; ++c) {
            const V f0 = hn::Add(hn::Mul(f0d, one_metal), hn::Mul(alb[c], metal));
            const V diffuse = hn::Mul(alb[c], one_metal);
            const V f = FresnelSchlick(f0, mh5);
            const V direct = hn::Mul(hn::Add(hn::Mul(diffuse, inv_pi), hn::Mul(f, dv)), nl);
            const V sun_vis = hn::Mul(sun[c], vis);
            V col = hn::IfThenElseZero(lit, hn::Mul(direct, sun_vis));
            const V amb = hn::Mul(amb_in[c], scale);
            const V dif_amb = hn::Mul(diffuse, amb);
            col = hn::Add(col, dif_amb);
            const V dif_sun =
                hn::IfThenElseZero(lit, hn::Mul(hn::Mul(hn::Mul(diffuse, inv_pi), nl), sun_vis));
            hn::StoreU(hn::Add(dif_sun, dif_amb), d, dif[c]);
            const V env_mix = hn::Add(hn::Mul(amb, hn::Sub(one, gloss)),
                                      hn::Mul(hn::Mul(env_in[c], scale), gloss));
            const V env = hn::IfThenElse(glossy, env_mix, amb);
            const V fs = FresnelSchlick(f0, mv5);
            hn::StoreU(hn::Add(col, hn::Mul(fs, env)), d, out[c]);
        }
    }
}

}  // namespace posthaste::raster::render_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::raster::render_detail {

HWY_EXPORT(ShadeLanes);

void shade_lanes(SurfaceLanes &s, int count, const KernelLight &kl)
{
    HWY_DYNAMIC_DISPATCH(ShadeLanes)(s, count, kl);
}

}  // namespace posthaste::raster::render_detail
#endif
