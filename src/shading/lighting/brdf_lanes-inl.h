// The microfacet BRDF of brdf.h over Highway's lane types: the terms that the rasterizer's vector
// beauty (raster/render_shade_kernels.cpp) and the relight kernel (relight_kernels.cpp) both
// evaluate, written once. Each function does the operations of its scalar twin in brdf.cpp in
// the same order with exact division and square root, so in a file compiled without FMA
// contraction a lane gives the scalar function's bits. Include it after <hwy/highway.h> in a
// kernel file that uses foreach_target.h; like every Highway "-inl.h" it is compiled once per
// target (the toggle guard below).

// clang-format off
#if defined(POSTHASTE_SHADING_BRDF_LANES_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef POSTHASTE_SHADING_BRDF_LANES_INL_H_
#undef POSTHASTE_SHADING_BRDF_LANES_INL_H_
#else
#define POSTHASTE_SHADING_BRDF_LANES_INL_H_
#endif
// clang-format on

#include <hwy/highway.h>

#include "core/hwy_math-inl.h"
#include "shading/lighting/brdf.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

/// The Schlick weight (1 - c)^5 of fresnel_schlick for c clamped to [0, 1], as (m^2 m^2) m.
template <class V>
HWY_INLINE V SchlickWeight(V c)
{
    const hn::DFromV<V> d;
    const V one = hn::Set(d, 1.0f);
    const V m = hn::Sub(one, simd::HWY_NAMESPACE::ClampToRange(c, hn::Zero(d), one));
    return hn::Mul(hn::Mul(hn::Mul(m, m), hn::Mul(m, m)), m);
}

/// fresnel_schlick from F0 and the weight w = SchlickWeight(cos): f0 + (1 - f0) w.
template <class V>
HWY_INLINE V FresnelSchlick(V f0, V w)
{
    const hn::DFromV<V> d;
    return hn::Add(f0, hn::Mul(hn::Sub(hn::Set(d, 1.0f), f0), w));
}

/// 1 - (n.h)^2 as dv_ggx_smith_correlated wants it: |h - n (n.h)|^2 clamped to 1, from the
/// unit normal and half vector and their unclamped dot product nh_raw.
template <class V>
HWY_INLINE V SinSquaredAcross(V nx, V ny, V nz, V hx, V hy, V hz, V nh_raw)
{
    const hn::DFromV<V> d;
    const V qx = hn::Sub(hx, hn::Mul(nx, nh_raw)), qy = hn::Sub(hy, hn::Mul(ny, nh_raw)),
            qz = hn::Sub(hz, hn::Mul(nz, nh_raw));
    const V q2 = hn::Add(hn::Add(hn::Mul(qx, qx), hn::Mul(qy, qy)), hn::Mul(qz, qz));
    return hn::Min(q2, hn::Set(d, 1.0f));
}

/// dv_ggx_smith_correlated from n.h, sin2_h (SinSquaredAcross), alpha^2, the clamped cosines and
/// their Smith roots (SmithRoot): (0.5 a2) / (pi d d (n.l root(n.v) + n.v root(n.l))) with
/// d = sin2_h (1 - a2) + a2; zero where n.h <= 0.
template <class V>
HWY_INLINE V GgxSmithDV(V nh, V sin2_h, V a2, V one_a2, V nv, V nl, V root_v, V root_l)
{
    const hn::DFromV<V> d;
    const V dd = hn::Add(hn::Mul(sin2_h, one_a2), a2);
    const V g = hn::Add(hn::Mul(nl, root_v), hn::Mul(nv, root_l));
    const V den = hn::Mul(hn::Mul(hn::Mul(hn::Set(d, kPi), dd), dd), g);
    const V value = hn::Div(hn::Mul(hn::Set(d, 0.5f), a2), den);
    return hn::IfThenElseZero(hn::Gt(nh, hn::Zero(d)), value);
}

/// d_ggx_aniso from the tangent and bitangent components of h (t.h, b.h) and the alphas:
/// 1 / (pi ax ay d d), d = (t.h / ax)^2 + (b.h / ay)^2 + (n.h)^2; zero where n.h <= 0.
template <class V>
HWY_INLINE V GgxDAniso(V nh, V th, V bh, V ax, V ay)
{
    const hn::DFromV<V> d;
    const V x = hn::Div(th, ax), y = hn::Div(bh, ay);
    const V dd = hn::Add(hn::Add(hn::Mul(x, x), hn::Mul(y, y)), hn::Mul(nh, nh));
    const V den = hn::Mul(hn::Mul(hn::Mul(hn::Mul(hn::Set(d, kPi), ax), ay), dd), dd);
    return hn::IfThenElseZero(hn::Gt(nh, hn::Zero(d)), hn::Div(hn::Set(d, 1.0f), den));
}

/// The root of height-correlated Smith for one clamped cosine c: sqrt(c^2 (1 - a2) + a2), with
/// one_a2 = 1 - a2. It depends on the pixel only for c = n.v: kernels compute it once a pixel.
template <class V>
HWY_INLINE V SmithRoot(V c, V a2, V one_a2)
{
    return hn::Sqrt(hn::Add(hn::Mul(hn::Mul(c, c), one_a2), a2));
}

/// v_smith_correlated from the clamped cosines and their roots (SmithRoot):
/// 0.5 / (n.l root(n.v) + n.v root(n.l)).
template <class V>
HWY_INLINE V SmithCorrelatedV(V nv, V nl, V root_v, V root_l)
{
    const hn::DFromV<V> d;
    return hn::Div(hn::Set(d, 0.5f), hn::Add(hn::Mul(nl, root_v), hn::Mul(nv, root_l)));
}

/// The anisotropic root of v_smith_correlated_aniso for one direction x: |(ax t.x, ay b.x, n.x)|
/// with n.x clamped, from ax^2 and ay^2.
template <class V>
HWY_INLINE V SmithRootAniso(V c, V tx, V bx, V ax2, V ay2)
{
    return hn::Sqrt(hn::Add(hn::Add(hn::Mul(hn::Mul(ax2, tx), tx), hn::Mul(hn::Mul(ay2, bx), bx)),
                            hn::Mul(c, c)));
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#endif  // include guard
