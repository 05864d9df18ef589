// The rasterizer's data-pass rows: depth and motion of the visible surfaces, per pixel or eight
// lanes at a time with AVX2 (bit-equal: no contraction).
#include <algorithm>
#include <cmath>
#include <limits>

#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {

void depth_motion_scalar(const DepthMotionRow &r,
                         int begin,
                         int end,
                         const DepthMotionParams &q,
                         float *depth,
                         float *motion)
{
    const float W = float(q.width), H = float(q.height);
    for (int i = begin; i < end; ++i) {
        const std::size_t k = std::size_t(i);
        const glm::vec3 p(r.px[k], r.py[k], r.pz[k]);
        if (r.sky[k]) {
            if (depth) {
                depth[i] = std::numeric_limits<float>::infinity();
            }
            if (motion) {
                // A point at infinity moves with the camera rotation only.
                const glm::vec4 hc = mul(q.cur, glm::vec4(p, 0.0f));
                const glm::vec4 hp = mul(q.prev, glm::vec4(p, 0.0f));
                glm::vec2 mv(0.0f);
                if (hc.w > 0.0f && hp.w > 0.0f) {
                    mv = glm::vec2(hc.x / hc.w - hp.x / hp.w, hc.y / hc.w - hp.y / hp.w) *
                         glm::vec2(W, H);
                }
                motion[2 * i] = mv.x;
                motion[2 * i + 1] = mv.y;
            }
            continue;
        }
        if (depth) {
            depth[i] = glm::dot(q.zrow, glm::vec4(p, 1.0f));
        }
        if (motion) {
            glm::vec2 cur, prev;
            glm::vec2 mv(0.0f);
            if (to_pixel(q.cur, p, q.width, q.height, cur) &&
                to_pixel(q.prev, glm::vec3(r.qx[k], r.qy[k], r.qz[k]), q.width, q.height, prev)) {
                mv = cur - prev;
            }
            motion[2 * i] = mv.x;
            motion[2 * i + 1] = mv.y;
        }
    }
}

#if POSTHASTE_HAVE_AVX2_TARGET
// Column c of a mat4 times (x, y, z, w) in mul()'s order: (m0 x + m1 y) + (m2 z + m3 w), one row
// of the result per call.
POSTHASTE_AVX2_INLINE v8::V mul_row(const glm::mat4 &m, int row, v8::V x, v8::V y, v8::V z, v8::V w)
{
    const v8::V a = _mm256_mul_ps(_mm256_set1_ps(m[0][row]), x);
    const v8::V b = _mm256_mul_ps(_mm256_set1_ps(m[1][row]), y);
    const v8::V c = _mm256_mul_ps(_mm256_set1_ps(m[2][row]), z);
    const v8::V d = _mm256_mul_ps(_mm256_set1_ps(m[3][row]), w);
    return _mm256_add_ps(_mm256_add_ps(a, b), _mm256_add_ps(c, d));
}

// Eight pixels at a time, the same operations in the same order as depth_motion_scalar and no
// fused multiply-adds, so the same bits (the data passes are compared bit for bit).
POSTHASTE_AVX2 POSTHASTE_NO_CONTRACT void depth_motion_avx2(
    const DepthMotionRow &r, int n, const DepthMotionParams &q, float *depth, float *motion)
{
    const v8::V zero = _mm256_setzero_ps(), one = _mm256_set1_ps(1.0f);
    const v8::V W = _mm256_set1_ps(float(q.width)), H = _mm256_set1_ps(float(q.height));
    const v8::V inf = _mm256_set1_ps(std::numeric_limits<float>::infinity());
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        const std::size_t k = std::size_t(i);
        const v8::V sky = _mm256_castsi256_ps(
            _mm256_loadu_si256(reinterpret_cast<const __m256i *>(r.sky.data() + k)));
        const v8::V x = _mm256_loadu_ps(r.px.data() + k), y = _mm256_loadu_ps(r.py.data() + k);
        const v8::V z = _mm256_loadu_ps(r.pz.data() + k);
        if (depth) {
            const v8::V a = _mm256_mul_ps(_mm256_set1_ps(q.zrow.x), x);
            const v8::V b = _mm256_mul_ps(_mm256_set1_ps(q.zrow.y), y);
            const v8::V c = _mm256_mul_ps(_mm256_set1_ps(q.zrow.z), z);
            const v8::V d = _mm256_mul_ps(_mm256_set1_ps(q.zrow.w), one);
            const v8::V dz = _mm256_add_ps(_mm256_add_ps(a, b), _mm256_add_ps(c, d));
            _mm256_storeu_ps(depth + i, _mm256_blendv_ps(dz, inf, sky));
        }
        if (!motion) {
            continue;
        }
        // Sky lanes project the direction (w = 0), surface lanes the point (w = 1).
        const v8::V w = _mm256_blendv_ps(one, zero, sky);
        const v8::V cx = mul_row(q.cur, 0, x, y, z, w), cy = mul_row(q.cur, 1, x, y, z, w);
        const v8::V cw = mul_row(q.cur, 3, x, y, z, w);
        const v8::V sx = _mm256_blendv_ps(_mm256_loadu_ps(r.qx.data() + k), x, sky);
        const v8::V sy = _mm256_blendv_ps(_mm256_loadu_ps(r.qy.data() + k), y, sky);
        const v8::V sz = _mm256_blendv_ps(_mm256_loadu_ps(r.qz.data() + k), z, sky);
        const v8::V px = mul_row(q.prev, 0, sx, sy, sz, w), py = mul_row(q.prev, 1, sx, sy, sz, w);
        const v8::V pw = mul_row(q.prev, 3, sx, sy, sz, w);
        const v8::V ok =
            _mm256_and_ps(_mm256_cmp_ps(cw, zero, _CMP_GT_OQ), _mm256_cmp_ps(pw, zero, _CMP_GT_OQ));
        const v8::V ncx = _mm256_div_ps(cx, cw), ncy = _mm256_div_ps(cy, cw);
        const v8::V npx = _mm256_div_ps(px, pw), npy = _mm256_div_ps(py, pw);
        // Sky: (cur - prev) * size; surface: cur * size - prev * size.
        const v8::V sky_x = _mm256_mul_ps(_mm256_sub_ps(ncx, npx), W);
        const v8::V sky_y = _mm256_mul_ps(_mm256_sub_ps(ncy, npy), H);
        const v8::V srf_x = _mm256_sub_ps(_mm256_mul_ps(ncx, W), _mm256_mul_ps(npx, W));
        const v8::V srf_y = _mm256_sub_ps(_mm256_mul_ps(ncy, H), _mm256_mul_ps(npy, H));
        const v8::V mx = _mm256_and_ps(ok, _mm256_blendv_ps(srf_x, sky_x, sky));
        const v8::V my = _mm256_and_ps(ok, _mm256_blendv_ps(srf_y, sky_y, sky));
        // Interleave to x0 y0 x1 y1 ...
        const v8::V lo = _mm256_unpacklo_ps(mx, my), hi = _mm256_unpackhi_ps(mx, my);
        _mm256_storeu_ps(motion + 2 * i, _mm256_permute2f128_ps(lo, hi, 0x20));
        _mm256_storeu_ps(motion + 2 * i + 8, _mm256_permute2f128_ps(lo, hi, 0x31));
    }
    depth_motion_scalar(r, i, n, q, depth, motion);
}
#endif

void depth_motion(
    const DepthMotionRow &r, int n, const DepthMotionParams &q, float *depth, float *motion)
{
#if POSTHASTE_HAVE_AVX2_TARGET
    if (simd::avx2()) {
        depth_motion_avx2(r, n, q, depth, motion);
        return;
    }
#endif
    depth_motion_scalar(r, 0, n, q, depth, motion);
}

// Order this thread's streaming stores before the tile is reported done.
void stream_fence()
{
#if defined(__SSE2__)
    _mm_sfence();
#endif
}

}  // namespace posthaste::raster::render_detail
