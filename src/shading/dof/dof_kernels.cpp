// The depth-of-field gather's group kernels over Highway (see dof_kernels.h and, for the
// method, dof_gather.cpp).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/dof/dof_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "shading/dof/dof_kernels.h"

#include <algorithm>
#include <cmath>
#include <limits>

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::dof::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// A group's lanes in pieces of at most eight (one piece on AVX2 and AVX-512, two on SSE4).
using D8 = hn::CappedTag<float, kLanes>;

template <class V>
HWY_INLINE V Clamp01(V v)
{
    const hn::DFromV<V> d;
    return hn::Min(hn::Max(v, hn::Zero(d)), hn::Set(d, 1.0f));
}

// The lanes of a plane at columns col .. col + L - 1 of a row: one load inside the image, a
// gather of the edge-clamped columns across its border.
template <class D>
HWY_INLINE hn::Vec<D> LoadCols(D d, const float *row, int col, int w)
{
    if (col >= 0 && col + int(hn::Lanes(d)) <= w) {
        return hn::LoadU(d, row + col);
    }
    const hn::RebindToSigned<D> di;
    const auto cols = hn::Min(hn::Max(hn::Add(hn::Iota(di, 0), hn::Set(di, col)), hn::Zero(di)),
                              hn::Set(di, w - 1));
    return hn::GatherIndex(d, row, cols);
}

void SetupGroup(const PlanesView &lv, int x0, int y, int count, Group &g)
{
    const int w = lv.width;
    if (count < kLanes) {
        // A row's last, partial group: lane by lane (rare).
        for (int j = 0; j < kLanes; ++j) {
            const std::size_t ip =
                std::size_t(y) * std::size_t(w) + std::size_t(std::min(x0 + j, w - 1));
            const float cp = lv.coc[ip];
            g.cp[j] = cp;
            g.acp[j] = std::fabs(cp);
            g.w_self[j] = std::min(lv.inv2[ip], 1.0f);
            const float wf = cp < -0.5f ? g.w_self[j] : 0.0f, wb = g.w_self[j] - wf;
            for (int k = 0; k < 4; ++k) {
                const float v = lv.ch[k][ip];
                g.front[k][j] = v * wf;
                g.back[k][j] = v * wb;
            }
            g.front_w[j] = wf;
            g.back_w[j] = wb;
            g.near_w[j] = 0.0f;
        }
        return;
    }
    const D8 d;
    const std::size_t ip = std::size_t(y) * std::size_t(w) + std::size_t(x0);
    for (int o = 0; o < kLanes; o += int(hn::Lanes(d))) {
        const auto cp = hn::LoadU(d, lv.coc + ip + o);
        const auto ws = hn::Min(hn::LoadU(d, lv.inv2 + ip + o), hn::Set(d, 1.0f));
        const auto wf = hn::IfThenElseZero(hn::Lt(cp, hn::Set(d, -0.5f)), ws);
        const auto wb = hn::Sub(ws, wf);
        hn::StoreU(cp, d, g.cp + o);
        hn::StoreU(hn::Abs(cp), d, g.acp + o);
        hn::StoreU(ws, d, g.w_self + o);
        for (int k = 0; k < 4; ++k) {
            const auto v = hn::LoadU(d, lv.ch[k] + ip + o);
            hn::StoreU(hn::Mul(v, wf), d, g.front[k] + o);
            hn::StoreU(hn::Mul(v, wb), d, g.back[k] + o);
        }
        hn::StoreU(wf, d, g.front_w + o);
        hn::StoreU(wb, d, g.back_w + o);
        hn::StoreU(hn::Zero(d), d, g.near_w + o);
    }
}

void NearPass(const PlanesView &lv, int x0, int y, const Tap *taps, int n, Group &g)
{
    const D8 d;
    const int w = lv.width, h = lv.height;
    const auto lim = hn::Set(d, -0.5f);
    for (int o = 0; o < kLanes; o += int(hn::Lanes(d))) {
        const auto cp1 = hn::Add(hn::LoadU(d, g.cp + o), hn::Set(d, 1.0f));
        auto f0 = hn::LoadU(d, g.front[0] + o), f1 = hn::LoadU(d, g.front[1] + o);
        auto f2 = hn::LoadU(d, g.front[2] + o), f3 = hn::LoadU(d, g.front[3] + o);
        auto fw = hn::LoadU(d, g.front_w + o), nw = hn::LoadU(d, g.near_w + o);
        for (int i = 0; i < n; ++i) {
            const std::size_t row =
                std::size_t(std::clamp(y + taps[i].dy, 0, h - 1)) * std::size_t(w);
            const int col = x0 + taps[i].dx + o;
            const auto cq = LoadCols(d, lv.coc + row, col, w);
            const auto front = hn::And(hn::Lt(cq, lim), hn::Le(cq, cp1));
            if (hn::AllFalse(d, front)) {
                continue;
            }
            // clamp(rim - c_q, 0, 1) / c_q^2 on the near-field lanes only.
            const auto cov = Clamp01(hn::Sub(hn::Set(d, taps[i].rim), cq));
            const auto wgt =
                hn::IfThenElseZero(front, hn::Mul(cov, LoadCols(d, lv.inv2 + row, col, w)));
            f0 = hn::MulAdd(LoadCols(d, lv.ch[0] + row, col, w), wgt, f0);
            f1 = hn::MulAdd(LoadCols(d, lv.ch[1] + row, col, w), wgt, f1);
            f2 = hn::MulAdd(LoadCols(d, lv.ch[2] + row, col, w), wgt, f2);
            f3 = hn::MulAdd(LoadCols(d, lv.ch[3] + row, col, w), wgt, f3);
            fw = hn::Add(fw, wgt);
            nw = hn::Add(nw, wgt);
        }
        hn::StoreU(f0, d, g.front[0] + o);
        hn::StoreU(f1, d, g.front[1] + o);
        hn::StoreU(f2, d, g.front[2] + o);
        hn::StoreU(f3, d, g.front[3] + o);
        hn::StoreU(fw, d, g.front_w + o);
        hn::StoreU(nw, d, g.near_w + o);
    }
}

// One background tap of a piece; Inside: its columns are in the image (idx is the first lane's
// element), else edge-clamped from column col of the row at idx.
template <bool Inside, class V>
HWY_INLINE void BackTap(const PlanesView &lv,
                        std::size_t idx,
                        int col,
                        float rim,
                        V cp1,
                        V acp,
                        V lo,
                        V hi,
                        V ws,
                        V (&c)[4],
                        V &sw)
{
    const hn::DFromV<V> d;
    const auto load = [&](const float *plane) {
        if constexpr (Inside) {
            return hn::LoadU(d, plane + idx);
        } else {
            return LoadCols(d, plane + idx, col, lv.width);
        }
    };
    const V cq = load(lv.coc);
    const auto front = hn::And(hn::Lt(cq, hn::Set(d, -0.5f)), hn::Le(cq, cp1));
    const V r = hn::Min(hn::Max(hn::Abs(cq), lo), acp);
    const V inv_area = hn::Max(hn::Min(load(lv.inv2), hi), ws);
    const V cov = Clamp01(hn::Add(r, hn::Set(d, rim)));
    const V wgt = hn::IfThenZeroElse(front, hn::Mul(cov, inv_area));
    for (int k = 0; k < 4; ++k) {
        c[k] = hn::MulAdd(load(lv.ch[k]), wgt, c[k]);
    }
    sw = hn::Add(sw, wgt);
}

void BackPass(const PlanesView &lv,
              int x0,
              int y,
              const Tap *taps,
              const std::ptrdiff_t *offsets,
              int n,
              int reach,
              unsigned lanes,
              Group &g)
{
    // Each lane's lo, hi and self weight (see back_pass in dof_kernels.h).
    float lo_p[kLanes], hi_p[kLanes], ws_p[kLanes];
    for (int j = 0; j < kLanes; ++j) {
        const bool on = (lanes >> j) & 1u, p_near = g.cp[j] < -0.5f;
        lo_p[j] = p_near ? g.acp[j] : 0.0f;
        hi_p[j] = on && !p_near ? 1.0f : 0.0f;
        ws_p[j] = on ? g.w_self[j] : 0.0f;
    }
    const D8 d;
    using V = hn::Vec<D8>;
    const int w = lv.width, h = lv.height;
    const bool all_inside =
        x0 - reach >= 0 && x0 + reach + kLanes <= w && y - reach >= 0 && y + reach < h;
    for (int o = 0; o < kLanes; o += int(hn::Lanes(d))) {
        const V cp1 = hn::Add(hn::LoadU(d, g.cp + o), hn::Set(d, 1.0f));
        const V acp = hn::LoadU(d, g.acp + o);
        const V lo = hn::LoadU(d, lo_p + o), hi = hn::LoadU(d, hi_p + o);
        const V ws = hn::LoadU(d, ws_p + o);
        V c[4];
        for (int k = 0; k < 4; ++k) {
            c[k] = hn::LoadU(d, g.back[k] + o);
        }
        V sw = hn::LoadU(d, g.back_w + o);
        if (all_inside) {
            // The whole reach inside the image: each tap is its precomputed offset.
            const std::ptrdiff_t base = std::ptrdiff_t(y) * w + x0 + o;
            for (int i = 0; i < n; ++i) {
                BackTap<true>(lv,
                              std::size_t(base + offsets[i]),
                              0,
                              taps[i].rim,
                              cp1,
                              acp,
                              lo,
                              hi,
                              ws,
                              c,
                              sw);
            }
        } else {
            for (int i = 0; i < n; ++i) {
                const std::size_t row =
                    std::size_t(std::clamp(y + taps[i].dy, 0, h - 1)) * std::size_t(w);
                const int col = x0 + taps[i].dx + o;
                if (col >= 0 && col + int(hn::Lanes(d)) <= w) {
                    BackTap<true>(
                        lv, row + std::size_t(col), 0, taps[i].rim, cp1, acp, lo, hi, ws, c, sw);
                } else {
                    BackTap<false>(lv, row, col, taps[i].rim, cp1, acp, lo, hi, ws, c, sw);
                }
            }
        }
        for (int k = 0; k < 4; ++k) {
            hn::StoreU(c[k], d, g.back[k] + o);
        }
        hn::StoreU(sw, d, g.back_w + o);
    }
}

void CompositeGroup(const Group &g, float sample_area, float (*out)[kLanes])
{
    const D8 d;
    const auto zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    for (int o = 0; o < kLanes; o += int(hn::Lanes(d))) {
        const auto fw = hn::LoadU(d, g.front_w + o), bw = hn::LoadU(d, g.back_w + o);
        const auto has_front = hn::Gt(fw, zero), has_back = hn::Gt(bw, zero);
        const auto inv_f = hn::Div(one, fw), inv_b = hn::Div(one, bw);
        auto alpha = hn::IfThenElseZero(
            has_front, hn::Min(hn::Mul(hn::LoadU(d, g.near_w + o), hn::Set(d, sample_area)), one));
        alpha = hn::IfThenElse(has_back, alpha, one);
        const auto keep = hn::Sub(one, alpha);
        for (int k = 0; k < 4; ++k) {
            const auto front =
                hn::IfThenElseZero(has_front, hn::Mul(hn::LoadU(d, g.front[k] + o), inv_f));
            const auto back =
                hn::IfThenElse(has_back, hn::Mul(hn::LoadU(d, g.back[k] + o), inv_b), front);
            hn::StoreU(hn::Add(hn::Mul(back, keep), hn::Mul(front, alpha)), d, out[k] + o);
        }
    }
}

// Non-finite colour (NaN, +-Inf) reads as 0: spreading an Inf, or even the largest half, over a
// disc would turn one bad pixel into a bright blot.
HWY_INLINE float Sanitize(float v)
{
    return std::fabs(v) <= std::numeric_limits<float>::max() ? v : 0.0f;
}

void SplitRow(const float *src, int nc, int x0, int x1, float *const *plane)
{
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    int x = x0;
    if (nc == 4) {
        const auto big = hn::Set(d, std::numeric_limits<float>::max());
        for (; x + lanes <= x1; x += lanes) {
            hn::Vec<decltype(d)> c[4];
            hn::LoadInterleaved4(d, src + std::size_t(x) * 4, c[0], c[1], c[2], c[3]);
            for (int k = 0; k < 4; ++k) {
                // Non-finite values (NaN fails the compare) as 0.
                hn::StoreU(hn::IfThenElseZero(hn::Le(hn::Abs(c[k]), big), c[k]), d, plane[k] + x);
            }
        }
    }
    for (; x < x1; ++x) {
        for (int k = 0; k < 4; ++k) {
            plane[k][x] =
                k < nc ? Sanitize(src[std::size_t(x) * std::size_t(nc) + std::size_t(k)]) : 0.0f;
        }
    }
}

void MergeRow(const float (*v)[kLanes], int count, int nc, float *dst)
{
    if (nc == 4 && count == kLanes) {
        const D8 d;
        for (int o = 0; o < kLanes; o += int(hn::Lanes(d))) {
            hn::StoreInterleaved4(hn::LoadU(d, v[0] + o),
                                  hn::LoadU(d, v[1] + o),
                                  hn::LoadU(d, v[2] + o),
                                  hn::LoadU(d, v[3] + o),
                                  d,
                                  dst + 4 * o);
        }
        return;
    }
    for (int j = 0; j < count; ++j) {
        for (int k = 0; k < nc; ++k) {  // nc <= 4
            dst[j * nc + k] = v[k][j];
        }
    }
}

}  // namespace posthaste::shading::dof::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading::dof {

HWY_EXPORT(SetupGroup);
HWY_EXPORT(NearPass);
HWY_EXPORT(BackPass);
HWY_EXPORT(CompositeGroup);
HWY_EXPORT(SplitRow);
HWY_EXPORT(MergeRow);

void setup_group(const PlanesView &lv, int x0, int y, int count, Group &g)
{
    HWY_DYNAMIC_DISPATCH(SetupGroup)(lv, x0, y, count, g);
}

void near_pass(const PlanesView &lv, int x0, int y, const Tap *taps, int n, Group &g)
{
    HWY_DYNAMIC_DISPATCH(NearPass)(lv, x0, y, taps, n, g);
}

void back_pass(const PlanesView &lv,
               int x0,
               int y,
               const Tap *taps,
               const std::ptrdiff_t *offsets,
               int n,
               int reach,
               unsigned lanes,
               Group &g)
{
    HWY_DYNAMIC_DISPATCH(BackPass)(lv, x0, y, taps, offsets, n, reach, lanes, g);
}

void composite_group(const Group &g, float sample_area, float (*out)[kLanes])
{
    HWY_DYNAMIC_DISPATCH(CompositeGroup)(g, sample_area, out);
}

void split_row(const float *src, int nc, int x0, int x1, float *const *plane)
{
    HWY_DYNAMIC_DISPATCH(SplitRow)(src, nc, x0, x1, plane);
}

void merge_row(const float (*v)[kLanes], int count, int nc, float *dst)
{
    HWY_DYNAMIC_DISPATCH(MergeRow)(v, count, nc, dst);
}

}  // namespace posthaste::shading::dof
#endif
