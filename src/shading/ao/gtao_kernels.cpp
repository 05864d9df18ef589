// GTAO's per-row kernel over Highway (see gtao_kernels.h and, for the method, gtao.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/ao/gtao_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include "shading/ao/gtao_kernels.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

constexpr float kPi = 3.14159265358979f;
constexpr float kHalfPi = 0.5f * kPi;

/// acos to about 7e-5 rad over [-1, 1] (Abramowitz and Stegun 4.4.45).
template <class D, class V>
HWY_INLINE V FastAcos(D d, V c)
{
    const V a = hn::Abs(c);
    V poly = hn::MulAdd(hn::Set(d, -0.0187293f), a, hn::Set(d, 0.0742610f));
    poly = hn::MulAdd(poly, a, hn::Set(d, -0.2121144f));
    poly = hn::MulAdd(poly, a, hn::Set(d, 1.5707288f));
    const V p = hn::Mul(hn::Sqrt(hn::Max(hn::Sub(hn::Set(d, 1.0f), a), hn::Zero(d))), poly);
    return hn::IfThenElse(hn::Lt(c, hn::Zero(d)), hn::Sub(hn::Set(d, kPi), p), p);
}

/// (-cos(2h - n) + cos n + 2 h sin n) / 4 from h's cosine ch and sine sh (Jimenez et al. 2016,
/// eq. 10, one side).
template <class D, class V>
HWY_INLINE V Arc(D d, V h, V ch, V sh, V cn, V sn)
{
    const V cos_2h = hn::MulAdd(hn::Add(ch, ch), ch, hn::Set(d, -1.0f));
    const V sin_2h = hn::Mul(hn::Add(sh, sh), ch);
    const V cos_diff = hn::MulAdd(cos_2h, cn, hn::Mul(sin_2h, sn));
    const V sum = hn::MulAdd(hn::Add(h, h), sn, hn::Sub(cn, cos_diff));
    return hn::Mul(hn::Set(d, 0.25f), sum);
}

template <class V>
HWY_INLINE V Dot(V ax, V ay, V az, V bx, V by, V bz)
{
    return hn::MulAdd(ax, bx, hn::MulAdd(ay, by, hn::Mul(az, bz)));
}

/// Bit masks of the k lowest of 32 sectors, k = 0..32 (the visibility bitmask's intervals).
HWY_ALIGN static constexpr std::int32_t kLowMask[33] = {
    0,         0x1,        0x3,        0x7,        0xF,       0x1F,      0x3F,
    0x7F,      0xFF,       0x1FF,      0x3FF,      0x7FF,     0xFFF,     0x1FFF,
    0x3FFF,    0x7FFF,     0xFFFF,     0x1FFFF,    0x3FFFF,   0x7FFFF,   0xFFFFF,
    0x1FFFFF,  0x3FFFFF,   0x7FFFFF,   0xFFFFFF,   0x1FFFFFF, 0x3FFFFFF, 0x7FFFFFF,
    0xFFFFFFF, 0x1FFFFFFF, 0x3FFFFFFF, 0x7FFFFFFF, -1};

template <bool kBitmask>
void GtaoRowT(const GtaoKernelParams &p,
              int oy,
              const float *zs,
              const float *nxs,
              const float *nys,
              const float *nzs,
              const std::int32_t *rots,
              const float *jits,
              int n,
              float *out)
{
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    const hn::RebindToUnsigned<decltype(d)> du32;
    using V = hn::Vec<decltype(d)>;
    const int lanes = int(hn::Lanes(d));
    const float inv_w = 1.0f / float(p.w), inv_h = 1.0f / float(p.h);
    const float y = float(oy * p.stride);
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f), half = hn::Set(d, 0.5f);
    const V cam_x = hn::Set(d, p.cam[0]), cam_y = hn::Set(d, p.cam[1]),
            cam_z = hn::Set(d, p.cam[2]);
    const V du_x = hn::Set(d, p.du[0]), du_y = hn::Set(d, p.du[1]), du_z = hn::Set(d, p.du[2]);
    const V dv_x = hn::Set(d, p.dv[0]), dv_y = hn::Set(d, p.dv[1]), dv_z = hn::Set(d, p.dv[2]);
    const V o_x = hn::Set(d, p.origin[0]), o_y = hn::Set(d, p.origin[1]),
            o_z = hn::Set(d, p.origin[2]);
    const V vinv_w = hn::Set(d, inv_w), vinv_h = hn::Set(d, inv_h);
    const V r2 = hn::Set(d, p.radius * p.radius), four_r2 = hn::Set(d, 4.0f * p.radius * p.radius);
    const V inv_radius = hn::Set(d, 1.0f / p.radius);
    const V width = hn::Set(d, float(p.w)), height = hn::Set(d, float(p.h));
    const auto width_i = hn::Set(di, p.w), map_w = hn::Set(di, p.map_w);
    const bool maps = p.thickness_map || p.reach_map;
    const auto map_round = hn::Set(di, (1 << p.map_shift) >> 1),
               map_last_x = hn::Set(di, p.map_w - 1), map_last_y = hn::Set(di, p.map_h - 1);
    // The row's rays at depth 1: origin + v dv + u du.
    const float v_row = (y + 0.5f) * inv_h;
    const V rb_x = hn::MulAdd(hn::Set(d, v_row), dv_x, o_x);
    const V rb_y = hn::MulAdd(hn::Set(d, v_row), dv_y, o_y);
    const V rb_z = hn::MulAdd(hn::Set(d, v_row), dv_z, o_z);
    const V vy = hn::Set(d, y);
    for (int i0 = 0; i0 < n; i0 += lanes) {
        const V z = hn::LoadU(d, zs + i0);
        auto active = hn::And(hn::Gt(z, zero), hn::IsFinite(z));
        if (hn::AllFalse(d, active)) {
            hn::StoreU(one, d, out + i0);
            continue;
        }
        const V zc = hn::IfThenElse(active, z, one);
        const V x = hn::Mul(hn::ConvertTo(d, hn::Iota(di, i0)), hn::Set(d, float(p.stride)));
        const V u = hn::Mul(hn::Add(x, half), vinv_w);
        const V ray_x = hn::MulAdd(u, du_x, rb_x), ray_y = hn::MulAdd(u, du_y, rb_y),
                ray_z = hn::MulAdd(u, du_z, rb_z);
        const V pos_x = hn::MulAdd(zc, ray_x, cam_x), pos_y = hn::MulAdd(zc, ray_y, cam_y),
                pos_z = hn::MulAdd(zc, ray_z, cam_z);
        // The view vector: from the point back to the camera.
        const V inv_ray = hn::Div(one, hn::Sqrt(Dot(ray_x, ray_y, ray_z, ray_x, ray_y, ray_z)));
        const V view_x = hn::Neg(hn::Mul(ray_x, inv_ray)),
                view_y = hn::Neg(hn::Mul(ray_y, inv_ray)),
                view_z = hn::Neg(hn::Mul(ray_z, inv_ray));
        V nx = hn::LoadU(d, nxs + i0), ny = hn::LoadU(d, nys + i0), nz = hn::LoadU(d, nzs + i0);
        const V nl = hn::Sqrt(Dot(nx, ny, nz, nx, ny, nz));
        const auto good_n = hn::And(hn::Gt(nl, hn::Set(d, 1e-6f)), hn::IsFinite(nl));
        const V inv_nl = hn::Div(one, hn::IfThenElse(good_n, nl, one));
        nx = hn::IfThenElse(good_n, hn::Mul(nx, inv_nl), view_x);
        ny = hn::IfThenElse(good_n, hn::Mul(ny, inv_nl), view_y);
        nz = hn::IfThenElse(good_n, hn::Mul(nz, inv_nl), view_z);
        // The search radius on screen; under a pixel there is nothing to find.
        const V radius_px =
            hn::Min(hn::Div(hn::Set(d, p.radius),
                            hn::Max(hn::Mul(zc, hn::Set(d, p.px_world_1)), hn::Set(d, 1e-12f))),
                    hn::Set(d, p.max_radius_px));
        active = hn::And(active, hn::Ge(radius_px, one));
        if (hn::AllFalse(d, active)) {
            hn::StoreU(one, d, out + i0);
            continue;
        }
        const auto rot = hn::LoadU(di, rots + i0);
        const V jitter = hn::LoadU(d, jits + i0);
        V visibility = zero;
        for (int s = 0; s < p.slices; ++s) {
            const auto idx = hn::Add(rot, hn::Set(di, s));
            const V dx = hn::GatherIndex(d, p.dir_x, idx), dy = hn::GatherIndex(d, p.dir_y, idx);
            // The slice's world direction toward the neighbouring pixel along (dx, dy), made
            // orthogonal to the view vector; the slice plane's axis; the normal projected.
            const V ddx = hn::Mul(dx, vinv_w), ddy = hn::Mul(dy, vinv_h);
            const V side_x = hn::MulAdd(ddx, du_x, hn::Mul(ddy, dv_x));
            const V side_y = hn::MulAdd(ddx, du_y, hn::Mul(ddy, dv_y));
            const V side_z = hn::MulAdd(ddx, du_z, hn::Mul(ddy, dv_z));
            const V sv = Dot(side_x, side_y, side_z, view_x, view_y, view_z);
            V or_x = hn::NegMulAdd(sv, view_x, side_x), or_y = hn::NegMulAdd(sv, view_y, side_y),
              or_z = hn::NegMulAdd(sv, view_z, side_z);
            const V inv_or = hn::Div(
                one,
                hn::Max(hn::Sqrt(Dot(or_x, or_y, or_z, or_x, or_y, or_z)), hn::Set(d, 1e-20f)));
            or_x = hn::Mul(or_x, inv_or);
            or_y = hn::Mul(or_y, inv_or);
            or_z = hn::Mul(or_z, inv_or);
            const V ax = hn::NegMulAdd(or_z, view_y, hn::Mul(or_y, view_z));
            const V ay = hn::NegMulAdd(or_x, view_z, hn::Mul(or_z, view_x));
            const V az = hn::NegMulAdd(or_y, view_x, hn::Mul(or_x, view_y));
            const V na = Dot(nx, ny, nz, ax, ay, az);
            const V pn_x = hn::NegMulAdd(ax, na, nx), pn_y = hn::NegMulAdd(ay, na, ny),
                    pn_z = hn::NegMulAdd(az, na, nz);
            const V pn_len = hn::Sqrt(Dot(pn_x, pn_y, pn_z, pn_x, pn_y, pn_z));
            const auto slice_ok = hn::Ge(pn_len, hn::Set(d, 1e-6f));
            const V cos_n = hn::Min(hn::Max(hn::Div(Dot(pn_x, pn_y, pn_z, view_x, view_y, view_z),
                                                    hn::Max(pn_len, hn::Set(d, 1e-20f))),
                                            hn::Set(d, -1.0f)),
                                    one);
            const auto neg = hn::Lt(Dot(pn_x, pn_y, pn_z, or_x, or_y, or_z), zero);
            const V acn = FastAcos(d, cos_n);
            const V ang_n = hn::IfThenElse(neg, hn::Neg(acn), acn);
            const V sin_abs = hn::Sqrt(hn::Max(hn::NegMulAdd(cos_n, cos_n, one), zero));
            const V sin_n = hn::IfThenElse(neg, hn::Neg(sin_abs), sin_abs);
            const V inv_pn = hn::Div(one, hn::Max(pn_len, hn::Set(d, 1e-6f)));
            // A sample's direction (q times inv_len: unit) as a horizon of the slice, a cosine
            // from the view vector. The pixel grid puts most samples a little off the slice's
            // plane, and their angle from the view vector is then not their angle within the
            // slice: on a surface seen at a grazing angle, a neighbour on the same plane came out
            // high above its tangent (a flat Cycles ground 0.38-0.55 open with one slice). So
            // the sample keeps what decides its occlusion, its elevation above the tangent plane
            // (its sine: n.q over the projected normal's length, exact within the slice), turned
            // from the side's tangent direction toward the normal (beyond the normal where the
            // sample lies beyond it), at most to the view vector.
            const auto horizon_cos = [&](V qx, V qy, V qz, V inv_len, bool side1) {
                const V qv = hn::Mul(Dot(qx, qy, qz, view_x, view_y, view_z), inv_len);
                const V qo = hn::Mul(Dot(qx, qy, qz, or_x, or_y, or_z), inv_len);
                const V se =
                    hn::Min(hn::Max(hn::Mul(hn::Mul(Dot(qx, qy, qz, nx, ny, nz), inv_len), inv_pn),
                                    hn::Set(d, -1.0f)),
                            one);
                const V ce_abs = hn::Sqrt(hn::Max(hn::NegMulAdd(se, se, one), zero));
                // The tangential part: q along the side's tangent direction.
                const V tt = side1 ? hn::Sub(hn::Mul(cos_n, qo), hn::Mul(sin_n, qv))
                                   : hn::Sub(hn::Mul(sin_n, qv), hn::Mul(cos_n, qo));
                const V ce = hn::IfThenElse(hn::Lt(tt, zero), hn::Neg(ce_abs), ce_abs);
                // side 1: the angle hi - e from the view vector; side 0: lo + e.
                const V ch = side1 ? hn::Sub(hn::Mul(cos_n, se), hn::Mul(sin_n, ce))
                                   : hn::MulAdd(cos_n, se, hn::Mul(sin_n, ce));
                const auto past_view =
                    side1 ? hn::Lt(hn::MulAdd(sin_n, se, hn::Mul(cos_n, ce)), zero)
                          : hn::Gt(hn::Sub(hn::Mul(sin_n, se), hn::Mul(cos_n, ce)), zero);
                return hn::IfThenElse(past_view, one, ch);
            };
            // The visibility bitmask: the hemisphere about the projected normal, lo .. hi from
            // the view vector, cut into 32 sectors of equal cosine-weighted measure (so that a
            // sector's share is its count); cum(lo) and the whole measure from gtao.h's arcs.
            const V lo = hn::Sub(ang_n, hn::Set(d, kHalfPi)),
                    hi = hn::Add(ang_n, hn::Set(d, kHalfPi));
            const V cum_lo = hn::Neg(Arc(d, lo, sin_n, hn::Neg(cos_n), cos_n, sin_n));
            const V measure = hn::Sub(Arc(d, hi, hn::Neg(sin_n), cos_n, cos_n, sin_n), cum_lo);
            const V inv_measure = hn::Div(one, hn::Max(measure, hn::Set(d, 1e-12f)));
            auto sectors = hn::Zero(di);
            // The sector coordinate (0 .. 1) of the direction at cosine c from the view vector
            // on side `side1` of the slice: its cumulative measure from lo.
            const auto sector_of = [&](V c, bool side1) {
                const V a = FastAcos(d, c);
                const V sa = hn::Sqrt(hn::Max(hn::NegMulAdd(c, c, one), zero));
                const V th = side1 ? a : hn::Neg(a);
                const V arc = Arc(d, th, c, side1 ? sa : hn::Neg(sa), cos_n, sin_n);
                const V u = hn::Mul(hn::Sub(side1 ? arc : hn::Neg(arc), cum_lo), inv_measure);
                return hn::IfThenElse(hn::Gt(th, hi), one, hn::IfThenElse(hn::Lt(th, lo), zero, u));
            };
            // Sectors hidden by a surface point q (from the point) with front cosine cf: from q
            // to q pushed `thickness` of camera depth away along its ray r, where `ok`.
            const auto occlude =
                [&](auto ok, V cf, V qx, V qy, V qz, V rx, V ry, V rz, V th, bool side1) {
                    const V bx = hn::MulAdd(th, rx, qx), by = hn::MulAdd(th, ry, qy),
                            bz = hn::MulAdd(th, rz, qz);
                    const V cb =
                        hn::Div(Dot(bx, by, bz, view_x, view_y, view_z),
                                hn::Sqrt(hn::Max(Dot(bx, by, bz, bx, by, bz), hn::Set(d, 1e-24f))));
                    const V uf = sector_of(cf, side1), ub = sector_of(cb, side1);
                    const V s32 = hn::Set(d, 32.0f);
                    const auto to_index = [&](V u) {
                        const auto i = hn::ConvertTo(di, hn::Floor(hn::MulAdd(u, s32, half)));
                        return hn::Min(hn::Max(i, hn::Zero(di)), hn::Set(di, 32));
                    };
                    const auto ia = to_index(hn::Min(uf, ub)), ib = to_index(hn::Max(uf, ub));
                    const auto bits = hn::AndNot(hn::GatherIndex(di, kLowMask, ia),
                                                 hn::GatherIndex(di, kLowMask, ib));
                    sectors = hn::Or(sectors, hn::IfThenElseZero(hn::RebindMask(di, ok), bits));
                };
            // Lowest horizons: the tangent plane, n - pi/2 (side 0) and n + pi/2 (side 1), as
            // cosines from the view vector.
            V hc[2] = {sin_n, hn::Neg(sin_n)};
            for (int side_i = 0; side_i < 2; ++side_i) {
                const V step_x = side_i == 0 ? hn::Neg(dx) : dx;
                const V step_y = side_i == 0 ? hn::Neg(dy) : dy;
                auto alive = active;
                auto have_prev = hn::Lt(one, zero);  // all false
                V prev_x = zero, prev_y = zero, prev_z = zero;
                V prev_depth = zero;  // the last sample's depth and pixel, for the gate
                auto prev_idx = hn::Zero(di);
                V h = hc[side_i];
                for (int k = 0; k < p.steps; ++k) {
                    // Quadratic spacing, as gtao.h says.
                    const V t = hn::Mul(hn::Add(hn::Set(d, float(k)), jitter),
                                        hn::Set(d, 1.0f / float(p.steps)));
                    const V dist = hn::Max(one, hn::Mul(hn::Mul(t, t), radius_px));
                    const V sxf = hn::Floor(hn::MulAdd(dist, step_x, hn::Add(x, half)));
                    const V syf = hn::Floor(hn::MulAdd(dist, step_y, hn::Add(vy, half)));
                    // Off screen: nothing known beyond, this side of the slice ends.
                    alive = hn::And(alive,
                                    hn::And(hn::And(hn::Ge(sxf, zero), hn::Ge(syf, zero)),
                                            hn::And(hn::Lt(sxf, width), hn::Lt(syf, height))));
                    if (hn::AllFalse(d, alive)) {
                        break;
                    }
                    const auto sxi = hn::ConvertTo(di, hn::IfThenElseZero(alive, sxf));
                    const auto syi = hn::ConvertTo(di, hn::IfThenElseZero(alive, syf));
                    const auto sidx = hn::Add(hn::Mul(syi, width_i), sxi);
                    const V sz = hn::GatherIndex(d, p.depth, sidx);
                    // The sample's pixel in the maps (on their grid, the one nearest to it);
                    // without a map nothing reads it.
                    const auto midx =
                        maps ? hn::Add(
                                   hn::Mul(hn::Min(hn::ShiftRightSame(hn::Add(syi, map_round),
                                                                      p.map_shift),
                                                   map_last_y),
                                           map_w),
                                   hn::Min(hn::ShiftRightSame(hn::Add(sxi, map_round), p.map_shift),
                                           map_last_x))
                             : sidx;
                    const auto valid = hn::And(alive, hn::And(hn::Gt(sz, zero), hn::IsFinite(sz)));
                    const V szc = hn::IfThenElse(valid, sz, one);
                    const V su = hn::Mul(hn::Add(sxf, half), vinv_w);
                    const V svv = hn::Mul(hn::Add(syf, half), vinv_h);
                    const V sr_x = hn::MulAdd(svv, dv_x, hn::MulAdd(su, du_x, o_x));
                    const V sr_y = hn::MulAdd(svv, dv_y, hn::MulAdd(su, du_y, o_y));
                    const V sr_z = hn::MulAdd(svv, dv_z, hn::MulAdd(su, du_z, o_z));
                    const V q_x = hn::Sub(hn::MulAdd(szc, sr_x, cam_x), pos_x);
                    const V q_y = hn::Sub(hn::MulAdd(szc, sr_y, cam_y), pos_y);
                    const V q_z = hn::Sub(hn::MulAdd(szc, sr_z, cam_z), pos_z);
                    const V len2 = Dot(q_x, q_y, q_z, q_x, q_y, q_z);
                    const auto in_range =
                        hn::And(valid, hn::And(hn::Le(len2, r2), hn::Ge(len2, hn::Set(d, 1e-12f))));
                    // The bitmask's sectors take the direction's own angle from the view
                    // vector (its elevation measured worse on the Cycles yard: 0.0945 against
                    // 0.0753 at full resolution).
                    const V c =
                        kBitmask
                            ? hn::Div(Dot(q_x, q_y, q_z, view_x, view_y, view_z),
                                      hn::Sqrt(hn::Max(len2, hn::Set(d, 1e-24f))))
                            : horizon_cos(q_x,
                                          q_y,
                                          q_z,
                                          hn::Div(one, hn::Sqrt(hn::Max(len2, hn::Set(d, 1e-24f)))),
                                          side_i == 1);
                    // The sample's surface depth: its pixel's own where a map gives one
                    // (at most `thickness` for the bitmask).
                    const V th = p.thickness_map
                                     ? hn::Min(hn::GatherIndex(d, p.thickness_map, midx),
                                               hn::Set(d, p.thickness))
                                     : hn::Set(d, p.thickness);
                    if constexpr (kBitmask) {
                        occlude(in_range, c, q_x, q_y, q_z, sr_x, sr_y, sr_z, th, side_i == 1);
                    } else {
                        h = hn::IfThenElse(in_range, hn::Max(h, c), h);
                    }
                    // Just beyond the radius of a sample inside it: the straight surface in
                    // between crosses the radius there (a larger jump is a depth edge).
                    const auto beyond = hn::And(valid, hn::Gt(len2, r2));
                    const auto crossing =
                        hn::And(hn::And(beyond, have_prev), hn::Lt(len2, four_r2));
                    if (!hn::AllFalse(d, crossing)) {
                        const V a_x = hn::Sub(q_x, prev_x), a_y = hn::Sub(q_y, prev_y),
                                a_z = hn::Sub(q_z, prev_z);
                        const V aa = Dot(a_x, a_y, a_z, a_x, a_y, a_z);
                        const V b = Dot(prev_x, prev_y, prev_z, a_x, a_y, a_z);
                        const V cc =
                            hn::Sub(Dot(prev_x, prev_y, prev_z, prev_x, prev_y, prev_z), r2);
                        const V disc = hn::NegMulAdd(aa, cc, hn::Mul(b, b));
                        auto ok = hn::And(crossing, hn::And(hn::Gt(aa, zero), hn::Ge(disc, zero)));
                        if (p.reach_map) {
                            // A surface between the two is there only if the nearer one reaches
                            // back to the farther one's depth (by the reach map): else the jump
                            // is a silhouette with empty space behind it.
                            const auto q_nearer = hn::Lt(szc, prev_depth);
                            const V reach = hn::GatherIndex(
                                d,
                                p.reach_map,
                                hn::IfThenElse(hn::RebindMask(di, q_nearer), midx, prev_idx));
                            ok = hn::And(ok, hn::Le(hn::Abs(hn::Sub(szc, prev_depth)), reach));
                        }
                        const V uu = hn::Div(hn::Sub(hn::Sqrt(hn::Max(disc, zero)), b),
                                             hn::IfThenElse(ok, aa, one));
                        const V x_x = hn::MulAdd(uu, a_x, prev_x),
                                x_y = hn::MulAdd(uu, a_y, prev_y),
                                x_z = hn::MulAdd(uu, a_z, prev_z);
                        if constexpr (kBitmask) {
                            const V cq =
                                hn::Mul(Dot(x_x, x_y, x_z, view_x, view_y, view_z), inv_radius);
                            occlude(ok, cq, x_x, x_y, x_z, sr_x, sr_y, sr_z, th, side_i == 1);
                        } else {
                            const V cq = horizon_cos(x_x, x_y, x_z, inv_radius, side_i == 1);
                            h = hn::IfThenElse(ok, hn::Max(h, cq), h);
                        }
                    }
                    // The last sample inside the radius: kept through samples too close to
                    // matter, forgotten at a missing depth or beyond the radius.
                    const auto forget = hn::Or(hn::AndNot(valid, alive), beyond);
                    have_prev = hn::Or(in_range, hn::AndNot(forget, have_prev));
                    prev_x = hn::IfThenElse(in_range, q_x, prev_x);
                    prev_depth = hn::IfThenElse(in_range, szc, prev_depth);
                    prev_idx = hn::IfThenElse(hn::RebindMask(di, in_range), midx, prev_idx);
                    prev_y = hn::IfThenElse(in_range, q_y, prev_y);
                    prev_z = hn::IfThenElse(in_range, q_z, prev_z);
                }
                hc[side_i] = h;
            }
            if constexpr (kBitmask) {
                const V open = hn::Sub(
                    hn::Set(d, 32.0f),
                    hn::ConvertTo(
                        d, hn::BitCast(di, hn::PopulationCount(hn::BitCast(du32, sectors)))));
                const V vis = hn::Mul(hn::Mul(measure, open), hn::Set(d, 1.0f / 32.0f));
                visibility =
                    hn::Add(visibility, hn::IfThenElseZero(slice_ok, hn::Mul(pn_len, vis)));
                continue;
            }
            // Horizon angles (side 0 negative), at most pi/2 from the normal.
            V h0 = hn::Neg(FastAcos(d, hc[0])), h1 = FastAcos(d, hc[1]);
            V c0 = hc[0], s0 = hn::Neg(hn::Sqrt(hn::Max(hn::NegMulAdd(c0, c0, one), zero)));
            V c1 = hc[1], s1 = hn::Sqrt(hn::Max(hn::NegMulAdd(c1, c1, one), zero));
            const auto clamp0 = hn::Lt(h0, lo), clamp1 = hn::Gt(h1, hi);
            h0 = hn::IfThenElse(clamp0, lo, h0);
            c0 = hn::IfThenElse(clamp0, sin_n, c0);  // cos(n - pi/2)
            s0 = hn::IfThenElse(clamp0, hn::Neg(cos_n), s0);
            h1 = hn::IfThenElse(clamp1, hi, h1);
            c1 = hn::IfThenElse(clamp1, hn::Neg(sin_n), c1);  // cos(n + pi/2)
            s1 = hn::IfThenElse(clamp1, cos_n, s1);
            const V arcs =
                hn::Add(Arc(d, h0, c0, s0, cos_n, sin_n), Arc(d, h1, c1, s1, cos_n, sin_n));
            visibility = hn::Add(visibility, hn::IfThenElseZero(slice_ok, hn::Mul(pn_len, arcs)));
        }
        // The mean over slices (unoccluded, the mean over all slice directions is exactly 1).
        const V ao = hn::Mul(visibility, hn::Set(d, 1.0f / float(p.slices)));
        hn::StoreU(hn::IfThenElse(active, ao, one), d, out + i0);
    }
}

void GtaoRow(const GtaoKernelParams &p,
             int oy,
             const float *zs,
             const float *nxs,
             const float *nys,
             const float *nzs,
             const std::int32_t *rots,
             const float *jits,
             int n,
             float *out)
{
    if (p.thickness > 0.0f) {
        GtaoRowT<true>(p, oy, zs, nxs, nys, nzs, rots, jits, n, out);
    } else {
        GtaoRowT<false>(p, oy, zs, nxs, nys, nzs, rots, jits, n, out);
    }
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(GtaoRow);

void gtao_row(const GtaoKernelParams &p,
              int oy,
              const float *z,
              const float *nx,
              const float *ny,
              const float *nz,
              const std::int32_t *rot,
              const float *jitter,
              int n,
              float *out)
{
    HWY_DYNAMIC_DISPATCH(GtaoRow)(p, oy, z, nx, ny, nz, rot, jitter, n, out);
}

}  // namespace posthaste::shading
#endif  // HWY_ONCE
