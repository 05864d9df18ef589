// The hatching kernel's AVX2 tiles (hatch_kernel.h); shading/hatch.cpp dispatches here.
#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/hatch_avx2_lanes.h"
#include "shading/hatch_kernel.h"

namespace posthaste::shading::hatch_detail {

#if POSTHASTE_HAVE_AVX2_TARGET
// The kernel below mirrors the scalar path operation by operation. GCC would fuse a * b + c of
// intrinsics into FMA (its C++ default is -ffp-contract=fast, and the scalar path, built for
// baseline x86-64, has no FMA), which rounds differently: keep the two paths equal.
#if defined(__GNUC__) && !defined(__clang__)
#if !defined(__clang__)  // clang builds pass -ffp-contract=off (CMakeLists.txt)
#pragma GCC push_options
#pragma GCC optimize("fp-contract=off")
#endif
#endif
namespace {

namespace v8 = simd::v8;
using v8::V;
using v8::VI;

/// Fills the sample planes of region r (stride `stride`, `rows` rows) from the passes.
POSTHASTE_AVX2 void fill_samples_avx2(
    const KernelCtx &k, const Rect &r, int stride, float *buf, std::size_t plane)
{
    const int w = k.color->width(), h = k.color->height();
    const int zs = k.depth->channels(), ps = k.position->channels(), ns = k.normal->channels();
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const V zero = _mm256_setzero_ps(), ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for (int row = 0; row < r.height(); ++row) {
        const int y = std::clamp(r.y0 + row, 0, h - 1);
        const float *zr = k.depth->pixel(0, y), *pr = k.position->pixel(0, y);
        const float *nr = k.normal->pixel(0, y);
        for (int col = 0; col < stride; col += 8) {
            const int x = r.x0 + col;
            V z, px, py, pz, nx, ny, nz;
            if (x >= 0 && x + 8 <= w && zs == 1 && ps == 3 && ns == 3) {
                z = ld(zr + x);
                load_xyz8(pr + 3 * std::size_t(x), px, py, pz);
                load_xyz8(nr + 3 * std::size_t(x), nx, ny, nz);
            } else {
                const VI xi =
                    _mm256_min_epi32(_mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane),
                                                      _mm256_setzero_si256()),
                                     _mm256_set1_epi32(w - 1));
                const VI zi = _mm256_mullo_epi32(xi, _mm256_set1_epi32(zs));
                const VI pi = _mm256_mullo_epi32(xi, _mm256_set1_epi32(ps));
                const VI ni = _mm256_mullo_epi32(xi, _mm256_set1_epi32(ns));
                const VI c1 = _mm256_set1_epi32(1), c2 = _mm256_set1_epi32(2);
                z = _mm256_i32gather_ps(zr, zi, 4);
                px = _mm256_i32gather_ps(pr, pi, 4);
                py = _mm256_i32gather_ps(pr, _mm256_add_epi32(pi, c1), 4);
                pz = _mm256_i32gather_ps(pr, _mm256_add_epi32(pi, c2), 4);
                nx = _mm256_i32gather_ps(nr, ni, 4);
                ny = _mm256_i32gather_ps(nr, _mm256_add_epi32(ni, c1), 4);
                nz = _mm256_i32gather_ps(nr, _mm256_add_epi32(ni, c2), 4);
            }
            // read_sample: hit = finite positive depth and finite position.
            const V hit = vand(vand(_mm256_cmp_ps(z, zero, _CMP_GT_OQ), finite_v(z)),
                               finite_v(add(add(px, py), pz)));
            const V len2 = dot3(nx, ny, nz, nx, ny, nz);
            const V nrm =
                vand(vand(hit, _mm256_cmp_ps(len2, v8::set1(1e-4f), _CMP_GT_OQ)), finite_v(len2));
            const V unit =
                _mm256_cmp_ps(vabs(sub(len2, v8::set1(1.0f))), v8::set1(1e-4f), _CMP_LT_OQ);
            const V rescale = andnot(nrm, unit);
            if (!_mm256_testz_ps(rescale, rescale)) {  // rendered normals are unit already
                const V root = _mm256_sqrt_ps(len2);
                nx = select(unit, nx, _mm256_div_ps(nx, root));
                ny = select(unit, ny, _mm256_div_ps(ny, root));
                nz = select(unit, nz, _mm256_div_ps(nz, root));
            }
            nx = vand(nrm, nx);
            ny = vand(nrm, ny);
            nz = vand(nrm, nz);
            float *o = buf + std::size_t(row) * std::size_t(stride) + std::size_t(col);
            _mm256_storeu_ps(o + kZ * plane, vand(hit, z));
            _mm256_storeu_ps(o + kPx * plane, vand(hit, px));
            _mm256_storeu_ps(o + kPy * plane, vand(hit, py));
            _mm256_storeu_ps(o + kPz * plane, vand(hit, pz));
            _mm256_storeu_ps(o + kNx * plane, nx);
            _mm256_storeu_ps(o + kNy * plane, ny);
            _mm256_storeu_ps(o + kNz * plane, nz);
            _mm256_storeu_ps(o + kHit * plane, vand(hit, ones));
            _mm256_storeu_ps(o + kNrm * plane, vand(nrm, ones));
        }
    }
}

}  // namespace

POSTHASTE_AVX2 void hatch_tile_avx2(const KernelCtx &k, const Rect &t)
{
    const Image &color = *k.color;
    const int w = color.width(), nc = color.channels();
    const Rect bounds = color.bounds();
    const Rect er = t.expand(k.line_reach);  // edge flags (zero outside the image)
    const Rect r = er.expand(1);             // samples
    const int stride = ((r.width() + 7) & ~7) + 8;
    const std::size_t plane = std::size_t(stride) * std::size_t(r.height());
    thread_local std::vector<float> tls_buf;
    tls_buf.resize(plane * kPlaneCount + 8);
    float *const buf = tls_buf.data();
    auto index = [&](int x, int y) {
        return std::size_t(y - r.y0) * std::size_t(stride) + std::size_t(x - r.x0);
    };
    const V zero = _mm256_setzero_ps(), ones = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const bool outlines = k.tap_count > 0;
    if (k.needs_samples) {
        fill_samples_avx2(k, r, stride, buf, plane);
    }
    float *const edges = buf + kEdge * plane;
    if (outlines) {
        std::fill(edges, edges + plane, 0.0f);
        const V cos_thr = v8::set1(k.cos_thr), dt = v8::set1(k.depth_threshold);
        const Rect eb = er.intersect(bounds);
        for (int y = eb.y0; y < eb.y1; ++y) {
            for (int x = eb.x0; x < eb.x1; x += 8) {
                const std::size_t i = index(x, y);
                const SampleV c = load_sample(buf, plane, i);
                if (_mm256_testz_ps(c.hit, c.hit)) {
                    continue;  // edges stay 0
                }
                const V dt_z = mul(dt, c.z);
                const V e = vor(
                    vor(is_edge_v(c, load_sample(buf, plane, i - 1), false, dt_z, cos_thr),
                        is_edge_v(c, load_sample(buf, plane, i + 1), true, dt_z, cos_thr)),
                    vor(is_edge_v(c, load_sample(buf, plane, i - stride), false, dt_z, cos_thr),
                        is_edge_v(c, load_sample(buf, plane, i + stride), true, dt_z, cos_thr)));
                const V in = _mm256_castsi256_ps(_mm256_cmpgt_epi32(
                    _mm256_set1_epi32(eb.x1 - x), lane));  // lanes inside the image and er
                _mm256_storeu_ps(edges + i, vand(vand(c.hit, in), vand(e, ones)));
            }
        }
    }

    const float *table = k.curve->table();
    const Tam &tam = *k.tam;
    const V paper[3] = {v8::set1(k.paper.x), v8::set1(k.paper.y), v8::set1(k.paper.z)};
    const V imp[3] = {v8::set1(k.ink_minus_paper.x),
                      v8::set1(k.ink_minus_paper.y),
                      v8::set1(k.ink_minus_paper.z)};
    const V oc[3] = {
        v8::set1(k.outline_color.x), v8::set1(k.outline_color.y), v8::set1(k.outline_color.z)};
    const V one = v8::set1(1.0f), mix = v8::set1(k.mix), exposure = v8::set1(k.exposure);
    alignas(32) float stage[4][8];
    for (int y = t.y0; y < t.y1; ++y) {
        for (int x = t.x0; x < t.x1; x += 8) {
            const int n = std::min(8, t.x1 - x);
            const float *src = color.pixel(x, y);
            V cr, cg, cb, ca;
            if (nc == 4 && n == 8) {
                load_rgba8(src, cr, cg, cb, ca);
            } else {
                for (int j = 0; j < 8; ++j) {
                    const float *s = color.pixel(std::min(x + j, w - 1), y);
                    stage[0][j] = s[0];
                    stage[1][j] = s[1];
                    stage[2][j] = s[2];
                    stage[3][j] = nc >= 4 ? s[3] : 1.0f;
                }
                cr = _mm256_load_ps(stage[0]);
                cg = _mm256_load_ps(stage[1]);
                cb = _mm256_load_ps(stage[2]);
                ca = _mm256_load_ps(stage[3]);
            }
            const std::size_t i = index(x, y);
            SampleV c;
            if (k.needs_samples) {
                c = load_sample(buf, plane, i);
            } else {
                c = SampleV{zero, zero, zero, zero, zero, zero, zero, zero, zero};
            }
            // Tone (ToneCurve::tone or the n.l variant); darkness 0 where nothing is drawn (the
            // sky in surface mode), and no tone at all for eight such pixels.
            const V drawn = k.screen_space ? ones : c.hit;
            V darkness = zero;
            if (!_mm256_testz_ps(drawn, drawn)) {
                V tone;
                if (k.tone_from_light) {
                    const V nl = _mm256_max_ps(dot3(c.nx,
                                                    c.ny,
                                                    c.nz,
                                                    v8::set1(k.light.x),
                                                    v8::set1(k.light.y),
                                                    v8::set1(k.light.z)),
                                               zero);
                    const V lit = select(c.nrm, nl, one);
                    tone = tone_curve_v(
                        table,
                        mul(add(v8::set1(k.ambient), mul(v8::set1(1.0f - k.ambient), lit)),
                            exposure));
                } else {
                    V lum = add(add(mul(v8::set1(0.2126f), cr), mul(v8::set1(0.7152f), cg)),
                                mul(v8::set1(0.0722f), cb));
                    const V part = vand(_mm256_cmp_ps(ca, v8::set1(1e-6f), _CMP_GT_OQ),
                                        _mm256_cmp_ps(ca, one, _CMP_LT_OQ));
                    lum = select(part, _mm256_div_ps(lum, ca), lum);
                    tone = tone_curve_v(table, mul(lum, exposure));
                }
                darkness = vand(drawn, sub(one, tone));
            }

            V ink;
            if (k.screen_space) {
                const V fx = _mm256_cvtepi32_ps(_mm256_add_epi32(_mm256_set1_epi32(x), lane));
                const V u = _mm256_div_ps(add(fx, v8::set1(0.5f)), v8::set1(k.finest));
                const V v =
                    _mm256_div_ps(add(v8::set1(float(y)), v8::set1(0.5f)), v8::set1(k.finest));
                ink = ramp_v(tam, ones, darkness, u, v, zero);
            } else if (_mm256_testz_ps(c.hit, c.hit)) {
                ink = zero;  // all sky: blank paper
            } else {
                V dxx, dxy, dxz, dyx, dyy, dyz;
                const V hx = pick_step_v(c,
                                         load_sample(buf, plane, i + 1),
                                         load_sample(buf, plane, i - 1),
                                         dxx,
                                         dxy,
                                         dxz);
                const V hy = pick_step_v(c,
                                         load_sample(buf, plane, i + stride),
                                         load_sample(buf, plane, i - stride),
                                         dyx,
                                         dyy,
                                         dyz);
                const V x_from_y = andnot(hy, hx), y_from_x = andnot(hx, hy);
                const V ux0 = dxx, uy0 = dxy, uz0 = dxz;
                dxx = select(x_from_y, dyx, dxx);
                dxy = select(x_from_y, dyy, dxy);
                dxz = select(x_from_y, dyz, dxz);
                dyx = select(y_from_x, ux0, dyx);
                dyy = select(y_from_x, uy0, dyy);
                dyz = select(y_from_x, uz0, dyz);
                const V footprint = vor(hx, hy);
                const V ax = vabs(c.nx), ay = vabs(c.ny), az = vabs(c.nz);
                const V flat = andnot(c.hit, c.nrm);  // no usable normal: flat mean tone
                const V flat_lod = v8::set1(k.flat_lod);
                if (k.triplanar) {
                    ink = triplanar_ink(k,
                                        c,
                                        flat,
                                        footprint,
                                        darkness,
                                        V3{{ax, ay, az}},
                                        V3{{dxx, dxy, dxz}},
                                        V3{{dyx, dyy, dyz}});
                } else {
                    // Dominant plane: 0 = (z, y), 1 = (x, z), 2 = (x, y).
                    const V p0 =
                        vand(_mm256_cmp_ps(ax, ay, _CMP_GE_OQ), _mm256_cmp_ps(ax, az, _CMP_GE_OQ));
                    const V p1 = andnot(_mm256_cmp_ps(ay, az, _CMP_GE_OQ), p0);
                    const V u = andnot(mul(select(p0, c.pz, c.px), v8::set1(k.inv_scale)), flat);
                    const V v = andnot(mul(select(p1, c.pz, c.py), v8::set1(k.inv_scale)), flat);
                    const V lod = plane_lod(k,
                                            select(p0, dxz, dxx),
                                            select(p1, dxz, dxy),
                                            select(p0, dyz, dyx),
                                            select(p1, dyz, dyy));
                    ink = ramp_v(tam,
                                 c.hit,
                                 darkness,
                                 u,
                                 v,
                                 select(vor(flat, andnot(ones, footprint)), flat_lod, lod));
                }
            }

            V line = zero;
            for (int j = 0; j < k.tap_count; ++j) {
                const LineTap &tap = k.taps[j];
                const V e = ld(edges + index(x + tap.dx, y + tap.dy));
                line = _mm256_max_ps(line, vand(e, v8::set1(tap.coverage)));
            }

            V alpha = nc >= 4 ? select(finite_v(ca), ca, one) : one;
            const V srcv[3] = {cr, cg, cb};
            V outv[3];
            // Id mask: lanes whose id is not listed keep their input pixel (all channels).
            alignas(32) std::int32_t keep_lane[8] = {};
            bool any_kept = false;
            if (k.ids) {
                for (int j = 0; j < n; ++j) {
                    const float id = k.id->at(x + j, y, 0);
                    const int key = std::isfinite(id) ? int(std::lround(id)) : -1;
                    const bool listed =
                        std::find(k.ids->begin(), k.ids->end(), key) != k.ids->end();
                    keep_lane[j] = listed ? 0 : -1;
                    any_kept = any_kept || !listed;
                }
            }
            const V keep =
                _mm256_castsi256_ps(_mm256_load_si256(reinterpret_cast<const VI *>(keep_lane)));
            for (int ch = 0; ch < 3; ++ch) {
                V val = add(paper[ch], mul(ink, imp[ch]));
                val = add(val, mul(line, sub(oc[ch], val)));
                val = mul(val, alpha);
                if (k.partial_mix) {
                    const V base = select(finite_v(srcv[ch]), srcv[ch], val);
                    val = add(base, mul(mix, sub(val, base)));
                }
                outv[ch] = select(keep, srcv[ch], val);
            }
            if (any_kept && nc >= 4) {
                alpha = select(keep, ca, alpha);
            }
            float *dst = k.out->pixel(x, y);
            if (nc == 4 && n == 8 && (reinterpret_cast<std::uintptr_t>(dst) & 15) == 0) {
                stream_rgba8(dst, outv[0], outv[1], outv[2], alpha);
            } else if (nc == 4 && n == 8) {
                store_rgba8(dst, outv[0], outv[1], outv[2], alpha);
            } else {
                _mm256_store_ps(stage[0], outv[0]);
                _mm256_store_ps(stage[1], outv[1]);
                _mm256_store_ps(stage[2], outv[2]);
                _mm256_store_ps(stage[3], alpha);
                for (int j = 0; j < n; ++j) {
                    float *d = dst + std::size_t(j) * std::size_t(nc);
                    const float *s = src + std::size_t(j) * std::size_t(nc);
                    if (keep_lane[j]) {
                        std::copy_n(s, nc, d);
                        continue;
                    }
                    d[0] = stage[0][j];
                    d[1] = stage[1][j];
                    d[2] = stage[2][j];
                    if (nc >= 4) {
                        d[3] = stage[3][j];
                        for (int ch = 4; ch < nc; ++ch) {
                            d[ch] = s[ch];
                        }
                    }
                }
            }
        }
    }
    _mm_sfence();  // order the streaming stores before the tile counts as done
}
#if defined(__GNUC__) && !defined(__clang__)
#if !defined(__clang__)
#pragma GCC pop_options
#endif
#endif
#endif

}  // namespace posthaste::shading::hatch_detail
