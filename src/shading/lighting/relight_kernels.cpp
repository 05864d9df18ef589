// The relight method's rows (relight.h), one source over Highway's lane types: one pixel a lane,
// whole rows (shade_rows_vector). Every operation is the reference's (relight.cpp's
// prepare_pixel and light_sum_scalar, lighting.cpp's direct_response, brdf.cpp's evaluate and
// multiscatter) in the same order, with exact division and square root, and the file is compiled
// without FMA contraction (CMakeLists.txt): each lane gives the reference's bits, on every target
// (tests/unit/relight_simd_test.cpp compares them value for value). The BRDF terms are those of
// brdf_lanes-inl.h, which the rasterizer's beauty lanes call too. What the lanes do not cover
// (quantised toon highlights) and the sky light go through the reference one pixel at a time.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/lighting/relight_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "core/hwy_math-inl.h"
#include "shading/lighting/brdf_lanes-inl.h"
#include "shading/lighting/relight_lanes-inl.h"
// clang-format on

#include <algorithm>
#include <cstdint>

#include "core/parallel.h"
#include "shading/lighting/relight_pixel.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::relight::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using shading::HWY_NAMESPACE::FresnelSchlick;
using shading::HWY_NAMESPACE::GgxDAniso;
using shading::HWY_NAMESPACE::GgxSmithDV;
using shading::HWY_NAMESPACE::SchlickWeight;
using shading::HWY_NAMESPACE::SinSquaredAcross;
using shading::HWY_NAMESPACE::SmithCorrelatedV;
using shading::HWY_NAMESPACE::SmithRoot;
using shading::HWY_NAMESPACE::SmithRootAniso;
using simd::HWY_NAMESPACE::ClampToRange;
using simd::HWY_NAMESPACE::Dot3Unfused;

/// A vector of prepared pixels (prepare_pixel's results, lane by lane) and what the lights'
/// loop needs of them.
struct Pixels {
    M valid, toon, aniso;
    V px, py, pz, nx, ny, nz, vx, vy, vz;
    V rough, metal, alb[3];
    V nv_raw, nv, a2, one_a2, root_v;  // n.v, clamped n.v, alpha^2, 1 - alpha^2, Smith's root
    V f0[3], kd[3];  // F0; diffuse albedo times 1 / pi (toon: divided by pi, as direct_response)
    // Anisotropic lanes: the tangent frame, the alphas and the view's terms.
    V tx, ty, tz, bx, by, bz, ax, ay, tv, bv, root_va;
    // Energy compensation: (1 - E(n.v)), pi (1 - E_avg), F_ms per channel, the table row.
    V one_ev, ms_den, ms[3], tr;
    VI row0;
};

/// prepare_pixel for a vector of pixels: which lanes are surfaces, and their shading inputs
/// (only `valid` when there is none).
template <bool kEnergy>
HWY_INLINE void Prepare(const Inputs &sh, int x, int y, int n, Pixels &p)
{
    const D d;
    const DI di;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    M depth_ok = hn::FirstN(d, std::size_t(n));
    if (sh.from_depth) {
        M ok;
        PositionFromDepth(sh, x, y, n, p.px, p.py, p.pz, ok);
        depth_ok = hn::And(depth_ok, ok);
    } else {
        Load3(*sh.position, x, y, n, p.px, p.py, p.pz);
        if (sh.depth) {
            depth_ok = hn::And(depth_ok, hn::IsFinite(Load1(*sh.depth, x, y, n)));
        }
    }
    Load3(*sh.normal, x, y, n, p.nx, p.ny, p.nz);
    const V nlen = hn::Sqrt(Dot3Unfused(p.nx, p.ny, p.nz, p.nx, p.ny, p.nz));
    M valid = hn::And(depth_ok,
                      hn::And(hn::IsFinite(p.px), hn::And(hn::IsFinite(p.py), hn::IsFinite(p.pz))));
    valid = hn::And(valid, hn::And(hn::Gt(nlen, hn::Set(d, 0.5f)), hn::IsFinite(nlen)));
    const V inv_n = hn::Div(one, hn::IfThenElse(valid, nlen, one));
    p.nx = hn::Mul(p.nx, inv_n);
    p.ny = hn::Mul(p.ny, inv_n);
    p.nz = hn::Mul(p.nz, inv_n);
    const V ex = hn::Sub(hn::Set(d, sh.eye.x), p.px), ey = hn::Sub(hn::Set(d, sh.eye.y), p.py),
            ez = hn::Sub(hn::Set(d, sh.eye.z), p.pz);
    const V elen = hn::Sqrt(Dot3Unfused(ex, ey, ez, ex, ey, ez));
    valid = hn::And(valid, hn::Gt(elen, zero));
    const V inv_e = hn::Div(one, hn::IfThenElse(valid, elen, one));
    p.vx = hn::Mul(ex, inv_e);
    p.vy = hn::Mul(ey, inv_e);
    p.vz = hn::Mul(ez, inv_e);
    // Seen from behind: shade the side we see.
    const M behind = hn::Lt(Dot3Unfused(p.nx, p.ny, p.nz, p.vx, p.vy, p.vz), zero);
    p.nx = hn::IfThenElse(behind, hn::Neg(p.nx), p.nx);
    p.ny = hn::IfThenElse(behind, hn::Neg(p.ny), p.ny);
    p.nz = hn::IfThenElse(behind, hn::Neg(p.nz), p.nz);
    p.valid = valid;
    if (hn::AllFalse(d, valid)) {
        return;  // background only: nothing else is read
    }

    V mr, mm, ma;
    Load3(*sh.material, x, y, n, mr, mm, ma);
    Load3(*sh.albedo, x, y, n, p.alb[0], p.alb[1], p.alb[2]);
    p.rough = hn::IfThenElse(hn::IsFinite(mr), ClampToRange(mr, zero, one), one);
    p.metal = hn::IfThenElseZero(hn::IsFinite(mm), ClampToRange(mm, zero, one));
    const M alb_ok =
        hn::And(hn::IsFinite(p.alb[0]), hn::And(hn::IsFinite(p.alb[1]), hn::IsFinite(p.alb[2])));
    for (V &a : p.alb) {
        a = hn::IfThenElseZero(alb_ok, a);
    }
    p.toon =
        sh.id ? hn::And(valid, ToonMask(*sh.id, x, y, n, sh.toon_words.data())) : hn::FirstN(d, 0);

    // evaluate()'s per-pixel terms.
    p.nv_raw = Dot3Unfused(p.nx, p.ny, p.nz, p.vx, p.vy, p.vz);
    p.nv = hn::Max(p.nv_raw, hn::Set(d, kMinCosine));
    const V r = ClampToRange(p.rough, hn::Set(d, kMinRoughness), one);
    const V alpha = hn::Mul(r, r);
    p.a2 = hn::Mul(alpha, alpha);
    p.one_a2 = hn::Sub(one, p.a2);
    p.root_v = SmithRoot(p.nv, p.a2, p.one_a2);
    // F0 = mix(0.04, albedo, metallic) (glm: 0.04 (1 - m) + albedo m); toon lanes shade their
    // specular as a black dielectric: F0 = 0.04.
    const V one_metal = hn::Sub(one, p.metal);
    const V f0_base = hn::Mul(hn::Set(d, 0.04f), one_metal);
    for (int c = 0; c < 3; ++c) {
        p.f0[c] =
            hn::IfThenElse(p.toon, hn::Set(d, 0.04f), hn::Add(f0_base, hn::Mul(p.alb[c], p.metal)));
        const V diffuse = hn::Mul(p.alb[c], one_metal);
        p.kd[c] = hn::IfThenElse(
            p.toon, hn::Div(diffuse, hn::Set(d, kPi)), hn::Mul(diffuse, hn::Set(d, 1.0f / kPi)));
    }

    // Anisotropy: a material value and a tangent with a usable part across n.
    p.aniso = hn::FirstN(d, 0);
    if (sh.tangent) {
        const M cand = hn::And(valid, hn::And(hn::IsFinite(ma), hn::Ne(ma, zero)));
        if (!hn::AllFalse(d, cand)) {
            V gx, gy, gz;
            Load3(*sh.tangent, x, y, n, gx, gy, gz);
            const V ndt = Dot3Unfused(p.nx, p.ny, p.nz, gx, gy, gz);
            const V qx = hn::Sub(gx, hn::Mul(p.nx, ndt)), qy = hn::Sub(gy, hn::Mul(p.ny, ndt)),
                    qz = hn::Sub(gz, hn::Mul(p.nz, ndt));
            const V q2 = Dot3Unfused(qx, qy, qz, qx, qy, qz);
            p.aniso = hn::And(
                cand, hn::And(hn::IsFinite(qx), hn::And(hn::IsFinite(qy), hn::IsFinite(qz))));
            p.aniso = hn::And(p.aniso, hn::Gt(q2, hn::Set(d, 1e-8f)));
            if (!hn::AllFalse(d, p.aniso)) {
                // evaluate(): t = normalize(tangent - n (n.t)) (glm: times 1 / sqrt), b = n x t.
                const V inv_t = hn::Div(one, hn::Sqrt(hn::IfThenElse(p.aniso, q2, one)));
                p.tx = hn::Mul(qx, inv_t);
                p.ty = hn::Mul(qy, inv_t);
                p.tz = hn::Mul(qz, inv_t);
                p.bx = hn::Sub(hn::Mul(p.ny, p.tz), hn::Mul(p.ty, p.nz));
                p.by = hn::Sub(hn::Mul(p.nz, p.tx), hn::Mul(p.tz, p.nx));
                p.bz = hn::Sub(hn::Mul(p.nx, p.ty), hn::Mul(p.tx, p.ny));
                const V an = ClampToRange(ma, hn::Set(d, -1.0f), one);
                const V min_alpha = hn::Set(d, kMinRoughness * kMinRoughness);
                p.ax = hn::Max(hn::Mul(alpha, hn::Add(one, an)), min_alpha);
                p.ay = hn::Max(hn::Mul(alpha, hn::Sub(one, an)), min_alpha);
                p.tv = Dot3Unfused(p.tx, p.ty, p.tz, p.vx, p.vy, p.vz);
                p.bv = Dot3Unfused(p.bx, p.by, p.bz, p.vx, p.vy, p.vz);
                p.root_va =
                    SmithRootAniso(p.nv, p.tv, p.bv, hn::Mul(p.ax, p.ax), hn::Mul(p.ay, p.ay));
            }
        }
    }

    if (kEnergy) {
        // multiscatter()'s per-pixel terms; toon lanes have no multiple-scattering lobe.
        HWY_ALIGN float r_a[kMaxLanes], nv_a[kMaxLanes], eavg_a[kMaxLanes], ev_a[kMaxLanes];
        HWY_ALIGN float use_a[kMaxLanes];
        hn::Store(p.rough, d, r_a);
        hn::Store(p.nv_raw, d, nv_a);
        hn::Store(hn::IfThenElseZero(hn::AndNot(p.toon, valid), one), d, use_a);
        for (int i = 0; i < int(hn::Lanes(d)); ++i) {
            eavg_a[i] = 1.0f;  // no lobe
            ev_a[i] = 0.0f;
            if (use_a[i] != 0.0f) {
                eavg_a[i] = sh.energy->lookup_e_avg(r_a[i]);
                ev_a[i] = sh.energy->lookup_e(r_a[i], std::clamp(nv_a[i], kMinCosine, 1.0f));
            }
        }
        const V e_avg = hn::Load(d, eavg_a);
        const M lobe = hn::Le(e_avg, hn::Set(d, 1.0f - 1e-6f));
        p.one_ev = hn::IfThenElseZero(lobe, hn::Sub(one, hn::Load(d, ev_a)));
        p.ms_den = hn::IfThenElse(lobe, hn::Mul(hn::Set(d, kPi), hn::Sub(one, e_avg)), one);
        const V one_e_avg = hn::Sub(one, e_avg);
        for (int c = 0; c < 3; ++c) {
            const V f_avg =
                hn::Div(hn::Add(hn::Mul(hn::Set(d, 20.0f), p.f0[c]), one), hn::Set(d, 21.0f));
            p.ms[c] = hn::Div(hn::Mul(hn::Mul(f_avg, f_avg), e_avg),
                              hn::Sub(one, hn::Mul(f_avg, one_e_avg)));
        }
        const V fr = hn::Mul(ClampToRange(p.rough, zero, one),
                             hn::Set(d, float(shading::EnergyTable::kRoughness - 1)));
        const VI j0 =
            hn::Min(hn::ConvertTo(di, fr), hn::Set(di, shading::EnergyTable::kRoughness - 2));
        p.tr = hn::Sub(fr, hn::ConvertTo(d, j0));
        p.row0 = hn::Mul(j0, hn::Set(di, shading::EnergyTable::kMu));
    }
}

/// light_at and direct_response for one light over a vector of prepared pixels, added to the
/// sums acc[3] where it lights them (as light_sum_scalar: times the irradiance, clamped).
template <bool kEnergy>
HWY_INLINE void AddLight(const Inputs &sh, const Light &light, const Pixels &p, M fast, V acc[3])
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    V lx, ly, lz, falloff = one;
    M reached = fast;
    if (light.type == LightType::Directional) {
        lx = hn::Set(d, light.direction.x);
        ly = hn::Set(d, light.direction.y);
        lz = hn::Set(d, light.direction.z);
    } else {
        const V dx = hn::Sub(hn::Set(d, light.position.x), p.px);
        const V dy = hn::Sub(hn::Set(d, light.position.y), p.py);
        const V dz = hn::Sub(hn::Set(d, light.position.z), p.pz);
        const V d2 = Dot3Unfused(dx, dy, dz, dx, dy, dz);
        const V dist = hn::Sqrt(d2);
        reached = hn::And(reached, hn::Gt(dist, zero));  // not at the light
        const V safe = hn::IfThenElse(reached, dist, one);
        const V inv_dist = hn::Div(one, safe);  // light_at: d times 1 / |d|
        lx = hn::Mul(dx, inv_dist);
        ly = hn::Mul(dy, inv_dist);
        lz = hn::Mul(dz, inv_dist);
        falloff = hn::Div(one, hn::Max(d2, hn::Set(d, light.radius * light.radius)));
        if (light.type == LightType::Spot) {
            const V cs = hn::Neg(Dot3Unfused(lx,
                                             ly,
                                             lz,
                                             hn::Set(d, light.direction.x),
                                             hn::Set(d, light.direction.y),
                                             hn::Set(d, light.direction.z)));
            const V t =
                ClampToRange(hn::Mul(hn::Sub(cs, hn::Set(d, light.cos_outer)),
                                     hn::Set(d, 1.0f / (light.cos_inner - light.cos_outer))),
                             zero,
                             one);
            falloff = hn::Mul(
                falloff,
                hn::Mul(hn::Mul(t, t), hn::Sub(hn::Set(d, 3.0f), hn::Mul(hn::Set(d, 2.0f), t))));
            // Outside the cone the light adds exactly 0 (times a finite response).
            reached = hn::And(reached, hn::Gt(falloff, zero));
        }
    }
    const V nl = Dot3Unfused(p.nx, p.ny, p.nz, lx, ly, lz);
    const M lit = hn::And(reached, hn::Gt(nl, zero));
    if (hn::AllFalse(d, lit)) {
        return;
    }
    // The half vector (n where v = -l) and its cosines.
    V hx = hn::Add(p.vx, lx), hy = hn::Add(p.vy, ly), hz = hn::Add(p.vz, lz);
    const V hlen = hn::Sqrt(Dot3Unfused(hx, hy, hz, hx, hy, hz));
    const M hok = hn::Gt(hlen, hn::Set(d, 1e-8f));
    // Times 1 / |v + l|, as evaluate() for the default masking term (the rows run no other).
    const V inv_h = hn::Div(one, hn::IfThenElse(hok, hlen, one));
    hx = hn::IfThenElse(hok, hn::Mul(hx, inv_h), p.nx);
    hy = hn::IfThenElse(hok, hn::Mul(hy, inv_h), p.ny);
    hz = hn::IfThenElse(hok, hn::Mul(hz, inv_h), p.nz);
    const V nh_raw = Dot3Unfused(p.nx, p.ny, p.nz, hx, hy, hz);
    const V nh = hn::Max(nh_raw, zero);
    const V vh = hn::Max(Dot3Unfused(p.vx, p.vy, p.vz, hx, hy, hz), zero);
    const V nlc = hn::Max(nl, hn::Set(d, kMinCosine));
    V dv = GgxSmithDV(nh,
                      SinSquaredAcross(p.nx, p.ny, p.nz, hx, hy, hz, nh_raw),
                      p.a2,
                      p.one_a2,
                      p.nv,
                      nlc,
                      p.root_v,
                      SmithRoot(nlc, p.a2, p.one_a2));
    if (!hn::AllFalse(d, hn::And(lit, p.aniso))) {
        const V th = Dot3Unfused(p.tx, p.ty, p.tz, hx, hy, hz);
        const V bh = Dot3Unfused(p.bx, p.by, p.bz, hx, hy, hz);
        const V tl = Dot3Unfused(p.tx, p.ty, p.tz, lx, ly, lz);
        const V bl = Dot3Unfused(p.bx, p.by, p.bz, lx, ly, lz);
        const V root_la = SmithRootAniso(nlc, tl, bl, hn::Mul(p.ax, p.ax), hn::Mul(p.ay, p.ay));
        const V dva = hn::Mul(GgxDAniso(nh, th, bh, p.ax, p.ay),
                              SmithCorrelatedV(p.nv, nlc, p.root_va, root_la));
        dv = hn::IfThenElse(p.aniso, dva, dv);
    }
    const V w = SchlickWeight(vh);
    // Diffuse: n.l, or the toon band ceil(n.l bands) / bands.
    V dfac = nl;
    const bool any_toon = !hn::AllFalse(d, hn::And(lit, p.toon));
    if (any_toon) {
        const float bands = float(sh.toon.toon_bands);
        const V band = hn::Div(hn::Ceil(hn::Mul(nl, hn::Set(d, bands))), hn::Set(d, bands));
        dfac = hn::IfThenElse(p.toon, band, nl);
    }
    V msl = zero;
    if (kEnergy) {
        // (1 - E(n.v)) (1 - E(n.l)) / (pi (1 - E_avg)), times n.l below.
        const V one_el = hn::Sub(one, EnergyE(*sh.energy, p.row0, p.tr, nl));
        msl = hn::Mul(hn::Div(hn::Mul(p.one_ev, one_el), p.ms_den), nl);
    }
    const float power[3] = {light.power.x, light.power.y, light.power.z};
    const bool clamp = sh.clamp > 0.0f;
    const V clamp_v = hn::Set(d, sh.clamp);
    for (int c = 0; c < 3; ++c) {
        const V f = FresnelSchlick(p.f0[c], w);
        const V spec = hn::Mul(f, dv);
        // Non-toon: (kd + F D V) n.l; toon: kd band + (0 + F D V) n.l.
        const V plain = hn::Mul(hn::Add(p.kd[c], spec), nl);
        V response = plain;
        if (any_toon) {
            response =
                hn::IfThenElse(p.toon, hn::Add(hn::Mul(p.kd[c], dfac), hn::Mul(spec, nl)), plain);
        }
        if (kEnergy) {
            response =
                hn::Add(response, hn::IfThenElseZero(hn::Not(p.toon), hn::Mul(p.ms[c], msl)));
        }
        // The irradiance: the light's power times the falloff (a sun has none).
        const V e = light.type == LightType::Directional ? hn::Set(d, power[c])
                                                         : hn::Mul(hn::Set(d, power[c]), falloff);
        V add = hn::Mul(response, e);
        if (clamp) {
            add = hn::IfThenElse(hn::Lt(clamp_v, add), clamp_v, add);  // glm::min(add, clamp)
        }
        acc[c] = hn::Add(acc[c], hn::IfThenElseZero(lit, add));
    }
}

template <bool kEnergy>
void ShadeRow(const Inputs &sh, int x0, int x1, int y, Image &out)
{
    const D d;
    const int lanes = int(hn::Lanes(d));
    const int nc = sh.color->channels();
    // Toon highlights quantised per pixel (toon_specular_steps) take the reference path.
    const bool toon_in_kernel = sh.toon.toon_specular_steps == 0;
    for (int x = x0; x < x1; x += lanes) {
        const int n = std::min(lanes, x1 - x);
        Pixels p;
        Prepare<kEnergy>(sh, x, y, n, p);
        M valid = p.valid;
        V acc[3] = {hn::Zero(d), hn::Zero(d), hn::Zero(d)};
        if (!hn::AllFalse(d, valid)) {
            const M slow = toon_in_kernel ? hn::FirstN(d, 0) : p.toon;
            const M fast = hn::AndNot(slow, valid);
            if (!hn::AllFalse(d, fast)) {
                for (const Light &light : sh.setup->lights) {
                    AddLight<kEnergy>(sh, light, p, fast, acc);
                }
            }
            // The reference one pixel at a time: quantised toon lanes, then the sky light.
            if (!hn::AllFalse(d, slow) || sh.ambient > 0.0f) {
                // The vector's n, v and surface are the reference's bits: the sky light starts
                // from them; quantised toon lanes are prepared again.
                HWY_ALIGN float s[14][kMaxLanes];
                const V keep[14] = {p.nx,
                                    p.ny,
                                    p.nz,
                                    p.vx,
                                    p.vy,
                                    p.vz,
                                    p.alb[0],
                                    p.alb[1],
                                    p.alb[2],
                                    p.rough,
                                    p.metal,
                                    acc[0],
                                    acc[1],
                                    acc[2]};
                for (int k = 0; k < 14; ++k) {
                    hn::Store(keep[k], d, s[k]);
                }
                HWY_ALIGN float valid_a[kMaxLanes], slow_a[kMaxLanes];
                hn::Store(hn::IfThenElseZero(valid, hn::Set(d, 1.0f)), d, valid_a);
                hn::Store(hn::IfThenElseZero(slow, hn::Set(d, 1.0f)), d, slow_a);
                for (int i = 0; i < n; ++i) {
                    if (valid_a[i] == 0.0f) {
                        continue;
                    }
                    Prepared pr;
                    glm::vec3 c(s[11][i], s[12][i], s[13][i]);
                    if (slow_a[i] != 0.0f) {
                        prepare_pixel(sh, x + i, y, pr);
                        c = light_sum_scalar(sh, pr, x + i, y);
                    } else {
                        pr.n = glm::vec3(s[0][i], s[1][i], s[2][i]);
                        pr.v = glm::vec3(s[3][i], s[4][i], s[5][i]);
                        pr.surf.albedo = glm::vec3(s[6][i], s[7][i], s[8][i]);
                        pr.surf.roughness = s[9][i];
                        pr.surf.metallic = s[10][i];
                    }
                    if (sh.ambient > 0.0f) {
                        c = shading::add_sky_light(c, pr.surf, pr.n, pr.v, sh.sky_sun, sh.ambient);
                    }
                    s[11][i] = c.x;
                    s[12][i] = c.y;
                    s[13][i] = c.z;
                }
                acc[0] = hn::Load(d, s[11]);
                acc[1] = hn::Load(d, s[12]);
                acc[2] = hn::Load(d, s[13]);
            }
        }
        // Output: surfaces get their light (plus the input color in mode add), the rest keeps
        // the input color.
        const float *src = sh.color->pixel(x, y);
        float *dst = out.pixel(x, y);
        if (nc == 4 && n == lanes) {
            V in[4];
            hn::LoadInterleaved4(d, src, in[0], in[1], in[2], in[3]);
            V o[3];
            for (int c = 0; c < 3; ++c) {
                o[c] = hn::IfThenElse(valid, sh.replace ? acc[c] : hn::Add(in[c], acc[c]), in[c]);
            }
            hn::StoreInterleaved4(o[0], o[1], o[2], in[3], d, dst);
            continue;
        }
        HWY_ALIGN float c[3][kMaxLanes], valid_a[kMaxLanes];
        for (int k = 0; k < 3; ++k) {
            hn::Store(acc[k], d, c[k]);
        }
        hn::Store(hn::IfThenElseZero(valid, hn::Set(d, 1.0f)), d, valid_a);
        std::copy(src, src + n * nc, dst);
        for (int i = 0; i < n; ++i) {
            if (valid_a[i] != 0.0f) {
                float *px = dst + i * nc;
                for (int k = 0; k < 3; ++k) {
                    px[k] = sh.replace ? c[k][i] : px[k] + c[k][i];
                }
            }
        }
    }
}

void ShadeRows(const Inputs &sh, Image &out)
{
    // Whole rows: seven long streams that the hardware prefetcher follows. Pixels are
    // independent, so the partition does not change any bits.
    const int W = out.width(), H = out.height();
    if (sh.energy) {
        parallel_for(0, H, [&](int y) { ShadeRow<true>(sh, 0, W, y, out); });
    } else {
        parallel_for(0, H, [&](int y) { ShadeRow<false>(sh, 0, W, y, out); });
    }
}

}  // namespace posthaste::shading::relight::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading::relight {

HWY_EXPORT(ShadeRows);

void shade_rows_vector(const Inputs &sh, Image &out)
{
    HWY_DYNAMIC_DISPATCH(ShadeRows)(sh, out);
}

}  // namespace posthaste::shading::relight
#endif
