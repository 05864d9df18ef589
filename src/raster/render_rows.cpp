// The rasterizer's data-pass rows: depth and motion of the visible surfaces, one source over
// Highway's lane types for every target (compiled without FMA contraction, CMakeLists.txt, so
// every target gives the same bits: the data passes are compared bit for bit).

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "raster/render_rows.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
// clang-format on

#include <algorithm>
#include <cstdint>
#include <limits>

#include "raster/render_detail.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::raster::render_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using V = hn::Vec<D>;
constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// Row `row` of m times (x, y, z, w) in mul()'s order: (m0 x + m1 y) + (m2 z + m3 w).
HWY_INLINE V MulRow(const glm::mat4 &m, int row, V x, V y, V z, V w)
{
    const D d;
    const V a = hn::Mul(hn::Set(d, m[0][row]), x), b = hn::Mul(hn::Set(d, m[1][row]), y);
    const V c = hn::Mul(hn::Set(d, m[2][row]), z), e = hn::Mul(hn::Set(d, m[3][row]), w);
    return hn::Add(hn::Add(a, b), hn::Add(c, e));
}

/// Depth (to depth[0..], if not null) and motion (x, y interleaved to motion[0..], if not null)
/// of one vector of pixels: position (surface) or ray direction (sky lanes), previous position.
HWY_INLINE void DepthMotionVector(const DepthMotionParams &q,
                                  hn::Mask<D> sky,
                                  V x,
                                  V y,
                                  V z,
                                  V qx,
                                  V qy,
                                  V qz,
                                  float *depth,
                                  float *motion)
{
    const D d;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0f);
    if (depth) {
        const V a = hn::Mul(hn::Set(d, q.zrow.x), x), b = hn::Mul(hn::Set(d, q.zrow.y), y);
        const V c = hn::Mul(hn::Set(d, q.zrow.z), z), e = hn::Mul(hn::Set(d, q.zrow.w), one);
        const V dz = hn::Add(hn::Add(a, b), hn::Add(c, e));
        hn::StoreU(
            hn::IfThenElse(sky, hn::Set(d, std::numeric_limits<float>::infinity()), dz), d, depth);
    }
    if (!motion) {
        return;
    }
    // Sky lanes project the direction (w = 0), surface lanes the point (w = 1).
    const V w = hn::IfThenZeroElse(sky, one);
    const V cx = MulRow(q.cur, 0, x, y, z, w), cy = MulRow(q.cur, 1, x, y, z, w);
    const V cw = MulRow(q.cur, 3, x, y, z, w);
    const V sx = hn::IfThenElse(sky, x, qx), sy = hn::IfThenElse(sky, y, qy);
    const V sz = hn::IfThenElse(sky, z, qz);
    const V px = MulRow(q.prev, 0, sx, sy, sz, w), py = MulRow(q.prev, 1, sx, sy, sz, w);
    const V pw = MulRow(q.prev, 3, sx, sy, sz, w);
    const auto ok = hn::And(hn::Gt(cw, zero), hn::Gt(pw, zero));
    const V ncx = hn::Div(cx, cw), ncy = hn::Div(cy, cw);
    const V npx = hn::Div(px, pw), npy = hn::Div(py, pw);
    const V W = hn::Set(d, float(q.width)), H = hn::Set(d, float(q.height));
    // Sky: (cur - prev) * size; surface: cur * size - prev * size.
    const V sky_x = hn::Mul(hn::Sub(ncx, npx), W), sky_y = hn::Mul(hn::Sub(ncy, npy), H);
    const V srf_x = hn::Sub(hn::Mul(ncx, W), hn::Mul(npx, W));
    const V srf_y = hn::Sub(hn::Mul(ncy, H), hn::Mul(npy, H));
    const V mx = hn::IfThenElseZero(ok, hn::IfThenElse(sky, sky_x, srf_x));
    const V my = hn::IfThenElseZero(ok, hn::IfThenElse(sky, sky_y, srf_y));
    hn::StoreInterleaved2(mx, my, d, motion);
}

void DepthMotion(
    const DepthMotionRow &r, int n, const DepthMotionParams &q, float *depth, float *motion)
{
    const D d;
    const hn::RebindToSigned<D> di;
    const int lanes = int(hn::Lanes(d));
    int i = 0;
    for (; i + lanes <= n; i += lanes) {
        const std::size_t k = std::size_t(i);
        const auto sky = hn::RebindMask(d, hn::Lt(hn::LoadU(di, r.sky.data() + k), hn::Zero(di)));
        DepthMotionVector(q,
                          sky,
                          hn::LoadU(d, r.px.data() + k),
                          hn::LoadU(d, r.py.data() + k),
                          hn::LoadU(d, r.pz.data() + k),
                          hn::LoadU(d, r.qx.data() + k),
                          hn::LoadU(d, r.qy.data() + k),
                          hn::LoadU(d, r.qz.data() + k),
                          depth ? depth + i : nullptr,
                          motion ? motion + 2 * i : nullptr);
    }
    if (i == n) {
        return;
    }
    // The row's last pixels through the same vector code on padded copies (the padding is a
    // surface at the origin; its results are not stored).
    const int m = n - i;
    const std::size_t k = std::size_t(i);
    HWY_ALIGN float in[6][kMaxLanes] = {};
    HWY_ALIGN std::int32_t sky[kMaxLanes] = {};
    HWY_ALIGN float out_depth[kMaxLanes], out_motion[2 * kMaxLanes];
    std::copy_n(r.px.data() + k, m, in[0]);
    std::copy_n(r.py.data() + k, m, in[1]);
    std::copy_n(r.pz.data() + k, m, in[2]);
    std::copy_n(r.qx.data() + k, m, in[3]);
    std::copy_n(r.qy.data() + k, m, in[4]);
    std::copy_n(r.qz.data() + k, m, in[5]);
    std::copy_n(r.sky.data() + k, m, sky);
    DepthMotionVector(q,
                      hn::RebindMask(d, hn::Lt(hn::Load(di, sky), hn::Zero(di))),
                      hn::Load(d, in[0]),
                      hn::Load(d, in[1]),
                      hn::Load(d, in[2]),
                      hn::Load(d, in[3]),
                      hn::Load(d, in[4]),
                      hn::Load(d, in[5]),
                      depth ? out_depth : nullptr,
                      motion ? out_motion : nullptr);
    if (depth) {
        std::copy_n(out_depth, m, depth + i);
    }
    if (motion) {
        std::copy_n(out_motion, 2 * m, motion + 2 * i);
    }
}

}  // namespace posthaste::raster::render_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace posthaste::raster::render_detail {

HWY_EXPORT(DepthMotion);

void depth_motion(
    const DepthMotionRow &r, int n, const DepthMotionParams &q, float *depth, float *motion)
{
    HWY_DYNAMIC_DISPATCH(DepthMotion)(r, n, q, depth, motion);
}

// Order this thread's streaming stores before the tile is reported done.
void stream_fence()
{
#if defined(__SSE2__)
    _mm_sfence();
#endif
}

}  // namespace posthaste::raster::render_detail
#endif
