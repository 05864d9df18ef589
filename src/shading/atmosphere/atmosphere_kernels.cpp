// The atmosphere's per-pixel kernels over Highway (see atmosphere_kernels.h and, for the model,
// atmosphere.h).

// Highway's foreach_target.h comes first, then highway.h, then any -inl.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/atmosphere/atmosphere_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include "core/hwy_math-inl.h"
// clang-format on

#include "shading/atmosphere/atmosphere_kernels.h"

#include <cstddef>
#include <limits>

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;
namespace sm = posthaste::simd::HWY_NAMESPACE;

constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);
constexpr float kPi = 3.14159265358979f;

template <class D, class V = hn::Vec<D>>
HWY_INLINE V Saturate(D d, V x)
{
    return hn::Min(hn::Max(x, hn::Zero(d)), hn::Set(d, 1.0f));  // NaN -> 0 or 1: finite
}

/// shading::fast_acos (Abramowitz and Stegun 4.4.46) lane by lane; NaN reads as 1.
template <class D, class V = hn::Vec<D>>
HWY_INLINE V FastAcos(D d, V x)
{
    const V ax = hn::Min(hn::Abs(x), hn::Set(d, 1.0f));
    V p = hn::Set(d, -0.0012624911f);
    p = hn::MulAdd(p, ax, hn::Set(d, 0.0066700901f));
    p = hn::MulAdd(p, ax, hn::Set(d, -0.0170881256f));
    p = hn::MulAdd(p, ax, hn::Set(d, 0.0308918810f));
    p = hn::MulAdd(p, ax, hn::Set(d, -0.0501743046f));
    p = hn::MulAdd(p, ax, hn::Set(d, 0.0889789874f));
    p = hn::MulAdd(p, ax, hn::Set(d, -0.2145988016f));
    p = hn::MulAdd(p, ax, hn::Set(d, 1.5707963050f));
    const V r = hn::Mul(hn::Sqrt(hn::Sub(hn::Set(d, 1.0f), ax)), p);
    return hn::IfThenElse(hn::Lt(x, hn::Zero(d)), hn::Sub(hn::Set(d, kPi), r), r);
}

/// SkyView::radiance's (u, s, above) for unit directions (dx, dy, dz).
template <class D, class V = hn::Vec<D>>
HWY_INLINE void SkyCoords(
    D d, const SkyCoordParams &p, V dx, V dy, V dz, V &u, V &s, hn::Mask<D> &above)
{
    const auto dot = [&](const float *v) {
        return sm::Dot3(dx, dy, dz, hn::Set(d, v[0]), hn::Set(d, v[1]), hn::Set(d, v[2]));
    };
    const V mu = dot(p.up), along = dot(p.sun_tangent), side = dot(p.sun_side);
    // u = sin(azimuth / 2) = sqrt((1 - cos azimuth) / 2).
    const V h = hn::Sqrt(hn::MulAdd(along, along, hn::Mul(side, side)));
    const V tiny = hn::Set(d, 1e-12f);
    const V cos_az =
        hn::IfThenElse(hn::Gt(h, tiny), hn::Div(along, hn::Max(h, tiny)), hn::Set(d, 1.0f));
    u = hn::Sqrt(hn::Max(hn::NegMulAdd(hn::Set(d, 0.5f), cos_az, hn::Set(d, 0.5f)), hn::Zero(d)));
    const V theta = FastAcos(d, mu);
    const V s_above =
        hn::Sub(hn::Set(d, 1.0f),
                hn::Sqrt(Saturate(
                    d, hn::NegMulAdd(theta, hn::Set(d, p.inv_theta_above), hn::Set(d, 1.0f)))));
    const V s_below = hn::Sqrt(Saturate(
        d, hn::Mul(hn::Sub(theta, hn::Set(d, p.theta_horizon)), hn::Set(d, p.inv_theta_below))));
    above = hn::Not(hn::Lt(mu, hn::Set(d, p.mu_horizon)));  // NaN: above
    s = hn::IfThenElse(above, s_above, s_below);
}

/// The sky-view LUT's bilinear lookup (Lut2D::sample_rows on the half above or below the
/// horizon) at (u, s) of one lane, its texels read as four-float vectors where the target has
/// them (the table has a padding texel at its end); a vector of gathers was slower on AVX2.
HWY_INLINE void SkyLookupLane(const SkyCoordParams &p, float u, float s, bool above, float *rgb)
{
    const int half = p.lut_height / 2;
    const int rows = above ? half : p.lut_height - half, row0 = above ? 0 : half;
    const float fx = (u > 0.0f ? (u < 1.0f ? u : 1.0f) : 0.0f) * float(p.lut_width - 1);
    const float fy = (s > 0.0f ? (s < 1.0f ? s : 1.0f) : 0.0f) * float(rows - 1);
    const int x0 = int(fx) < p.lut_width - 2 ? int(fx) : p.lut_width - 2;
    const int y0 = int(fy) < rows - 2 ? int(fy) : rows - 2;
    const float tx = fx - float(x0), ty = fy - float(y0);
    const float *t0 = p.lut + (std::size_t(row0 + y0) * std::size_t(p.lut_width) + x0) * 3;
    const float *t1 = t0 + std::size_t(p.lut_width) * 3;
    const hn::CappedTag<float, 4> d4;
    if constexpr (hn::MaxLanes(decltype(d4)()) >= 4) {
        const auto vtx = hn::Set(d4, tx);
        const auto a = hn::LoadU(d4, t0), b = hn::LoadU(d4, t0 + 3);
        const auto c = hn::LoadU(d4, t1), e = hn::LoadU(d4, t1 + 3);
        const auto top = hn::MulAdd(vtx, hn::Sub(b, a), a);
        const auto bottom = hn::MulAdd(vtx, hn::Sub(e, c), c);
        HWY_ALIGN float out[4];
        hn::Store(hn::MulAdd(hn::Set(d4, ty), hn::Sub(bottom, top), top), d4, out);
        rgb[0] = out[0];
        rgb[1] = out[1];
        rgb[2] = out[2];
    } else {
        for (int k = 0; k < 3; ++k) {
            const float top = t0[k] + tx * (t0[3 + k] - t0[k]);
            const float bottom = t1[k] + tx * (t1[3 + k] - t1[k]);
            rgb[k] = top + ty * (bottom - top);
        }
    }
}

void SkyRadianceN(
    const SkyCoordParams &p, const float *x, const float *y, const float *z, int n, float *rgb)
{
    const hn::ScalableTag<float> d;
    const int lanes = int(hn::Lanes(d));
    HWY_ALIGN float bx[kMaxLanes], by[kMaxLanes], bz[kMaxLanes], bu[kMaxLanes], bs[kMaxLanes];
    for (int i = 0; i < n; i += lanes) {
        const int m = n - i < lanes ? n - i : lanes;
        for (int l = 0; l < lanes; ++l) {
            bx[l] = l < m ? x[i + l] : 0.0f;
            by[l] = l < m ? y[i + l] : 1.0f;
            bz[l] = l < m ? z[i + l] : 0.0f;
        }
        hn::Vec<decltype(d)> u, s;
        hn::Mask<decltype(d)> above;
        SkyCoords(d, p, hn::Load(d, bx), hn::Load(d, by), hn::Load(d, bz), u, s, above);
        hn::Store(u, d, bu);
        hn::Store(s, d, bs);
        std::uint8_t bits[kMaxLanes / 8 + 8] = {};
        hn::StoreMaskBits(d, above, bits);
        for (int l = 0; l < m; ++l) {
            SkyLookupLane(
                p, bu[l], bs[l], (bits[l >> 3] >> (l & 7)) & 1u, rgb + 3 * std::size_t(i + l));
        }
    }
}

using D8 = hn::CappedTag<float, 8>;

// The froxel at the camera: in-scatter 0, transmittance 1.
constexpr float kCamera[8] = {0, 0, 0, 0, 1, 1, 1, 1};

/// Froxel bilinear at column (cx + tx, row cy + ty) of slice z: floats o .. o + Lanes(d) - 1 of
/// its eight (in-scatter RGB0, transmittance RGB1).
template <class D>
HWY_INLINE hn::Vec<D> FroxelBilinear(
    D d, const AtmosphereRowParams &p, int z, int cx, float tx, int o = 0)
{
    const float *f =
        p.froxels +
        ((std::size_t(z) * std::size_t(p.ap_height) + std::size_t(p.cy)) * std::size_t(p.ap_width) +
         std::size_t(cx)) *
            8 +
        o;
    const std::size_t row = std::size_t(p.ap_width) * 8;
    const auto vtx = hn::Set(d, tx);
    const auto a = hn::LoadU(d, f), b = hn::LoadU(d, f + 8);
    const auto c = hn::LoadU(d, f + row), e = hn::LoadU(d, f + row + 8);
    const auto top = hn::MulAdd(vtx, hn::Sub(b, a), a);
    const auto bottom = hn::MulAdd(vtx, hn::Sub(e, c), c);
    return hn::MulAdd(hn::Set(d, p.ty), hn::Sub(bottom, top), top);
}

/// All eight floats of FroxelBilinear into out, a capped vector at a time (targets narrower
/// than eight lanes).
HWY_INLINE void FroxelBilinear8(const AtmosphereRowParams &p, int z, int cx, float tx, float *out)
{
    const D8 d8;
    for (int o = 0; o < 8; o += int(hn::Lanes(d8))) {
        hn::StoreU(FroxelBilinear(d8, p, z, cx, tx, o), d8, out + o);
    }
}

/// The froxels' blend at one pixel q (slice z0, -1 before the first centre; column cx + tx;
/// weight tz between the slices), then pixel * T + S on its RGB (alpha * 1 + 0 with four
/// channels).
template <class D>
HWY_INLINE void FroxelComposite(
    D d8, const AtmosphereRowParams &p, int z0, int cx, float tx, float tz, float *q, int channels)
{
    const hn::CappedTag<float, 4> d4;
#if HWY_TARGET != HWY_SCALAR  // (no UpperHalf on the one-lane target)
    if constexpr (hn::MaxLanes(D()) == 8) {
        // A froxel in one register: blend there, then pixel * T + S from its halves.
        const D d8v;
        const auto vtz = hn::Set(d8v, tz);
        auto s = FroxelBilinear(d8v, p, z0 < 0 ? 0 : z0, cx, tx);
        if (z0 < 0) {
            // From (in-scatter 0, transmittance 1) at the camera to slice 0.
            const auto c = hn::LoadU(d8v, kCamera);
            s = hn::MulAdd(vtz, hn::Sub(s, c), c);
        } else {
            const auto b = FroxelBilinear(d8v, p, z0 + 1, cx, tx);
            s = hn::MulAdd(vtz, hn::Sub(b, s), s);
        }
        const hn::Half<D> dh;
        const auto in = hn::LowerHalf(dh, s), tr = hn::UpperHalf(dh, s);
        if (channels == 4) {
            // Alpha * 1 + 0: it passes through exactly.
            hn::StoreU(hn::MulAdd(hn::LoadU(dh, q), tr, in), dh, q);
        } else {
            HWY_ALIGN float o4[4];
            const float q3[4] = {q[0], q[1], q[2], 0.0f};
            hn::Store(hn::MulAdd(hn::LoadU(dh, q3), tr, in), dh, o4);
            q[0] = o4[0];
            q[1] = o4[1];
            q[2] = o4[2];
        }
        return;
    }
#endif
    HWY_ALIGN float a[8], b[8];
    const auto vtz = hn::Set(d8, tz);
    if (z0 < 0) {
        // From (in-scatter 0, transmittance 1) at the camera to slice 0.
        FroxelBilinear8(p, 0, cx, tx, a);
        for (int o = 0; o < 8; o += int(hn::Lanes(d8))) {
            const auto c = hn::LoadU(d8, kCamera + o);
            hn::Store(hn::MulAdd(vtz, hn::Sub(hn::Load(d8, a + o), c), c), d8, a + o);
        }
    } else {
        FroxelBilinear8(p, z0, cx, tx, a);
        FroxelBilinear8(p, z0 + 1, cx, tx, b);
        for (int o = 0; o < 8; o += int(hn::Lanes(d8))) {
            const auto va = hn::Load(d8, a + o);
            hn::Store(hn::MulAdd(vtz, hn::Sub(hn::Load(d8, b + o), va), va), d8, a + o);
        }
    }
    // pixel * T + S, alpha * 1 + 0 when there are four channels.
    const int cs = channels == 4 ? 4 : 3;
    for (int o = 0; o < cs; o += int(hn::Lanes(d4))) {
        if (o + int(hn::Lanes(d4)) <= cs) {
            hn::StoreU(
                hn::MulAdd(hn::LoadU(d4, q + o), hn::Load(d4, a + 4 + o), hn::Load(d4, a + o)),
                d4,
                q + o);
        } else {
            for (int c = o; c < cs; ++c) {
                const hn::CappedTag<float, 1> d1;
                q[c] = hn::GetLane(
                    hn::MulAdd(hn::Set(d1, q[c]), hn::Set(d1, a[4 + c]), hn::Set(d1, a[c])));
            }
        }
    }
}

int AtmosphereRow(const AtmosphereRowParams &params,
                  const float *z,
                  float *px,
                  int channels,
                  int n,
                  std::int32_t *disc_x,
                  float *disc_dir)
{
    // A local copy: stores to the pixels cannot alias it, so its fields stay in registers.
    const AtmosphereRowParams p = params;
    const hn::ScalableTag<float> d;
    const hn::RebindToSigned<decltype(d)> di;
    using V = hn::Vec<decltype(d)>;
    const int lanes = int(hn::Lanes(d));
    const V inf = hn::Set(d, std::numeric_limits<float>::infinity());
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    HWY_ALIGN float txs[kMaxLanes], tzs[kMaxLanes], us[kMaxLanes], ss[kMaxLanes];
    HWY_ALIGN float dxs[kMaxLanes], dys[kMaxLanes], dzs[kMaxLanes];
    HWY_ALIGN std::int32_t cxs[kMaxLanes], z0s[kMaxLanes];
    int listed = 0;
    for (int x = 0; x < n; x += lanes) {
        const int m = n - x < lanes ? n - x : lanes;
        V depth;
        if (m == lanes) {
            depth = hn::LoadU(d, z + x);
        } else {
            HWY_ALIGN float tail[kMaxLanes];
            for (int l = 0; l < lanes; ++l) {
                tail[l] = l < m ? z[x + l] : std::numeric_limits<float>::quiet_NaN();
            }
            depth = hn::Load(d, tail);
        }
        const V u =
            hn::Mul(hn::Add(hn::Set(d, float(x) + 0.5f), hn::Iota(d, 0.0f)), hn::Set(d, p.inv_w));
        const V rx = hn::MulAdd(u, hn::Set(d, p.du[0]), hn::Set(d, p.origin[0]));
        const V ry = hn::MulAdd(u, hn::Set(d, p.du[1]), hn::Set(d, p.origin[1]));
        const V rz = hn::MulAdd(u, hn::Set(d, p.du[2]), hn::Set(d, p.origin[2]));
        const V len = hn::Sqrt(sm::Dot3(rx, ry, rz, rx, ry, rz));
        const auto finite = hn::Lt(depth, inf);
        const auto is_sky = hn::Eq(depth, inf);
        std::uint8_t finite_bits[kMaxLanes / 8 + 8] = {}, sky_bits[kMaxLanes / 8 + 8] = {};
        const bool any_finite = !hn::AllFalse(d, finite);
        const bool any_sky = p.sky && !hn::AllFalse(d, is_sky);
        if (any_finite) {
            // AerialPerspective::sample at distance depth * len.
            const V fx =
                hn::Sub(hn::Mul(Saturate(d, u), hn::Set(d, float(p.ap_width))), hn::Set(d, 0.5f));
            auto cx = hn::Sub(hn::ConvertTo(di, hn::Add(fx, one)), hn::Set(di, 1));
            cx = hn::Max(hn::Min(cx, hn::Set(di, p.ap_width - 2)), hn::Zero(di));
            const V tx = Saturate(d, hn::Sub(fx, hn::ConvertTo(d, cx)));
            const V w =
                hn::Sqrt(Saturate(d, hn::Mul(hn::Mul(depth, len), hn::Set(d, p.inv_max_distance))));
            const V fz = hn::MulSub(w, hn::Set(d, float(p.slices)), hn::Set(d, 0.5f));
            const auto near = hn::Lt(fz, zero);
            // Before the first slice centre: the blend from the camera, (2 w slices)^2.
            const V w0 = hn::Mul(hn::Set(d, 2.0f * float(p.slices)), w);
            const V tz_near = Saturate(d, hn::Mul(w0, w0));
            const auto z0 =
                hn::Min(hn::ConvertTo(di, hn::Max(fz, zero)), hn::Set(di, p.slices - 2));
            const V z0f = hn::ConvertTo(d, z0);
            const V wa = hn::Mul(hn::Add(z0f, hn::Set(d, 0.5f)), hn::Set(d, p.inv_slices));
            const V ics = hn::GatherIndex(d, p.inv_centre_sum, z0);
            const V tz_far = Saturate(d, hn::Mul(hn::Mul(hn::Sub(fz, z0f), hn::Add(w, wa)), ics));
            hn::Store(tx, d, txs);
            hn::Store(hn::IfThenElse(near, tz_near, tz_far), d, tzs);
            hn::Store(cx, di, cxs);
            // Lanes before the first centre blend from the camera: slice -1.
            hn::Store(hn::IfThenElse(hn::RebindMask(di, near), hn::Set(di, -1), z0), di, z0s);
            hn::StoreMaskBits(d, finite, finite_bits);
        }
        if (any_sky) {
            const V inv_len = hn::Div(one, len);
            const V dx = hn::Mul(rx, inv_len), dy = hn::Mul(ry, inv_len), dz = hn::Mul(rz, inv_len);
            V su, ssv;
            hn::Mask<decltype(d)> above;
            SkyCoords(d, p.sky_coords, dx, dy, dz, su, ssv, above);
            std::uint8_t above_bits[kMaxLanes / 8 + 8] = {};
            hn::StoreMaskBits(d, above, above_bits);
            std::uint8_t disc_bits[kMaxLanes / 8 + 8] = {};
            if (p.sun_disc) {
                const V c = sm::Dot3(
                    dx, dy, dz, hn::Set(d, p.sun[0]), hn::Set(d, p.sun[1]), hn::Set(d, p.sun[2]));
                hn::StoreMaskBits(d, hn::And(is_sky, hn::Ge(c, hn::Set(d, p.cos_sun))), disc_bits);
            }
            hn::StoreMaskBits(d, is_sky, sky_bits);
            hn::Store(su, d, us);
            hn::Store(ssv, d, ss);
            hn::Store(dx, d, dxs);
            hn::Store(dy, d, dys);
            hn::Store(dz, d, dzs);
            for (int l = 0; l < m; ++l) {
                if (!((sky_bits[l >> 3] >> (l & 7)) & 1u)) {
                    continue;
                }
                SkyLookupLane(p.sky_coords,
                              us[l],
                              ss[l],
                              (above_bits[l >> 3] >> (l & 7)) & 1u,
                              px + std::size_t(x + l) * std::size_t(channels));
                if ((disc_bits[l >> 3] >> (l & 7)) & 1u) {
                    disc_x[listed] = x + l;
                    disc_dir[3 * listed] = dxs[l];
                    disc_dir[3 * listed + 1] = dys[l];
                    disc_dir[3 * listed + 2] = dzs[l];
                    ++listed;
                }
            }
        }
        if (!any_finite) {
            continue;
        }
        for (int l = 0; l < m; ++l) {
            if (!((finite_bits[l >> 3] >> (l & 7)) & 1u)) {
                continue;
            }
            FroxelComposite(D8(),
                            p,
                            z0s[l],
                            cxs[l],
                            txs[l],
                            tzs[l],
                            px + std::size_t(x + l) * std::size_t(channels),
                            channels);
        }
    }
    return listed;
}

}  // namespace posthaste::shading::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading {

HWY_EXPORT(SkyRadianceN);
HWY_EXPORT(AtmosphereRow);

void sky_view_radiance(
    const SkyCoordParams &p, const float *x, const float *y, const float *z, int n, float *rgb)
{
    HWY_DYNAMIC_DISPATCH(SkyRadianceN)(p, x, y, z, n, rgb);
}

int atmosphere_row(const AtmosphereRowParams &p,
                   const float *z,
                   float *px,
                   int channels,
                   int n,
                   std::int32_t *disc_x,
                   float *disc_dir)
{
    return HWY_DYNAMIC_DISPATCH(AtmosphereRow)(p, z, px, channels, n, disc_x, disc_dir);
}

}  // namespace posthaste::shading
#endif
