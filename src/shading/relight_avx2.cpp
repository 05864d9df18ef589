// The relight method's AVX2 rows (see the comment below); shading/relight.cpp dispatches here.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <limits>

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/relight_avx2_lanes.h"
#include "shading/relight_pixel.h"

namespace posthaste::shading::relight {

#if POSTHASTE_HAVE_AVX2_TARGET
// The AVX2 path: one tile row, 8 pixels at a time in structure-of-arrays form, setup and lights
// in vector registers. Same formulas as prepare_pixel and shading::evaluate; it rounds
// differently (FMA, rsqrt/rcp with one Newton step), so it matches the portable path to a few
// ulp, not bit for bit (tests/unit/relight_simd_test.cpp bounds the difference on a real frame).
//
// No FMA contraction here: the reference (shading::evaluate, the rasterizer) rounds every
// product, and the GGX peak amplifies a one-ulp change of n.h by about 1 / alpha^2; fused
// multiply-adds raised the relit-vs-beauty RMSE by a fifth.
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif

// kEnergy: with the Kulla-Conty lobe (a separate instance: its live registers slowed the
// default path by a fifth).
template <bool kEnergy>
POSTHASTE_AVX2 void shade_row_avx2(const Inputs &sh, int x0, int x1, int y, Image &out)
{
    const V zero = _mm256_setzero_ps(), one = vset(1.0f), half = vset(0.5f);
    const V min_cos = vset(shading::kMinCosine);
    const V clamp_v = vset(sh.clamp > 0.0f ? sh.clamp : std::numeric_limits<float>::max());
    const V lane = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const std::vector<Light> &lights = sh.setup->lights;
    const int bands = sh.toon.toon_bands;
    const V bands_v = vset(float(bands)), inv_bands = vset(1.0f / float(bands));
    // Toon highlights quantised per pixel (toon_specular_steps) take the scalar path.
    const bool toon_in_kernel = sh.toon.toon_specular_steps == 0;
    const int nc = sh.color->channels();
    const V eye_x = vset(sh.eye.x), eye_y = vset(sh.eye.y), eye_z = vset(sh.eye.z);
    const __m256i toon_bits =
        _mm256_loadu_si256(reinterpret_cast<const __m256i *>(sh.toon_words.data()));
    // Streaming (non-temporal) stores when the row is 16-byte aligned: the 33 MB output does
    // not fit in any cache, and a normal store first reads each line it writes.
    const bool stream = nc == 4 && reinterpret_cast<std::uintptr_t>(out.pixel(x0, y)) % 16 == 0;
    for (int x = x0; x < x1; x += 8) {
        const int n = std::min(8, x1 - x);
        // Setup, as prepare_pixel.
        V px, py, pz, nx, ny, nz;
        V depth_ok = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
        if (sh.from_depth) {
            position_from_depth(sh, x, y, n, px, py, pz, depth_ok);
        } else {
            load3x8(*sh.position, x, y, n, px, py, pz);
        }
        load3x8(*sh.normal, x, y, n, nx, ny, nz);
        const V nlen2 = vdot(nx, ny, nz, nx, ny, nz);
        // |n| > 0.5 and finite, as nlen2 > 0.25 (rounding can differ only within an ulp of 0.5).
        V valid = _mm256_cmp_ps(lane, vset(float(n)), _CMP_LT_OQ);
        valid = _mm256_and_ps(valid, _mm256_and_ps(finite_mask(px), finite_mask(py)));
        valid = _mm256_and_ps(valid, _mm256_and_ps(finite_mask(pz), depth_ok));
        valid = _mm256_and_ps(valid, _mm256_cmp_ps(nlen2, vset(0.25f), _CMP_GT_OQ));
        valid = _mm256_and_ps(valid, finite_mask(nlen2));
        const V ex = vsub(eye_x, px), ey = vsub(eye_y, py), ez = vsub(eye_z, pz);
        const V elen2 = vdot(ex, ey, ez, ex, ey, ez);
        valid = _mm256_and_ps(valid, _mm256_cmp_ps(elen2, zero, _CMP_GT_OQ));
        int valid_bits = _mm256_movemask_ps(valid);
        alignas(32) float cr[8], cg[8], cb[8];
        V ar = zero, ag = zero, ab = zero;
        if (valid_bits != 0) {
            // Exact sqrt and division, as prepare_pixel: the highlight's D amplifies an error in
            // n or v by about 1 / alpha^2 (rsqrt with one Newton step doubled the RMSE of
            // RelightAccuracy and failed its 1e-4 hand check at a glossy peak).
            const V inv_n = _mm256_div_ps(one, _mm256_sqrt_ps(select(valid, nlen2, one)));
            const V inv_e = _mm256_div_ps(one, _mm256_sqrt_ps(select(valid, elen2, one)));
            nx = vmul(nx, inv_n);
            ny = vmul(ny, inv_n);
            nz = vmul(nz, inv_n);
            const V vx = vmul(ex, inv_e), vy = vmul(ey, inv_e), vz = vmul(ez, inv_e);
            // Seen from behind: flip n (n.v changes sign exactly).
            const V ndv = vdot(nx, ny, nz, vx, vy, vz);
            const V flip = _mm256_and_ps(_mm256_cmp_ps(ndv, zero, _CMP_LT_OQ), vset(-0.0f));
            nx = _mm256_xor_ps(nx, flip);
            ny = _mm256_xor_ps(ny, flip);
            nz = _mm256_xor_ps(nz, flip);
            const V nv_raw = _mm256_xor_ps(ndv, flip);
            const V nv = _mm256_max_ps(nv_raw, min_cos);

            V mr, mm, ma, alb_r, alb_g, alb_b;
            load3x8(*sh.material, x, y, n, mr, mm, ma);
            load3x8(*sh.albedo, x, y, n, alb_r, alb_g, alb_b);
            const V rough = select(finite_mask(mr), simd::v8::clamp(mr, zero, one), one);
            const V metal = select(finite_mask(mm), simd::v8::clamp(mm, zero, one), zero);
            const V alb_ok = _mm256_and_ps(_mm256_and_ps(finite_mask(alb_r), finite_mask(alb_g)),
                                           finite_mask(alb_b));
            alb_r = _mm256_and_ps(alb_r, alb_ok);
            alb_g = _mm256_and_ps(alb_g, alb_ok);
            alb_b = _mm256_and_ps(alb_b, alb_ok);
            V slow = zero;
            V toon = zero;
            if (sh.id) {
                toon = toon_mask(*sh.id, x, y, n, toon_bits);
                if (!toon_in_kernel) {
                    slow = _mm256_or_ps(slow, toon);
                }
            }
            slow = _mm256_and_ps(slow, valid);
            const V fast = _mm256_andnot_ps(slow, valid);

            const V rc = _mm256_max_ps(rough, vset(shading::kMinRoughness));
            const V alpha = vmul(rc, rc);
            const V a2 = vmul(alpha, alpha);
            const V one_minus_a2 = vsub(one, a2);
            const V a2_pi = vmul(a2, vset(1.0f / shading::kPi));
            const V sv2 = vfma(vmul(nv, nv), one_minus_a2, a2);
            const V sv = vmul(sv2, simd::v8::rsqrt(sv2));  // sv2 >= a2 > 0
            // F0 = mix(0.04, albedo, metallic), 0.04 for toon (a black dielectric's highlight).
            const V f0_base = vmul(vset(0.04f), vsub(one, metal));
            const V f0r = select(toon, vset(0.04f), vfma(alb_r, metal, f0_base));
            const V f0g = select(toon, vset(0.04f), vfma(alb_g, metal, f0_base));
            const V f0b = select(toon, vset(0.04f), vfma(alb_b, metal, f0_base));
            const V kd_scale = vmul(vsub(one, metal), vset(1.0f / shading::kPi));
            const V kdr = vmul(alb_r, kd_scale), kdg = vmul(alb_g, kd_scale),
                    kdb = vmul(alb_b, kd_scale);
            // Anisotropic lanes, as prepare_pixel and evaluate(): a material anisotropy and a
            // tangent with a usable part across n. t, b = n x t, the alphas of
            // anisotropic_alphas and the per-pixel half of the anisotropic Smith term.
            V aniso = zero;
            V tx = zero, ty = zero, tz = zero, bx = zero, by = zero, bz = zero;
            V inv_ax = one, inv_ay = one, ax2 = one, ay2 = one, d_scale = one;
            V tv = zero, bv = zero, lv = one;
            if (sh.tangent) {
                const V cand = _mm256_and_ps(
                    valid, _mm256_and_ps(finite_mask(ma), _mm256_cmp_ps(ma, zero, _CMP_NEQ_UQ)));
                V px_ = zero, py_ = zero, pz_ = zero, tp2 = one;
                if (_mm256_movemask_ps(cand) != 0) {
                    V gx, gy, gz;
                    load3x8(*sh.tangent, x, y, n, gx, gy, gz);
                    const V ndt = vdot(nx, ny, nz, gx, gy, gz);
                    px_ = vsub(gx, vmul(nx, ndt));
                    py_ = vsub(gy, vmul(ny, ndt));
                    pz_ = vsub(gz, vmul(nz, ndt));
                    tp2 = vdot(px_, py_, pz_, px_, py_, pz_);
                    aniso = _mm256_and_ps(cand, _mm256_and_ps(finite_mask(px_), finite_mask(py_)));
                    aniso = _mm256_and_ps(aniso, finite_mask(pz_));
                    aniso = _mm256_and_ps(aniso, _mm256_cmp_ps(tp2, vset(1e-8f), _CMP_GT_OQ));
                }
                if (_mm256_movemask_ps(aniso) != 0) {
                    const V inv_t = _mm256_div_ps(one, _mm256_sqrt_ps(select(aniso, tp2, one)));
                    tx = vmul(px_, inv_t);
                    ty = vmul(py_, inv_t);
                    tz = vmul(pz_, inv_t);
                    bx = vsub(vmul(ny, tz), vmul(nz, ty));
                    by = vsub(vmul(nz, tx), vmul(nx, tz));
                    bz = vsub(vmul(nx, ty), vmul(ny, tx));
                    const V an = simd::v8::clamp(ma, vset(-1.0f), one);
                    const V min_alpha = vset(shading::kMinRoughness * shading::kMinRoughness);
                    const V ax = _mm256_max_ps(vmul(alpha, vadd(one, an)), min_alpha);
                    const V ay = _mm256_max_ps(vmul(alpha, vsub(one, an)), min_alpha);
                    inv_ax = _mm256_div_ps(one, ax);
                    inv_ay = _mm256_div_ps(one, ay);
                    ax2 = vmul(ax, ax);
                    ay2 = vmul(ay, ay);
                    d_scale = _mm256_div_ps(vset(1.0f / shading::kPi), vmul(ax, ay));
                    tv = vdot(tx, ty, tz, vx, vy, vz);
                    bv = vdot(bx, by, bz, vx, vy, vz);
                    lv = _mm256_sqrt_ps(
                        vadd(vadd(vmul(ax2, vmul(tv, tv)), vmul(ay2, vmul(bv, bv))), vmul(nv, nv)));
                }
            }
            const bool any_aniso = _mm256_movemask_ps(aniso) != 0;
            const bool any_toon = _mm256_movemask_ps(_mm256_and_ps(toon, valid)) != 0;
            // Kulla-Conty lobe (shading::multiscatter): per pixel E_avg, E(n.v) and the coloured
            // F_ms / (pi (1 - E_avg)) (1 - E(n.v)), looked up exactly as the scalar code; per light
            // E(n.l) from the table row of this roughness. Toon lanes have none.
            V msr = zero, msg = zero, msb = zero, tr = zero;
            __m256i row0 = _mm256_setzero_si256();
            if (kEnergy) {
                alignas(32) float r_a[8], nv_a[8], eavg_a[8] = {}, k_a[8] = {};
                _mm256_store_ps(r_a, rough);
                _mm256_store_ps(nv_a, nv_raw);
                const int fast_bits = _mm256_movemask_ps(_mm256_andnot_ps(toon, fast));
                for (int i = 0; i < n; ++i) {
                    if (!((fast_bits >> i) & 1)) {
                        continue;
                    }
                    const float e_avg = sh.energy->lookup_e_avg(r_a[i]);
                    if (e_avg > 1.0f - 1e-6f) {
                        continue;
                    }
                    const float ev =
                        sh.energy->lookup_e(r_a[i], std::clamp(nv_a[i], shading::kMinCosine, 1.0f));
                    eavg_a[i] = e_avg;
                    k_a[i] = (1.0f - ev) / (shading::kPi * (1.0f - e_avg));
                }
                const V e_avg = _mm256_load_ps(eavg_a), k = _mm256_load_ps(k_a);
                msr = vmul(ms_colour(f0r, e_avg), k);
                msg = vmul(ms_colour(f0g, e_avg), k);
                msb = vmul(ms_colour(f0b, e_avg), k);
                const V fr = vmul(rough, vset(float(shading::EnergyTable::kRoughness - 1)));
                const __m256i j0 =
                    _mm256_min_epi32(_mm256_cvttps_epi32(fr),
                                     _mm256_set1_epi32(shading::EnergyTable::kRoughness - 2));
                tr = vsub(fr, _mm256_cvtepi32_ps(j0));
                row0 = _mm256_mullo_epi32(j0, _mm256_set1_epi32(shading::EnergyTable::kMu));
            }
            const V f1r = vsub(one, f0r), f1g = vsub(one, f0g), f1b = vsub(one, f0b);

            if (_mm256_movemask_ps(fast) != 0) {
                for (const Light &light : lights) {
                    V lx, ly, lz, falloff = one;
                    if (light.type == LightType::Directional) {
                        lx = vset(light.direction.x);
                        ly = vset(light.direction.y);
                        lz = vset(light.direction.z);
                    } else {
                        const V dx = vsub(vset(light.position.x), px);
                        const V dy = vsub(vset(light.position.y), py);
                        const V dz = vsub(vset(light.position.z), pz);
                        const V d2 = vdot(dx, dy, dz, dx, dy, dz);
                        // At the light (d2 = 0) the lane gets l = 0: n.l = 0, no light.
                        const V inv =
                            _mm256_and_ps(_mm256_cmp_ps(d2, zero, _CMP_GT_OQ), simd::v8::rsqrt(d2));
                        lx = vmul(dx, inv);
                        ly = vmul(dy, inv);
                        lz = vmul(dz, inv);
                        falloff =
                            simd::v8::rcp(_mm256_max_ps(d2, vset(light.radius * light.radius)));
                        if (light.type == LightType::Spot) {
                            const V cs = vdot(lx,
                                              ly,
                                              lz,
                                              vset(-light.direction.x),
                                              vset(-light.direction.y),
                                              vset(-light.direction.z));
                            const V t = simd::v8::clamp(
                                vmul(vsub(cs, vset(light.cos_outer)),
                                     vset(1.0f / (light.cos_inner - light.cos_outer))),
                                zero,
                                one);
                            falloff =
                                vmul(falloff, vmul(vmul(t, t), vfma(t, vset(-2.0f), vset(3.0f))));
                        }
                    }
                    const V nl = vdot(nx, ny, nz, lx, ly, lz);
                    V lit = _mm256_and_ps(fast, _mm256_cmp_ps(nl, zero, _CMP_GT_OQ));
                    if (light.type == LightType::Spot) {
                        // Outside the cone the light adds exactly 0: skip it for the group.
                        lit = _mm256_and_ps(lit, _mm256_cmp_ps(falloff, zero, _CMP_GT_OQ));
                    }
                    if (_mm256_movemask_ps(lit) == 0) {
                        continue;
                    }
                    // h = (v + l) / |v + l|; n.h and v.h from dot products.
                    const V hx = vadd(vx, lx), hy = vadd(vy, ly), hz = vadd(vz, lz);
                    const V hlen2 = vdot(hx, hy, hz, hx, hy, hz);
                    const V hok = _mm256_cmp_ps(hlen2, vset(1e-16f), _CMP_GT_OQ);
                    const V inv_h = simd::v8::rsqrt(select(hok, hlen2, one));
                    // Degenerate h (v = -l) falls back to h = n: n.h = 1, v.h = n.v.
                    const V nh =
                        _mm256_max_ps(select(hok, vmul(vadd(nv_raw, nl), inv_h), one), zero);
                    const V vl = vdot(vx, vy, vz, lx, ly, lz);
                    const V vh =
                        _mm256_max_ps(select(hok, vmul(vadd(one, vl), inv_h), nv_raw), zero);
                    // D = a2 / (pi d^2), d = (n.h)^2 (a2 - 1) + 1 = s2 (1 - a2) + a2 with
                    // s2 = 1 - (n.h)^2 from h's part across n, |h - n (n.h)|^2: near the peak
                    // 1 - (n.h)^2 cancels and D inherits an error ~ ulp / a2.
                    const V nhu = vadd(nv_raw, nl);  // n.(v + l)
                    const V qx = vsub(hx, vmul(nx, nhu)), qy = vsub(hy, vmul(ny, nhu)),
                            qz = vsub(hz, vmul(nz, nhu));
                    V s2 =
                        _mm256_min_ps(vmul(vdot(qx, qy, qz, qx, qy, qz), vmul(inv_h, inv_h)), one);
                    s2 = select(_mm256_cmp_ps(nh, zero, _CMP_GT_OQ), s2, one);  // n.h = 0
                    s2 = select(hok, s2, zero);                                 // h = n
                    const V dd = vfma(s2, one_minus_a2, a2);
                    const V d = vmul(a2_pi, simd::v8::rcp(vmul(dd, dd)));
                    // V = 0.5 / (n.l sv + n.v sqrt(n.l^2 (1 - a2) + a2)), cosines clamped.
                    const V nlc = _mm256_max_ps(nl, min_cos);
                    const V sl2 = vfma(vmul(nlc, nlc), one_minus_a2, a2);
                    const V sl = vmul(sl2, simd::v8::rsqrt(sl2));
                    const V vis = vmul(half, simd::v8::rcp(vfma(nlc, sv, vmul(nv, sl))));
                    V dv = vmul(d, vis);
                    if (any_aniso) {
                        // Anisotropic D and V (d_ggx_aniso, v_smith_correlated_aniso).
                        const V tl = vdot(tx, ty, tz, lx, ly, lz);
                        const V bl = vdot(bx, by, bz, lx, ly, lz);
                        const V hxa = vmul(vmul(vadd(tv, tl), inv_h), inv_ax);
                        const V hya = vmul(vmul(vadd(bv, bl), inv_h), inv_ay);
                        const V da2 = vadd(vadd(vmul(hxa, hxa), vmul(hya, hya)), vmul(nh, nh));
                        const V da = _mm256_and_ps(_mm256_cmp_ps(nh, zero, _CMP_GT_OQ),
                                                   vmul(d_scale, simd::v8::rcp(vmul(da2, da2))));
                        const V ll2 = vadd(vadd(vmul(ax2, vmul(tl, tl)), vmul(ay2, vmul(bl, bl))),
                                           vmul(nlc, nlc));
                        const V ll = vmul(ll2, simd::v8::rsqrt(ll2));
                        const V visa = vmul(half, simd::v8::rcp(vadd(vmul(nlc, lv), vmul(nv, ll))));
                        dv = select(aniso, vmul(da, visa), dv);
                    }
                    V spec = vmul(dv, nl);
                    // Schlick: F = f0 + (1 - f0) m^5, m = 1 - clamp(v.h, 0, 1).
                    const V m = vsub(one, _mm256_min_ps(vh, one));
                    const V m2 = vmul(m, m);
                    const V m5 = vmul(vmul(m2, m2), m);
                    // Diffuse n.l, or the toon band ceil(n.l bands) / bands.
                    const V dfac =
                        any_toon
                            ? select(toon, vmul(_mm256_ceil_ps(vmul(nl, bands_v)), inv_bands), nl)
                            : nl;
                    const V er = vmul(vset(light.power.x), falloff);
                    const V eg = vmul(vset(light.power.y), falloff);
                    const V eb = vmul(vset(light.power.z), falloff);
                    if (kEnergy) {
                        const V msl = vmul(vsub(one, energy_e(*sh.energy, row0, tr, nl)), nl);
                        ar = vadd(
                            ar,
                            light_channel_ms(
                                f0r, f1r, kdr, er, m5, dfac, spec, vmul(msr, msl), lit, clamp_v));
                        ag = vadd(
                            ag,
                            light_channel_ms(
                                f0g, f1g, kdg, eg, m5, dfac, spec, vmul(msg, msl), lit, clamp_v));
                        ab = vadd(
                            ab,
                            light_channel_ms(
                                f0b, f1b, kdb, eb, m5, dfac, spec, vmul(msb, msl), lit, clamp_v));
                        continue;
                    }
                    ar = vadd(ar, light_channel(f0r, f1r, kdr, er, m5, dfac, spec, lit, clamp_v));
                    ag = vadd(ag, light_channel(f0g, f1g, kdg, eg, m5, dfac, spec, lit, clamp_v));
                    ab = vadd(ab, light_channel(f0b, f1b, kdb, eb, m5, dfac, spec, lit, clamp_v));
                }
            }
            _mm256_store_ps(cr, ar);
            _mm256_store_ps(cg, ag);
            _mm256_store_ps(cb, ab);
            // Scalar work: anisotropic (and quantised-toon) lanes, then the sky light.
            const int slow_bits = _mm256_movemask_ps(slow);
            if (slow_bits != 0 || sh.ambient > 0.0f) {
                alignas(32) float s[11][8];
                const V keep[11] = {nx, ny, nz, vx, vy, vz, alb_r, alb_g, alb_b, rough, metal};
                for (int k = 0; k < 11; ++k) {
                    _mm256_store_ps(s[k], keep[k]);
                }
                for (int i = 0; i < n; ++i) {
                    if (!((valid_bits >> i) & 1)) {
                        continue;
                    }
                    Prepared pr;
                    glm::vec3 c(cr[i], cg[i], cb[i]);
                    if ((slow_bits >> i) & 1) {
                        prepare_pixel(sh, x + i, y, pr);
                        if (!pr.valid) {  // |n| within an ulp of 0.5: background after all
                            valid_bits &= ~(1 << i);
                            continue;
                        }
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
                    cr[i] = c.x;
                    cg[i] = c.y;
                    cb[i] = c.z;
                }
                ar = _mm256_load_ps(cr);
                ag = _mm256_load_ps(cg);
                ab = _mm256_load_ps(cb);
                valid = mask_from_bits(valid_bits);
            }
        }
        // Output: surfaces get their light (plus the input color in mode add), the rest keeps
        // the input color.
        const float *src = sh.color->pixel(x, y);
        float *dst = out.pixel(x, y);
        if (nc == 4 && n == 8) {
            V acc[4], mask[4];
            interleave4x8(ar, ag, ab, zero, acc);
            interleave4x8(valid, valid, valid, zero, mask);
            for (int k = 0; k < 4; ++k) {
                const V in = _mm256_loadu_ps(src + 8 * k);
                const V lit = sh.replace ? acc[k] : vadd(in, acc[k]);
                const V o = select(mask[k], lit, in);
                if (stream) {
                    _mm_stream_ps(dst + 8 * k, _mm256_castps256_ps128(o));
                    _mm_stream_ps(dst + 8 * k + 4, _mm256_extractf128_ps(o, 1));
                } else {
                    _mm256_storeu_ps(dst + 8 * k, o);
                }
            }
            continue;
        }
        _mm256_store_ps(cr, ar);
        _mm256_store_ps(cg, ag);
        _mm256_store_ps(cb, ab);
        std::copy(src, src + n * nc, dst);
        for (int i = 0; i < n; ++i) {
            if ((valid_bits >> i) & 1) {
                float *d = dst + i * nc;
                d[0] = sh.replace ? cr[i] : d[0] + cr[i];
                d[1] = sh.replace ? cg[i] : d[1] + cg[i];
                d[2] = sh.replace ? cb[i] : d[2] + cb[i];
            }
        }
    }
    if (stream) {
        _mm_sfence();  // order the streaming stores before the loop's join
    }
}
#if !defined(__clang__)
#pragma GCC pop_options
#endif

void shade_rows_avx2(const Inputs &sh, Image &out)
{
    // Whole rows: seven long streams that the hardware prefetcher follows, instead of 64-pixel
    // pieces of them (the tile layout left the loads of color and id waiting on memory). Pixels
    // are independent, so the partition does not change any bits.
    const int W = out.width(), H = out.height();
    if (sh.energy) {
        parallel_for(0, H, [&](int y) { shade_row_avx2<true>(sh, 0, W, y, out); });
    } else {
        parallel_for(0, H, [&](int y) { shade_row_avx2<false>(sh, 0, W, y, out); });
    }
}
#endif

}  // namespace posthaste::shading::relight
