// The screen-space reflection march's depth tests over Highway (see ssr_kernels.h; the method
// and the scalar march it follows in ssr.cpp). Compiled without FP contraction (CMakeLists.txt):
// every step is rounded as the scalar march rounds it.

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/ssr/ssr_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "shading/ssr/ssr_kernels.h"

#include <cstddef>
#include <limits>

#include "core/hwy_math-inl.h"
#include "shading/atmosphere/atmosphere_kernels.h"
#include "shading/lighting/env_brdf.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
using simd::HWY_NAMESPACE::ClampToRange;
using simd::HWY_NAMESPACE::Dot3Unfused;

/// The grid cell index of coordinates (x, y) in pixels: ssr.cpp's clamp_index in each axis
/// (clamped in float, then truncated).
template <class D, class V = hn::Vec<D>>
HWY_INLINE hn::Vec<hn::RebindToSigned<D>> CellIndex(D d, const SsrDepthGrid &g, V x, V y)
{
    const hn::RebindToSigned<D> di;
    const V zero = hn::Zero(d);
    const V inv_stride = hn::Set(d, g.inv_stride);
    const auto cx =
        hn::ConvertTo(di, ClampToRange(hn::Mul(x, inv_stride), zero, hn::Set(d, float(g.w - 1))));
    const auto cy =
        hn::ConvertTo(di, ClampToRange(hn::Mul(y, inv_stride), zero, hn::Set(d, float(g.h - 1))));
    return hn::Add(hn::Mul(cy, hn::Set(di, g.w)), cx);
}

/// sincos_turns (ssr_kernels.h) in lanes, the same operations in the same order.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void SinCosTurns(D d, V u, V &s, V &c)
{
    const hn::RebindToSigned<D> di;
    const V one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f), quarter = hn::Set(d, 0.25f);
    V q = hn::Sub(u, hn::ConvertTo(d, hn::ConvertTo(di, u)));
    q = hn::IfThenElse(hn::Gt(q, half),
                       hn::Sub(q, one),
                       hn::IfThenElse(hn::Lt(q, hn::Neg(half)), hn::Add(q, one), q));
    const auto high = hn::Gt(q, quarter), low = hn::Lt(q, hn::Neg(quarter));
    const V r =
        hn::IfThenElse(high, hn::Sub(half, q), hn::IfThenElse(low, hn::Sub(hn::Neg(half), q), q));
    const V x = hn::Mul(r, hn::Set(d, 6.28318530717958647692f));
    const V x2 = hn::Mul(x, x);
    // Written out (not looped) so that every target keeps the polynomials unrolled.
    V ps = hn::Set(d, kSinTaylor[0]);
    ps = hn::Add(hn::Mul(ps, x2), hn::Set(d, kSinTaylor[1]));
    ps = hn::Add(hn::Mul(ps, x2), hn::Set(d, kSinTaylor[2]));
    ps = hn::Add(hn::Mul(ps, x2), hn::Set(d, kSinTaylor[3]));
    ps = hn::Add(hn::Mul(ps, x2), hn::Set(d, kSinTaylor[4]));
    s = hn::Add(x, hn::Mul(x, hn::Mul(x2, ps)));
    V pc = hn::Set(d, kCosTaylor[0]);
    pc = hn::Add(hn::Mul(pc, x2), hn::Set(d, kCosTaylor[1]));
    pc = hn::Add(hn::Mul(pc, x2), hn::Set(d, kCosTaylor[2]));
    pc = hn::Add(hn::Mul(pc, x2), hn::Set(d, kCosTaylor[3]));
    pc = hn::Add(hn::Mul(pc, x2), hn::Set(d, kCosTaylor[4]));
    pc = hn::Add(hn::Mul(pc, x2), hn::Set(d, kCosTaylor[5]));
    const V cv = hn::Add(one, hn::Mul(x2, pc));
    c = hn::IfThenElse(hn::Or(high, low), hn::Neg(cv), cv);
}

void GgxRays(const float *const in[9], int n, float *const out[4])
{
    const hn::ScalableTag<float> d;
    using V = hn::Vec<decltype(d)>;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    for (int i = 0; i < n; i += int(hn::Lanes(d))) {
        const V nx = hn::LoadU(d, in[0] + i), ny = hn::LoadU(d, in[1] + i),
                nz = hn::LoadU(d, in[2] + i);
        const V vx = hn::LoadU(d, in[3] + i), vy = hn::LoadU(d, in[4] + i),
                vz = hn::LoadU(d, in[5] + i);
        const V alpha = hn::LoadU(d, in[6] + i), u1 = hn::LoadU(d, in[7] + i),
                u2 = hn::LoadU(d, in[8] + i);
        const V a2 = hn::Mul(alpha, alpha);
        const V cos2 = hn::Div(hn::Sub(one, u1), hn::Add(one, hn::Mul(hn::Sub(a2, one), u1)));
        const V cos_t = hn::Sqrt(
            hn::IfThenElse(hn::Gt(cos2, zero), hn::IfThenElse(hn::Lt(cos2, one), cos2, one), zero));
        const V sin2 = hn::Sub(one, hn::Mul(cos_t, cos_t));
        const V sin_t = hn::Sqrt(hn::IfThenElse(hn::Gt(sin2, zero), sin2, zero));
        V sp, cp;
        SinCosTurns(d, u2, sp, cp);
        const V sign = hn::CopySign(one, nz);
        const V a = hn::Div(hn::Set(d, -1.0f), hn::Add(sign, nz));
        const V b = hn::Mul(hn::Mul(nx, ny), a);
        const V t1[3] = {hn::Add(one, hn::Mul(hn::Mul(hn::Mul(sign, nx), nx), a)),
                         hn::Mul(sign, b),
                         hn::Mul(hn::Neg(sign), nx)};
        const V t2[3] = {b, hn::Add(sign, hn::Mul(hn::Mul(ny, ny), a)), hn::Neg(ny)};
        const V w1 = hn::Mul(sin_t, cp), w2 = hn::Mul(sin_t, sp);
        const V nv[3] = {nx, ny, nz}, vv[3] = {vx, vy, vz};
        V h[3];
        for (int k = 0; k < 3; ++k) {
            h[k] = hn::Add(hn::Add(hn::Mul(t1[k], w1), hn::Mul(t2[k], w2)), hn::Mul(nv[k], cos_t));
        }
        const V vh2 = hn::Mul(hn::Set(d, 2.0f), Dot3Unfused(vx, vy, vz, h[0], h[1], h[2]));
        V r[3];
        for (int k = 0; k < 3; ++k) {
            r[k] = hn::Sub(hn::Mul(vh2, h[k]), vv[k]);
        }
        const V inv = hn::Div(one, hn::Sqrt(Dot3Unfused(r[0], r[1], r[2], r[0], r[1], r[2])));
        V l[3];
        for (int k = 0; k < 3; ++k) {
            l[k] = hn::Mul(r[k], inv);
            hn::StoreU(l[k], d, out[k] + i);
        }
        // n . l in glm's order.
        hn::StoreU(Dot3Unfused(nx, ny, nz, l[0], l[1], l[2]), d, out[3] + i);
    }
}

/// Row r of the matrix m (glm's column-major layout) times (x, y, z, w), in glm's order:
/// (m0 x + m1 y) + (m2 z + m3 w).
template <class D, class V = hn::Vec<D>>
HWY_INLINE V MatRow(D d, const float *m, int r, V x, V y, V z, V w)
{
    const V a0 = hn::Add(hn::Mul(hn::Set(d, m[r]), x), hn::Mul(hn::Set(d, m[4 + r]), y));
    const V a1 = hn::Add(hn::Mul(hn::Set(d, m[8 + r]), z), hn::Mul(hn::Set(d, m[12 + r]), w));
    return hn::Add(a0, a1);
}

/// std::min(a, b) and std::max(a, b) as the scalar code has them ((b < a) ? b : a and
/// (a < b) ? b : a), NaN included.
template <class V>
HWY_INLINE V StdMin(V a, V b)
{
    return hn::IfThenElse(hn::Lt(b, a), b, a);
}
template <class V>
HWY_INLINE V StdMax(V a, V b)
{
    return hn::IfThenElse(hn::Lt(a, b), b, a);
}

void Segments(const SsrSegmentCamera &c,
              const float *oxs,
              const float *oys,
              const float *ozs,
              const float *dxs,
              const float *dys,
              const float *dzs,
              int n,
              float *const out[9])
{
    const hn::ScalableTag<float> d;
    using V = hn::Vec<decltype(d)>;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V width = hn::Set(d, float(c.width)), height = hn::Set(d, float(c.height));
    const V near = hn::Set(d, c.near);
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    const float *w2c = c.world_to_camera, *w2n = c.world_to_ndc;
    // project(): pixel coordinates and 1 / camera z of the world point (x, y, z, 1).
    const auto project = [&](V x, V y, V z, V &px, V &py, V &inv_z) {
        const V hx = MatRow(d, w2n, 0, x, y, z, one), hy = MatRow(d, w2n, 1, x, y, z, one);
        const V hw = MatRow(d, w2n, 3, x, y, z, one);
        px = hn::Mul(hn::Div(hx, hw), width);
        py = hn::Mul(hn::Div(hy, hw), height);
        inv_z = hn::Div(one, MatRow(d, w2c, 2, x, y, z, one));
    };
    for (int i = 0; i < n; i += int(hn::Lanes(d))) {
        const V ox = hn::LoadU(d, oxs + i), oy = hn::LoadU(d, oys + i), oz = hn::LoadU(d, ozs + i);
        const V dx = hn::LoadU(d, dxs + i), dy = hn::LoadU(d, dys + i), dz = hn::LoadU(d, dzs + i);
        // Camera z along the ray, to clip its far end in front of the camera.
        const V oc_z = MatRow(d, w2c, 2, ox, oy, oz, one);
        const V dc_z = MatRow(d, w2c, 2, dx, dy, dz, zero);
        V length = hn::Set(d, c.max_distance);
        const auto clip = hn::Lt(hn::Add(oc_z, hn::Mul(dc_z, length)), near);
        auto valid = hn::Not(hn::And(clip, hn::Ge(dc_z, zero)));
        length = hn::IfThenElse(clip, hn::Div(hn::Sub(near, oc_z), dc_z), length);
        valid = hn::And(valid, hn::Gt(length, zero));
        V ax, ay, az, bx, by, bz;
        project(ox, oy, oz, ax, ay, az);
        project(hn::Add(ox, hn::Mul(dx, length)),
                hn::Add(oy, hn::Mul(dy, length)),
                hn::Add(oz, hn::Mul(dz, length)),
                bx,
                by,
                bz);
        const V sum = hn::Add(hn::Add(hn::Add(hn::Add(hn::Add(ax, ay), az), bx), by), bz);
        valid = hn::And(valid, hn::Lt(hn::Abs(sum), inf));
        // The part of the segment on screen: t in [0, t_end].
        V t_end = one;
        const V ddx = hn::Sub(bx, ax), ddy = hn::Sub(by, ay);
        t_end = hn::IfThenElse(
            hn::Gt(ddx, zero),
            StdMin(t_end, hn::Div(hn::Sub(width, ax), ddx)),
            hn::IfThenElse(hn::Lt(ddx, zero), StdMin(t_end, hn::Div(hn::Neg(ax), ddx)), t_end));
        t_end = hn::IfThenElse(
            hn::Gt(ddy, zero),
            StdMin(t_end, hn::Div(hn::Sub(height, ay), ddy)),
            hn::IfThenElse(hn::Lt(ddy, zero), StdMin(t_end, hn::Div(hn::Neg(ay), ddy)), t_end));
        valid = hn::And(valid, hn::Gt(t_end, zero));
        const V length_px = hn::Sqrt(hn::Add(hn::Mul(ddx, ddx), hn::Mul(ddy, ddy)));
        const V t_start =
            StdMin(t_end, hn::Div(hn::Set(d, 1.5f), StdMax(length_px, hn::Set(d, 1e-6f))));
        const V pixels = hn::Mul(length_px, hn::Sub(t_end, t_start));
        const V steps =
            StdMax(one, hn::Trunc(StdMin(hn::Set(d, float(c.max_steps)), hn::Ceil(pixels))));
        const V values[9] = {
            ax, ay, az, bx, by, bz, t_start, t_end, hn::IfThenElseZero(valid, steps)};
        for (int k = 0; k < 9; ++k) {
            hn::StoreU(values[k], d, out[k] + i);
        }
    }
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

/// shading::fast_acos, the same operations in the same order.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V AcosAsScalar(D d, V x)
{
    const V ax = hn::Min(hn::Set(d, 1.0f), hn::Abs(x));
    V p = hn::Set(d, -0.0012624911f);
    p = hn::Add(hn::Mul(p, ax), hn::Set(d, 0.0066700901f));
    p = hn::Sub(hn::Mul(p, ax), hn::Set(d, 0.0170881256f));
    p = hn::Add(hn::Mul(p, ax), hn::Set(d, 0.0308918810f));
    p = hn::Sub(hn::Mul(p, ax), hn::Set(d, 0.0501743046f));
    p = hn::Add(hn::Mul(p, ax), hn::Set(d, 0.0889789874f));
    p = hn::Sub(hn::Mul(p, ax), hn::Set(d, 0.2145988016f));
    p = hn::Add(hn::Mul(p, ax), hn::Set(d, 1.5707963050f));
    const V r = hn::Mul(hn::Sqrt(hn::Sub(hn::Set(d, 1.0f), ax)), p);
    return hn::IfThenElse(hn::Lt(x, hn::Zero(d)), hn::Sub(hn::Set(d, 3.14159265358979f), r), r);
}

void SkyViewRadiance(const SkyCoordParams &p,
                     const float *xs,
                     const float *ys,
                     const float *zs,
                     int n,
                     float *out_r,
                     float *out_g,
                     float *out_b)
{
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const auto dot = [&](V x, V y, V z, const float *v) {
        return Dot3Unfused(x, y, z, hn::Set(d, v[0]), hn::Set(d, v[1]), hn::Set(d, v[2]));
    };
    // shading::saturate for finite x.
    const auto saturate = [&](V x) { return ClampToRange(x, zero, one); };
    const int rows_above = p.lut_height / 2, rows_below = p.lut_height - rows_above;
    for (int i = 0; i < n; i += int(hn::Lanes(d))) {
        const V x = hn::LoadU(d, xs + i), y = hn::LoadU(d, ys + i), z = hn::LoadU(d, zs + i);
        const V mu = dot(x, y, z, p.up);
        const V along = dot(x, y, z, p.sun_tangent);
        const V side = dot(x, y, z, p.sun_side);
        const V horizontal = hn::Sqrt(hn::Add(hn::Mul(along, along), hn::Mul(side, side)));
        const V cos_azimuth =
            hn::IfThenElse(hn::Gt(horizontal, hn::Set(d, 1e-12f)), hn::Div(along, horizontal), one);
        const V u = hn::Sqrt(hn::Max(hn::Sub(half, hn::Mul(half, cos_azimuth)), zero));
        const V theta = AcosAsScalar(d, mu);
        const auto above = hn::Not(hn::Lt(mu, hn::Set(d, p.mu_horizon)));
        const V s_above = hn::Sub(
            one, hn::Sqrt(saturate(hn::Sub(one, hn::Mul(theta, hn::Set(d, p.inv_theta_above))))));
        const V s_below = hn::Sqrt(saturate(
            hn::Mul(hn::Sub(theta, hn::Set(d, p.theta_horizon)), hn::Set(d, p.inv_theta_below))));
        const V s = hn::IfThenElse(above, s_above, s_below);
        // Lut2D::sample_rows over the half the direction is in.
        const V rows =
            hn::IfThenElse(above, hn::Set(d, float(rows_above)), hn::Set(d, float(rows_below)));
        const auto row0 =
            hn::IfThenElseZero(hn::RebindMask(di, hn::Not(above)), hn::Set(di, rows_above));
        const V fx = hn::Mul(saturate(u), hn::Set(d, float(p.lut_width - 1)));
        const V fy = hn::Mul(saturate(s), hn::Sub(rows, one));
        const auto x0 = hn::Min(hn::ConvertTo(di, fx), hn::Set(di, p.lut_width - 2));
        const auto y0 =
            hn::Min(hn::ConvertTo(di, fy), hn::ConvertTo(di, hn::Sub(rows, hn::Set(d, 2.0f))));
        const V tx = hn::Sub(fx, hn::ConvertTo(d, x0));
        const V ty = hn::Sub(fy, hn::ConvertTo(d, y0));
        const auto texel = hn::Add(hn::Mul(hn::Add(row0, y0), hn::Set(di, p.lut_width)), x0);
        const auto i00 = hn::Mul(texel, hn::Set(di, 3));
        const auto i01 = hn::Add(i00, hn::Set(di, 3));
        const auto i10 = hn::Add(i00, hn::Set(di, 3 * p.lut_width));
        const auto i11 = hn::Add(i10, hn::Set(di, 3));
        float *outs[3] = {out_r, out_g, out_b};
        for (int c = 0; c < 3; ++c) {
            const auto cc = hn::Set(di, c);
            const V p00 = hn::GatherIndex(d, p.lut, hn::Add(i00, cc));
            const V p01 = hn::GatherIndex(d, p.lut, hn::Add(i01, cc));
            const V p10 = hn::GatherIndex(d, p.lut, hn::Add(i10, cc));
            const V p11 = hn::GatherIndex(d, p.lut, hn::Add(i11, cc));
            const V top = hn::Add(p00, hn::Mul(tx, hn::Sub(p01, p00)));
            const V bottom = hn::Add(p10, hn::Mul(tx, hn::Sub(p11, p10)));
            hn::StoreU(hn::Add(top, hn::Mul(ty, hn::Sub(bottom, top))), d, outs[c] + i);
        }
    }
}

/// ggx_directional_albedo's (A, B) at n.v (nv) and roughness, bilinear in its table
/// (env_brdf.cpp), rounded as it rounds them. The indices are clamped as integers too, so lanes
/// the caller discards (a NaN roughness) read inside the table.
template <class D, class V = hn::Vec<D>>
HWY_INLINE void GgxDirectionalAlbedo(D d, const float *table, V nv, V rough, V &a, V &b)
{
    const hn::RebindToSigned<D> di;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    const V last = hn::Set(d, float(kGgxAlbedoTableSize - 1));
    const V x = hn::Mul(ClampToRange(nv, zero, one), last);
    const V y = hn::Mul(ClampToRange(rough, zero, one), last);
    const auto top = hn::Set(di, kGgxAlbedoTableSize - 2);
    const auto i = hn::Min(hn::Max(hn::ConvertTo(di, x), hn::Zero(di)), top);
    const auto j = hn::Min(hn::Max(hn::ConvertTo(di, y), hn::Zero(di)), top);
    const V fx = hn::Sub(x, hn::ConvertTo(d, i)), fy = hn::Sub(y, hn::ConvertTo(d, j));
    const V gx = hn::Sub(one, fx), gy = hn::Sub(one, fy);
    // Pair (i, j) at 2 (j size + i); (i + 1, j) two floats on, (i, j + 1) a row of pairs on.
    const auto p00 = hn::ShiftLeft<1>(hn::Add(hn::Mul(j, hn::Set(di, kGgxAlbedoTableSize)), i));
    const auto p10 = hn::Add(p00, hn::Set(di, 2));
    const auto p01 = hn::Add(p00, hn::Set(di, 2 * kGgxAlbedoTableSize));
    const auto p11 = hn::Add(p01, hn::Set(di, 2));
    // glm::mix(p, q, f) = p (1 - f) + q f, along n.v, then along roughness.
    const auto lerp = [&](const float *t) {
        const V row0 = hn::Add(hn::Mul(hn::GatherIndex(d, t, p00), gx),
                               hn::Mul(hn::GatherIndex(d, t, p10), fx));
        const V row1 = hn::Add(hn::Mul(hn::GatherIndex(d, t, p01), gx),
                               hn::Mul(hn::GatherIndex(d, t, p11), fx));
        return hn::Add(hn::Mul(row0, gy), hn::Mul(row1, fy));
    };
    a = lerp(table);
    b = lerp(table + 1);
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
    const V stride = hn::Set(d, float(r.stride));  // exact: i stride is an integer below 2^24
    const bool terms = r.n_out[0] != nullptr;
    const V f0_dielectric = hn::Set(d, 0.04f);
    const auto ggx = hn::Ne(hn::Set(d, r.ggx_table ? 1.0f : 0.0f), zero);  // all lanes or none
    const std::size_t lanes = hn::Lanes(d);
    for (int x = 0; x < r.n; x += int(lanes)) {
        const V z = hn::LoadU(d, r.z + x);
        const V rough = hn::LoadU(d, r.roughness + x);
        V nx = hn::LoadU(d, r.nx + x), ny = hn::LoadU(d, r.ny + x), nz = hn::LoadU(d, r.nz + x);
        const V nlen = hn::Sqrt(Dot3Unfused(nx, ny, nz, nx, ny, nz));
        const V gloss = hn::Mul(hn::Sub(one, rough), hn::Sub(one, rough));
        // (The rasterizer's weight is 0 below a gloss of 0.05; a GGX lobe's is not.)
        const auto glossy =
            hn::And(hn::And(hn::Gt(z, zero), hn::Lt(z, inf)),
                    hn::And(hn::And(hn::Le(rough, max_roughness), hn::Gt(nlen, zero)),
                            hn::Or(hn::Ge(gloss, hn::Set(d, 0.05f)), ggx)));
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
        const V u = hn::Div(hn::Add(hn::Mul(hn::Iota(d, float(x)), stride), half), width);
        const V rx = hn::Add(hn::Add(ox, hn::Mul(u, dux)), vdx);
        const V ry = hn::Add(hn::Add(oy, hn::Mul(u, duy)), vdy);
        const V rz = hn::Add(hn::Add(oz, hn::Mul(u, duz)), vdz);
        const V inv_len = hn::Div(one, hn::Sqrt(Dot3Unfused(rx, ry, rz, rx, ry, rz)));
        const V vx = hn::Neg(hn::Mul(rx, inv_len)), vy = hn::Neg(hn::Mul(ry, inv_len)),
                vz = hn::Neg(hn::Mul(rz, inv_len));
        // The side the camera sees.
        const auto back = hn::Lt(Dot3Unfused(nx, ny, nz, vx, vy, vz), zero);
        nx = hn::IfThenElse(back, hn::Neg(nx), nx);
        ny = hn::IfThenElse(back, hn::Neg(ny), ny);
        nz = hn::IfThenElse(back, hn::Neg(nz), nz);
        if (terms) {
            // glossy_pixel's point: position + depth_ray(u, v) z.
            const V p[3] = {hn::Add(hn::Set(d, r.position[0]), hn::Mul(rx, z)),
                            hn::Add(hn::Set(d, r.position[1]), hn::Mul(ry, z)),
                            hn::Add(hn::Set(d, r.position[2]), hn::Mul(rz, z))};
            const V nn[3] = {nx, ny, nz}, vv[3] = {vx, vy, vz};
            for (int c = 0; c < 3; ++c) {
                hn::StoreU(nn[c], d, r.n_out[c] + x);
                hn::StoreU(vv[c], d, r.view_out[c] + x);
                hn::StoreU(p[c], d, r.point_out[c] + x);
            }
        }
        const V nv = hn::Max(Dot3Unfused(nx, ny, nz, vx, vy, vz), zero);
        // F0 = mix(0.04, albedo, metallic) = 0.04 (1 - metallic) + albedo metallic.
        const V metal = hn::LoadU(d, r.metallic + x);
        const V base = hn::Mul(f0_dielectric, hn::Sub(one, metal));
        if (r.ggx_table) {
            V a, b;
            GgxDirectionalAlbedo(d, r.ggx_table, nv, rough, a, b);
            const auto weight = [&](const float *albedo) {
                const V f0 = hn::Add(base, hn::Mul(hn::LoadU(d, albedo + x), metal));
                return hn::IfThenElseZero(glossy, hn::Add(hn::Mul(f0, a), b));
            };
            hn::StoreU(weight(r.ar), d, wr + x);
            hn::StoreU(weight(r.ag), d, wg + x);
            hn::StoreU(weight(r.ab), d, wb + x);
            continue;
        }
        const V m = hn::Sub(one, ClampToRange(nv, zero, one));
        const V m2 = hn::Mul(m, m);
        const V m5 = hn::Mul(hn::Mul(m2, m2), m);
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
                const V dot = Dot3Unfused(hn::LoadU(d, c + pitch + e),
                                          hn::LoadU(d, c + 2 * pitch + e),
                                          hn::LoadU(d, c + 3 * pitch + e),
                                          nx,
                                          ny,
                                          nz);
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

HWY_EXPORT(GgxRays);
HWY_EXPORT(Segments);

void ssr_ggx_rays(const float *const in[9], int n, float *const out[4])
{
    HWY_DYNAMIC_DISPATCH(GgxRays)(in, n, out);
}
HWY_EXPORT(MarchSteps);

void ssr_segments(const SsrSegmentCamera &c,
                  const float *ox,
                  const float *oy,
                  const float *oz,
                  const float *dx,
                  const float *dy,
                  const float *dz,
                  int n,
                  float *const out[9])
{
    HWY_DYNAMIC_DISPATCH(Segments)(c, ox, oy, oz, dx, dy, dz, n, out);
}
HWY_EXPORT(SkyViewRadiance);
HWY_EXPORT(WeightRow);

void ssr_sky_view_radiance(const SkyCoordParams &p,
                           const float *x,
                           const float *y,
                           const float *z,
                           int n,
                           float *r,
                           float *g,
                           float *b)
{
    HWY_DYNAMIC_DISPATCH(SkyViewRadiance)(p, x, y, z, n, r, g, b);
}
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
