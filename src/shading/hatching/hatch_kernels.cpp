// The hatching kernel's tiles, written once over Highway's lane types (hatch_kernel.h): compiled
// for each x86 target and for the portable one-lane target that tests compare them with, and
// dispatched at run time. shading/hatching/hatch.cpp sets up the frame and calls hatch_tile per tile.

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/hatching/hatch_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "shading/hatching/hatch_lanes-inl.h"
// clang-format on

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "shading/hatching/hatch_kernel.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::hatch_detail::HWY_NAMESPACE {

/// Fills the sample planes of region r (stride `stride`, r.height() rows) from the passes.
void FillSamples(const KernelCtx &k, const Rect &r, int stride, float *buf, std::size_t plane)
{
    const D d;
    const DI di;
    const int n = int(hn::Lanes(d));
    const int w = k.color->width(), h = k.color->height();
    const int zs = k.depth->channels(), ps = k.position->channels(), ns = k.normal->channels();
    const VI lane = hn::Iota(di, 0);
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), tiny = hn::Set(d, 1e-4f);
    for (int row = 0; row < r.height(); ++row) {
        const int y = std::clamp(r.y0 + row, 0, h - 1);
        const float *zr = k.depth->pixel(0, y), *pr = k.position->pixel(0, y);
        const float *nr = k.normal->pixel(0, y);
        for (int col = 0; col < stride; col += n) {
            const int x = r.x0 + col;
            V z, px, py, pz, nx, ny, nz;
            if (x >= 0 && x + n <= w && zs == 1 && ps == 3 && ns == 3) {
                z = hn::LoadU(d, zr + x);
                LoadXyz(d, pr + 3 * std::size_t(x), px, py, pz);
                LoadXyz(d, nr + 3 * std::size_t(x), nx, ny, nz);
            } else {  // the image's borders (clamped) and passes of other channel counts
                const VI xi = hn::Min(hn::Max(hn::Add(hn::Set(di, x), lane), hn::Zero(di)),
                                      hn::Set(di, w - 1));
                const VI zi = hn::Mul(xi, hn::Set(di, zs));
                const VI pi = hn::Mul(xi, hn::Set(di, ps)), ni = hn::Mul(xi, hn::Set(di, ns));
                const VI c1 = hn::Set(di, 1), c2 = hn::Set(di, 2);
                z = hn::GatherIndex(d, zr, zi);
                px = hn::GatherIndex(d, pr, pi);
                py = hn::GatherIndex(d, pr, hn::Add(pi, c1));
                pz = hn::GatherIndex(d, pr, hn::Add(pi, c2));
                nx = hn::GatherIndex(d, nr, ni);
                ny = hn::GatherIndex(d, nr, hn::Add(ni, c1));
                nz = hn::GatherIndex(d, nr, hn::Add(ni, c2));
            }
            // hit = finite positive depth and finite position.
            const M hit =
                hn::And(hn::And(hn::Gt(z, zero), Finite(z)), Finite(hn::Add(hn::Add(px, py), pz)));
            const V len2 = Dot3Unfused(nx, ny, nz, nx, ny, nz);
            const M nrm = hn::And(hn::And(hit, hn::Gt(len2, tiny)), Finite(len2));
            const M unit = hn::Lt(hn::Abs(hn::Sub(len2, one)), tiny);
            if (!hn::AllFalse(d, hn::AndNot(unit, nrm))) {  // rendered normals are unit already
                const V root = hn::Sqrt(len2);
                nx = hn::IfThenElse(unit, nx, hn::Div(nx, root));
                ny = hn::IfThenElse(unit, ny, hn::Div(ny, root));
                nz = hn::IfThenElse(unit, nz, hn::Div(nz, root));
            }
            float *o = buf + std::size_t(row) * std::size_t(stride) + std::size_t(col);
            hn::StoreU(hn::IfThenElseZero(hit, z), d, o + kZ * plane);
            hn::StoreU(hn::IfThenElseZero(hit, px), d, o + kPx * plane);
            hn::StoreU(hn::IfThenElseZero(hit, py), d, o + kPy * plane);
            hn::StoreU(hn::IfThenElseZero(hit, pz), d, o + kPz * plane);
            hn::StoreU(hn::IfThenElseZero(nrm, nx), d, o + kNx * plane);
            hn::StoreU(hn::IfThenElseZero(nrm, ny), d, o + kNy * plane);
            hn::StoreU(hn::IfThenElseZero(nrm, nz), d, o + kNz * plane);
            hn::StoreU(hn::VecFromMask(d, hit), d, o + kHit * plane);
            hn::StoreU(hn::VecFromMask(d, nrm), d, o + kNrm * plane);
        }
    }
}

/// Ink darkness of the surface lanes (the TAM ramp at the pixel's footprint), face-plane or
/// triplanar; 0 on the sky.
HWY_INLINE V SurfaceInk(const KernelCtx &k,
                        const float *buf,
                        std::size_t plane,
                        std::size_t i,
                        std::size_t stride,
                        const SampleV &c,
                        V darkness)
{
    const D d;
    V dxx, dxy, dxz, dyx, dyy, dyz;
    const M hx =
        PickStepV(c, LoadSample(buf, plane, i + 1), LoadSample(buf, plane, i - 1), dxx, dxy, dxz);
    const M hy = PickStepV(
        c, LoadSample(buf, plane, i + stride), LoadSample(buf, plane, i - stride), dyx, dyy, dyz);
    // A missing step takes the other direction's.
    const M x_from_y = hn::AndNot(hx, hy), y_from_x = hn::AndNot(hy, hx);
    const V ux0 = dxx, uy0 = dxy, uz0 = dxz;
    dxx = hn::IfThenElse(x_from_y, dyx, dxx);
    dxy = hn::IfThenElse(x_from_y, dyy, dxy);
    dxz = hn::IfThenElse(x_from_y, dyz, dxz);
    dyx = hn::IfThenElse(y_from_x, ux0, dyx);
    dyy = hn::IfThenElse(y_from_x, uy0, dyy);
    dyz = hn::IfThenElse(y_from_x, uz0, dyz);
    const M footprint = hn::Or(hx, hy);
    const V ax = hn::Abs(c.nx), ay = hn::Abs(c.ny), az = hn::Abs(c.nz);
    const M flat = hn::AndNot(c.nrm, c.hit);  // no usable normal: the flat mean tone
    if (k.triplanar) {
        return TriplanarInk(k,
                            c,
                            flat,
                            footprint,
                            darkness,
                            V3{{ax, ay, az}},
                            V3{{dxx, dxy, dxz}},
                            V3{{dyx, dyy, dyz}});
    }
    // The dominant plane: 0 = (z, y), 1 = (x, z), 2 = (x, y).
    const M p0 = hn::And(hn::Ge(ax, ay), hn::Ge(ax, az));
    const M p1 = hn::AndNot(p0, hn::Ge(ay, az));
    const V inv_scale = hn::Set(d, k.inv_scale);
    const V u = hn::IfThenZeroElse(flat, hn::Mul(hn::IfThenElse(p0, c.pz, c.px), inv_scale));
    const V v = hn::IfThenZeroElse(flat, hn::Mul(hn::IfThenElse(p1, c.pz, c.py), inv_scale));
    const V lod = PlaneLod(k,
                           hn::IfThenElse(p0, dxz, dxx),
                           hn::IfThenElse(p1, dxz, dxy),
                           hn::IfThenElse(p0, dyz, dyx),
                           hn::IfThenElse(p1, dyz, dyy));
    const M use_lod = hn::AndNot(flat, footprint);
    return RampV(
        *k.tam, c.hit, darkness, u, v, hn::IfThenElse(use_lod, lod, hn::Set(d, k.flat_lod)));
}

void HatchTile(const KernelCtx &k, const Rect &t)
{
    const D d;
    const DI di;
    const int n_lanes = int(hn::Lanes(d));
    const Image &color = *k.color;
    const int w = color.width(), nc = color.channels();
    const Rect er = t.expand(k.line_reach);  // edge flags (zero outside the image)
    const Rect r = er.expand(1);             // samples
    const int stride = (r.width() + n_lanes - 1) / n_lanes * n_lanes + n_lanes;
    const std::size_t plane = std::size_t(stride) * std::size_t(r.height());
    thread_local std::vector<float> tls_buf;
    tls_buf.resize(plane * kPlaneCount + std::size_t(n_lanes));
    float *const buf = tls_buf.data();
    auto index = [&](int x, int y) {
        return std::size_t(y - r.y0) * std::size_t(stride) + std::size_t(x - r.x0);
    };
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const VI lane = hn::Iota(di, 0);
    if (k.needs_samples) {
        FillSamples(k, r, stride, buf, plane);
    }
    float *const edges = buf + kEdge * plane;
    if (k.tap_count > 0) {
        std::fill(edges, edges + plane, 0.0f);
        const V cos_thr = hn::Set(d, k.cos_thr), dt = hn::Set(d, k.depth_threshold);
        const Rect eb = er.intersect(color.bounds());
        for (int y = eb.y0; y < eb.y1; ++y) {
            for (int x = eb.x0; x < eb.x1; x += n_lanes) {
                const std::size_t i = index(x, y);
                const SampleV c = LoadSample(buf, plane, i);
                if (hn::AllFalse(d, c.hit)) {
                    continue;  // edges stay 0
                }
                const V dt_z = hn::Mul(dt, c.z);
                const M e = hn::Or(
                    hn::Or(IsEdgeV(c, LoadSample(buf, plane, i - 1), false, dt_z, cos_thr),
                           IsEdgeV(c, LoadSample(buf, plane, i + 1), true, dt_z, cos_thr)),
                    hn::Or(IsEdgeV(c, LoadSample(buf, plane, i - stride), false, dt_z, cos_thr),
                           IsEdgeV(c, LoadSample(buf, plane, i + stride), true, dt_z, cos_thr)));
                // Lanes inside the image and er only.
                const M in = hn::RebindMask(d, hn::Gt(hn::Set(di, eb.x1 - x), lane));
                hn::StoreU(hn::VecFromMask(d, hn::And(hn::And(c.hit, in), e)), d, edges + i);
            }
        }
    }

    const float *table = k.curve->table();
    const Tam &tam = *k.tam;
    const V paper[3] = {hn::Set(d, k.paper.x), hn::Set(d, k.paper.y), hn::Set(d, k.paper.z)};
    const V imp[3] = {hn::Set(d, k.ink_minus_paper.x),
                      hn::Set(d, k.ink_minus_paper.y),
                      hn::Set(d, k.ink_minus_paper.z)};
    const V oc[3] = {hn::Set(d, k.outline_color.x),
                     hn::Set(d, k.outline_color.y),
                     hn::Set(d, k.outline_color.z)};
    const V mix = hn::Set(d, k.mix), exposure = hn::Set(d, k.exposure);
    // The line taps as offsets in the tile's edge plane, once per tile: the loop over them runs
    // for every vector of pixels.
    thread_local std::vector<std::ptrdiff_t> tls_tap_offsets;
    tls_tap_offsets.resize(std::size_t(std::max(k.tap_count, 0)));
    for (int j = 0; j < k.tap_count; ++j) {
        tls_tap_offsets[std::size_t(j)] =
            std::ptrdiff_t(k.taps[j].dy) * stride + std::ptrdiff_t(k.taps[j].dx);
    }
    const std::ptrdiff_t *const tap_offsets = tls_tap_offsets.data();
    HWY_ALIGN float stage[4][kMaxLanes];
    HWY_ALIGN std::int32_t keep_lane[kMaxLanes];
    for (int y = t.y0; y < t.y1; ++y) {
        for (int x = t.x0; x < t.x1; x += n_lanes) {
            const int n = std::min(n_lanes, t.x1 - x);
            const float *src = color.pixel(x, y);
            V cr, cg, cb, ca;
            if (nc == 4 && n == n_lanes) {
                hn::LoadInterleaved4(d, src, cr, cg, cb, ca);
            } else {
                for (int j = 0; j < n_lanes; ++j) {
                    const float *s = color.pixel(std::min(x + j, w - 1), y);
                    stage[0][j] = s[0];
                    stage[1][j] = s[1];
                    stage[2][j] = s[2];
                    stage[3][j] = nc >= 4 ? s[3] : 1.0f;
                }
                cr = hn::Load(d, stage[0]);
                cg = hn::Load(d, stage[1]);
                cb = hn::Load(d, stage[2]);
                ca = hn::Load(d, stage[3]);
            }
            const std::size_t i = index(x, y);
            const M none = hn::FirstN(d, 0);
            const SampleV c = k.needs_samples
                                  ? LoadSample(buf, plane, i)
                                  : SampleV{zero, zero, zero, zero, zero, zero, zero, none, none};
            // Tone (ToneCurve::tone or the n.l variant); darkness 0 where nothing is drawn (the
            // sky in surface mode), and no tone at all for a vector of such pixels.
            const M drawn = k.screen_space ? hn::FirstN(d, std::size_t(n_lanes)) : c.hit;
            V darkness = zero;
            if (!hn::AllFalse(d, drawn)) {
                V tone;
                if (k.tone_from_light) {
                    const V nl = hn::Max(Dot3Unfused(c.nx,
                                                     c.ny,
                                                     c.nz,
                                                     hn::Set(d, k.light.x),
                                                     hn::Set(d, k.light.y),
                                                     hn::Set(d, k.light.z)),
                                         zero);
                    const V lit = hn::IfThenElse(c.nrm, nl, one);
                    tone = ToneCurveV(table,
                                      hn::Mul(hn::Add(hn::Set(d, k.ambient),
                                                      hn::Mul(hn::Set(d, 1.0f - k.ambient), lit)),
                                              exposure));
                } else {
                    V lum = hn::Add(
                        hn::Add(hn::Mul(hn::Set(d, 0.2126f), cr), hn::Mul(hn::Set(d, 0.7152f), cg)),
                        hn::Mul(hn::Set(d, 0.0722f), cb));
                    // The tone of the surface, not of its coverage.
                    const M part = hn::And(hn::Gt(ca, hn::Set(d, 1e-6f)), hn::Lt(ca, one));
                    lum = hn::IfThenElse(part, hn::Div(lum, ca), lum);
                    tone = ToneCurveV(table, hn::Mul(lum, exposure));
                }
                darkness = hn::IfThenElseZero(drawn, hn::Sub(one, tone));
            }

            V ink;
            if (k.screen_space) {
                const V fx = hn::ConvertTo(d, hn::Add(hn::Set(di, x), lane));
                const V finest = hn::Set(d, k.finest), half = hn::Set(d, 0.5f);
                const V u = hn::Div(hn::Add(fx, half), finest);
                const V v = hn::Div(hn::Add(hn::Set(d, float(y)), half), finest);
                ink = RampV(tam, hn::FirstN(d, std::size_t(n_lanes)), darkness, u, v, zero);
            } else if (hn::AllFalse(d, c.hit)) {
                ink = zero;  // all sky: blank paper
            } else {
                ink = SurfaceInk(k, buf, plane, i, std::size_t(stride), c, darkness);
            }

            V line = zero;
            const float *const edge_at = edges + i;
            for (int j = 0; j < k.tap_count; ++j) {
                const V e = hn::LoadU(d, edge_at + tap_offsets[j]);
                line = hn::Max(line, hn::And(e, hn::Set(d, k.taps[j].coverage)));
            }

            V alpha = nc >= 4 ? hn::IfThenElse(Finite(ca), ca, one) : one;
            const V srcv[3] = {cr, cg, cb};
            V outv[3];
            // Id mask: lanes whose id is not listed keep their input pixel (all channels).
            bool any_kept = false;
            if (k.ids) {
                for (int j = 0; j < n_lanes; ++j) {
                    keep_lane[j] = 0;
                    if (j >= n) {
                        continue;
                    }
                    const float id = k.id->at(x + j, y, 0);
                    const int key = std::isfinite(id) ? int(std::lround(id)) : -1;
                    const bool listed =
                        std::find(k.ids->begin(), k.ids->end(), key) != k.ids->end();
                    keep_lane[j] = listed ? 0 : -1;
                    any_kept = any_kept || !listed;
                }
            }
            const M keep = k.ids ? hn::RebindMask(d, hn::Lt(hn::Load(di, keep_lane), hn::Zero(di)))
                                 : hn::FirstN(d, 0);
            for (int ch = 0; ch < 3; ++ch) {
                V val = hn::Add(paper[ch], hn::Mul(ink, imp[ch]));
                val = hn::Add(val, hn::Mul(line, hn::Sub(oc[ch], val)));
                val = hn::Mul(val, alpha);
                if (k.partial_mix) {
                    const V base = hn::IfThenElse(Finite(srcv[ch]), srcv[ch], val);
                    val = hn::Add(base, hn::Mul(mix, hn::Sub(val, base)));
                }
                outv[ch] = hn::IfThenElse(keep, srcv[ch], val);
            }
            if (any_kept && nc >= 4) {
                alpha = hn::IfThenElse(keep, ca, alpha);
            }
            float *dst = k.out->pixel(x, y);
            if (nc == 4 && n == n_lanes) {
                StoreRgba(outv[0], outv[1], outv[2], alpha, dst);
            } else {
                hn::Store(outv[0], d, stage[0]);
                hn::Store(outv[1], d, stage[1]);
                hn::Store(outv[2], d, stage[2]);
                hn::Store(alpha, d, stage[3]);
                for (int j = 0; j < n; ++j) {
                    float *o = dst + std::size_t(j) * std::size_t(nc);
                    const float *s = src + std::size_t(j) * std::size_t(nc);
                    if (k.ids && keep_lane[j]) {
                        std::copy_n(s, nc, o);
                        continue;
                    }
                    o[0] = stage[0][j];
                    o[1] = stage[1][j];
                    o[2] = stage[2][j];
                    if (nc >= 4) {
                        o[3] = stage[3][j];
                        std::copy(s + 4, s + nc, o + 4);
                    }
                }
            }
        }
    }
    hwy::FlushStream();  // order StoreRgba's streaming stores before the tile counts as done
}

}  // namespace posthaste::shading::hatch_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading::hatch_detail {

HWY_EXPORT(HatchTile);

void hatch_tile(const KernelCtx &k, const Rect &t)
{
    HWY_DYNAMIC_DISPATCH(HatchTile)(k, t);
}

}  // namespace posthaste::shading::hatch_detail
#endif
