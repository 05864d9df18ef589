// The height fog's row kernels over Highway (see height_fog_kernels.h and, for the model,
// height_fog.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/fog/height_fog_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "core/hwy_math-inl.h"
// clang-format on

#include "shading/fog/height_fog_kernels.h"

#include <limits>

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
namespace sm = posthaste::simd::HWY_NAMESPACE;

constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// Transmittance and inscatter of one vector of pixels starting at x; `bad` gets the lanes the
/// exact path must take.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void FogVector(
    D d, const FogRowParams &p, V depth, float x, V &tr, V &ir, V &ig, V &ib, hn::Mask<D> &bad)
{
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    const V u = hn::Mul(hn::Add(hn::Set(d, x + 0.5f), hn::Iota(d, 0.0f)), hn::Set(d, p.inv_w));
    const V rx = hn::MulAdd(u, hn::Set(d, p.du[0]), hn::Set(d, p.origin[0]));
    const V ry = hn::MulAdd(u, hn::Set(d, p.du[1]), hn::Set(d, p.origin[1]));
    const V rz = hn::MulAdd(u, hn::Set(d, p.du[2]), hn::Set(d, p.origin[2]));
    const V len = hn::Sqrt(sm::Dot3(rx, ry, rz, rx, ry, rz));
    const V b = hn::Set(d, p.falloff), a = hn::Set(d, p.density);
    // k * distance = b (ray_y / len) (depth len) = b ray_y depth; the optical depth is
    // a distance (1 - e^-x) / x, by its series near x = 0 (one_minus_exp_over_x).
    const V xk = hn::Mul(b, hn::Mul(ry, depth));
    const V series = hn::NegMulAdd(
        xk,
        hn::NegMulAdd(xk,
                      hn::NegMulAdd(xk, hn::Set(d, 1.0f / 24.0f), hn::Set(d, 1.0f / 6.0f)),
                      hn::Set(d, 0.5f)),
        one);
    const V safe_x = hn::IfThenElse(hn::Eq(xk, zero), one, xk);
    const V direct = hn::Div(hn::Sub(one, sm::FastExp(d, hn::Neg(xk))), safe_x);
    const V g = hn::IfThenElse(hn::Lt(hn::Abs(xk), hn::Set(d, 0.03f)), series, direct);
    const auto finite = hn::And(hn::Gt(depth, zero), hn::Lt(depth, inf));
    // Infinite depth: a / k looking up (k = b ray_y / len > 0), everything absorbed otherwise.
    const V k = hn::Div(hn::Mul(b, ry), len);
    const V tau_up = hn::Div(a, hn::Max(k, hn::Set(d, 1e-30f)));
    const V tau_inf = p.opaque_sky ? hn::Set(d, 1e30f)
                                   : hn::IfThenElse(hn::Gt(k, zero), tau_up, hn::Set(d, 1e30f));
    const V tau_finite = hn::Mul(hn::Mul(a, hn::Mul(depth, len)), g);
    // Depth <= 0 or NaN: no fog (tau = 0).
    const V tau =
        hn::IfThenElse(finite, tau_finite, hn::IfThenElseZero(hn::Eq(depth, inf), tau_inf));
    tr = sm::FastExp(d, hn::Neg(tau));
    V lobe = zero;
    if (p.has_lobe) {
        const V dot =
            sm::Dot3(rx, ry, rz, hn::Set(d, p.sun[0]), hn::Set(d, p.sun[1]), hn::Set(d, p.sun[2]));
        const V dd =
            hn::Max(hn::NegMulAdd(hn::Set(d, p.lobe_b), hn::Div(dot, len), hn::Set(d, p.lobe_a)),
                    hn::Set(d, 1e-6f));
        lobe = hn::Div(one, hn::Mul(dd, hn::Sqrt(dd)));
    }
    const V omt = hn::Sub(one, tr);
    ir = hn::Mul(omt, hn::MulAdd(lobe, hn::Set(d, p.lobe_rgb[0]), hn::Set(d, p.fog_rgb[0])));
    ig = hn::Mul(omt, hn::MulAdd(lobe, hn::Set(d, p.lobe_rgb[1]), hn::Set(d, p.fog_rgb[1])));
    ib = hn::Mul(omt, hn::MulAdd(lobe, hn::Set(d, p.lobe_rgb[2]), hn::Set(d, p.fog_rgb[2])));
    bad = hn::AndNot(hn::Gt(xk, hn::Set(d, -40.0f)), finite);
}

int FogRow(const FogRowParams &params,
           const float *z,
           float *row,
           int channels,
           int n,
           std::int32_t *fallback)
{
    // A local copy: stores to the pixels cannot alias it, so its fields stay in registers.
    const FogRowParams p = params;
    const hn::ScalableTag<float> d;
    using V = hn::Vec<decltype(d)>;
    const int lanes = int(hn::Lanes(d));
    int count = 0;
    for (int i = 0; i < n; i += lanes) {
        const int m = n - i < lanes ? n - i : lanes;
        V depth;
        if (m == lanes) {
            depth = hn::LoadU(d, z + i);
        } else {
            // The tail through a padded copy (depth 0: no fog in the padding).
            HWY_ALIGN float tail[kMaxLanes] = {};
            for (int l = 0; l < m; ++l) {
                tail[l] = z[i + l];
            }
            depth = hn::Load(d, tail);
        }
        V tr, ir, ig, ib;
        hn::Mask<decltype(d)> bad;
        FogVector(d, p, depth, float(i), tr, ir, ig, ib, bad);
        float *px = row + std::size_t(i) * std::size_t(channels);
        const bool all = m == lanes && hn::AllFalse(d, bad);
        if (all && channels == 4) {
            // pixel * (T, T, T, 1) + inscatter, de-interleaved and back.
            V r, g, b, a;
            hn::LoadInterleaved4(d, px, r, g, b, a);
            hn::StoreInterleaved4(
                hn::MulAdd(r, tr, ir), hn::MulAdd(g, tr, ig), hn::MulAdd(b, tr, ib), a, d, px);
            continue;
        }
        if (all && channels == 3) {
            V r, g, b;
            hn::LoadInterleaved3(d, px, r, g, b);
            hn::StoreInterleaved3(
                hn::MulAdd(r, tr, ir), hn::MulAdd(g, tr, ig), hn::MulAdd(b, tr, ib), d, px);
            continue;
        }
        // Lane by lane: the tail, images of more than four channels, and vectors with pixels
        // for the exact path (listed, and left alone here). The same fused multiply-add where
        // the target has one (hn::MulAdd on one lane).
        HWY_ALIGN float lt[kMaxLanes], lr[kMaxLanes], lg[kMaxLanes], lb[kMaxLanes];
        std::uint8_t bits[kMaxLanes / 8 + 8] = {};
        hn::Store(tr, d, lt);
        hn::Store(ir, d, lr);
        hn::Store(ig, d, lg);
        hn::Store(ib, d, lb);
        hn::StoreMaskBits(d, bad, bits);
        const hn::CappedTag<float, 1> d1;
        for (int l = 0; l < m; ++l) {
            if (bits[l >> 3] & (1u << (l & 7))) {
                fallback[count++] = i + l;
                continue;
            }
            float *q = px + std::size_t(l) * std::size_t(channels);
            const auto t1 = hn::Set(d1, lt[l]);
            q[0] = hn::GetLane(hn::MulAdd(hn::Set(d1, q[0]), t1, hn::Set(d1, lr[l])));
            q[1] = hn::GetLane(hn::MulAdd(hn::Set(d1, q[1]), t1, hn::Set(d1, lg[l])));
            q[2] = hn::GetLane(hn::MulAdd(hn::Set(d1, q[2]), t1, hn::Set(d1, lb[l])));
        }
    }
    return count;
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(FogRow);

int fog_row(
    const FogRowParams &p, const float *z, float *row, int channels, int n, std::int32_t *fallback)
{
    return HWY_DYNAMIC_DISPATCH(FogRow)(p, z, row, channels, n, fallback);
}

}  // namespace posthaste::shading
#endif
