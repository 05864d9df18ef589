#include "shading/height_fog.h"

#include <algorithm>
#include <cassert>
#include <cstring>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"

namespace posthaste::shading {
namespace {

void composite(float *px, const FogResult &f)
{
    px[0] = px[0] * f.transmittance + f.inscatter.x;
    px[1] = px[1] * f.transmittance + f.inscatter.y;
    px[2] = px[2] * f.transmittance + f.inscatter.z;
}

#if defined(__SSE2__)
// fast_exp for four lanes, inputs clamped to [-87, 88] (so exp(-huge) is 1.6e-38, not 0).
__m128 exp4(__m128 x)
{
    x = _mm_min_ps(_mm_max_ps(x, _mm_set1_ps(-87.0f)), _mm_set1_ps(88.0f));
    const __m128i n = _mm_cvtps_epi32(_mm_mul_ps(x, _mm_set1_ps(1.44269504089f)));  // round
    const __m128 nf = _mm_cvtepi32_ps(n);
    const __m128 r = _mm_sub_ps(_mm_sub_ps(x, _mm_mul_ps(nf, _mm_set1_ps(0.693145751953125f))),
                                _mm_mul_ps(nf, _mm_set1_ps(1.428606765330187e-06f)));
    __m128 p = _mm_set1_ps(1.0f / 720.0f);
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.0f / 120.0f));
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.0f / 24.0f));
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.0f / 6.0f));
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(0.5f));
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.0f));
    p = _mm_add_ps(_mm_mul_ps(p, r), _mm_set1_ps(1.0f));
    const __m128i bits = _mm_slli_epi32(_mm_add_epi32(n, _mm_set1_epi32(127)), 23);
    return _mm_mul_ps(p, _mm_castsi128_ps(bits));
}

// Four pixels of height_fog() with start distance 0: transmittance and the sun lobe factor
// 1 / d^1.5. Returns the mask of lanes it handled (all but finite depths looking far down).
int fog4(const HeightFogCamera &c,
         const glm::vec3 &row_origin,
         const glm::vec3 &du,
         __m128 u,
         __m128 depth,
         __m128 &transmittance,
         __m128 &lobe)
{
    const __m128 rx = _mm_add_ps(_mm_set1_ps(row_origin.x), _mm_mul_ps(u, _mm_set1_ps(du.x)));
    const __m128 ry = _mm_add_ps(_mm_set1_ps(row_origin.y), _mm_mul_ps(u, _mm_set1_ps(du.y)));
    const __m128 rz = _mm_add_ps(_mm_set1_ps(row_origin.z), _mm_mul_ps(u, _mm_set1_ps(du.z)));
    const __m128 len = _mm_sqrt_ps(
        _mm_add_ps(_mm_add_ps(_mm_mul_ps(rx, rx), _mm_mul_ps(ry, ry)), _mm_mul_ps(rz, rz)));
    const __m128 dist = _mm_mul_ps(depth, len);
    // k * distance = b * (ray_y / len) * (depth * len) = b * ray_y * depth.
    const __m128 x = _mm_mul_ps(_mm_set1_ps(c.fog.falloff), _mm_mul_ps(ry, depth));
    const __m128 series = _mm_sub_ps(
        _mm_set1_ps(1.0f),
        _mm_mul_ps(x,
                   _mm_sub_ps(_mm_set1_ps(0.5f),
                              _mm_mul_ps(x,
                                         _mm_sub_ps(_mm_set1_ps(1.0f / 6.0f),
                                                    _mm_mul_ps(x, _mm_set1_ps(1.0f / 24.0f)))))));
    const __m128 safe_x =
        _mm_or_ps(x, _mm_and_ps(_mm_cmpeq_ps(x, _mm_setzero_ps()), _mm_set1_ps(1.0f)));
    const __m128 direct =
        _mm_div_ps(_mm_sub_ps(_mm_set1_ps(1.0f), exp4(_mm_sub_ps(_mm_setzero_ps(), x))), safe_x);
    const __m128 abs_x = _mm_andnot_ps(_mm_set1_ps(-0.0f), x);
    const __m128 small = _mm_cmplt_ps(abs_x, _mm_set1_ps(0.03f));
    const __m128 g = _mm_or_ps(_mm_and_ps(small, series), _mm_andnot_ps(small, direct));
    const __m128 a = _mm_set1_ps(c.density_at_camera);
    const __m128 inf = _mm_set1_ps(std::numeric_limits<float>::infinity());
    const __m128 finite =
        _mm_and_ps(_mm_cmpgt_ps(depth, _mm_setzero_ps()), _mm_cmplt_ps(depth, inf));
    // Infinite depth: a / k looking up (k = b * ray_y / len > 0), everything absorbed otherwise.
    const __m128 k = _mm_div_ps(_mm_mul_ps(_mm_set1_ps(c.fog.falloff), ry), len);
    const __m128 up = c.fog.opaque_sky ? _mm_setzero_ps() : _mm_cmpgt_ps(k, _mm_setzero_ps());
    const __m128 tau_inf =
        _mm_or_ps(_mm_and_ps(up, _mm_div_ps(a, _mm_max_ps(k, _mm_set1_ps(1e-30f)))),
                  _mm_andnot_ps(up, _mm_set1_ps(1e30f)));
    const __m128 tau_finite = _mm_mul_ps(_mm_mul_ps(a, dist), g);
    const __m128 is_inf = _mm_cmpeq_ps(depth, inf);
    // Depth <= 0 or NaN: no fog (tau = 0).
    const __m128 tau = _mm_or_ps(_mm_and_ps(finite, tau_finite), _mm_and_ps(is_inf, tau_inf));
    transmittance = exp4(_mm_sub_ps(_mm_setzero_ps(), tau));
    if (c.has_lobe) {
        const glm::vec3 &s = c.fog.sun_direction;
        const __m128 dot = _mm_add_ps(
            _mm_add_ps(_mm_mul_ps(rx, _mm_set1_ps(s.x)), _mm_mul_ps(ry, _mm_set1_ps(s.y))),
            _mm_mul_ps(rz, _mm_set1_ps(s.z)));
        const __m128 cos_theta = _mm_div_ps(dot, len);
        const __m128 d = _mm_max_ps(
            _mm_sub_ps(_mm_set1_ps(c.lobe_a), _mm_mul_ps(_mm_set1_ps(c.lobe_b), cos_theta)),
            _mm_set1_ps(1e-6f));
        lobe = _mm_div_ps(_mm_set1_ps(1.0f), _mm_mul_ps(d, _mm_sqrt_ps(d)));
    } else {
        lobe = _mm_setzero_ps();
    }
    // Lanes left to the scalar path: finite depth looking down far enough to risk overflow.
    const __m128 ok = _mm_andnot_ps(_mm_andnot_ps(_mm_cmpgt_ps(x, _mm_set1_ps(-40.0f)), finite),
                                    _mm_castsi128_ps(_mm_set1_epi32(-1)));
    return _mm_movemask_ps(ok);
}
#endif

#if POSTHASTE_HAVE_AVX2_TARGET
// fog4 for eight lanes with fused multiply-adds: the AVX2 path of apply_height_fog. Lanes that
// are not `ok` (finite depth looking far down, where the closed form may overflow) go to
// `scalar`, the exact per-pixel path.
template <class Scalar>
POSTHASTE_AVX2 void fog_row_avx2(const HeightFogCamera &c,
                                 const glm::vec3 &row_origin,
                                 const glm::vec3 &du,
                                 float inv_w,
                                 const float *z,
                                 float *row,
                                 int channels,
                                 int x0,
                                 int x1,
                                 const Scalar &scalar)
{
    using namespace simd::v8;
    const __m256 lane = _mm256_setr_ps(0.5f, 1.5f, 2.5f, 3.5f, 4.5f, 5.5f, 6.5f, 7.5f);
    const __m256 inf = set1(std::numeric_limits<float>::infinity());
    const __m256 b = set1(c.fog.falloff), a = set1(c.density_at_camera);
    const __m128 fog_rgb = _mm_setr_ps(c.fog.color.x, c.fog.color.y, c.fog.color.z, 0.0f);
    const __m128 sun_rgb = _mm_setr_ps(c.lobe_scale.x, c.lobe_scale.y, c.lobe_scale.z, 0.0f);
    const __m128 keep_alpha = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
    const __m256 fog_rgb2 = _mm256_set_m128(fog_rgb, fog_rgb);  // alpha lanes 0
    const __m256 sun_rgb2 = _mm256_set_m128(sun_rgb, sun_rgb);
    alignas(32) float t8[8], l8[8];
    int x = x0;
    for (; x + 8 <= x1; x += 8) {
        const __m256 u = _mm256_mul_ps(_mm256_add_ps(set1(float(x)), lane), set1(inv_w));
        const __m256 rx = _mm256_fmadd_ps(u, set1(du.x), set1(row_origin.x));
        const __m256 ry = _mm256_fmadd_ps(u, set1(du.y), set1(row_origin.y));
        const __m256 rz = _mm256_fmadd_ps(u, set1(du.z), set1(row_origin.z));
        const __m256 len =
            _mm256_sqrt_ps(_mm256_fmadd_ps(rx, rx, _mm256_fmadd_ps(ry, ry, _mm256_mul_ps(rz, rz))));
        const __m256 depth = _mm256_loadu_ps(z + x);
        // k * distance = b * (ray_y / len) * (depth * len) = b * ray_y * depth; optical depth
        // a * distance * (1 - e^-x) / x, by its series near x = 0.
        const __m256 xk = _mm256_mul_ps(b, _mm256_mul_ps(ry, depth));
        const __m256 series = _mm256_fnmadd_ps(
            xk,
            _mm256_fnmadd_ps(
                xk, _mm256_fnmadd_ps(xk, set1(1.0f / 24.0f), set1(1.0f / 6.0f)), set1(0.5f)),
            set1(1.0f));
        const __m256 zero_x = _mm256_cmp_ps(xk, _mm256_setzero_ps(), _CMP_EQ_OQ);
        const __m256 safe_x = _mm256_blendv_ps(xk, set1(1.0f), zero_x);
        const __m256 direct = _mm256_div_ps(
            _mm256_sub_ps(set1(1.0f), exp(_mm256_sub_ps(_mm256_setzero_ps(), xk))), safe_x);
        const __m256 small =
            _mm256_cmp_ps(_mm256_andnot_ps(set1(-0.0f), xk), set1(0.03f), _CMP_LT_OQ);
        const __m256 g = _mm256_blendv_ps(direct, series, small);
        const __m256 finite = _mm256_and_ps(_mm256_cmp_ps(depth, _mm256_setzero_ps(), _CMP_GT_OQ),
                                            _mm256_cmp_ps(depth, inf, _CMP_LT_OQ));
        // Infinite depth: a / k looking up (k = b ray_y / len > 0), everything absorbed otherwise.
        const __m256 k = _mm256_div_ps(_mm256_mul_ps(b, ry), len);
        const __m256 up = c.fog.opaque_sky ? _mm256_setzero_ps()
                                           : _mm256_cmp_ps(k, _mm256_setzero_ps(), _CMP_GT_OQ);
        const __m256 tau_inf =
            _mm256_blendv_ps(set1(1e30f), _mm256_div_ps(a, _mm256_max_ps(k, set1(1e-30f))), up);
        const __m256 tau_finite = _mm256_mul_ps(_mm256_mul_ps(a, _mm256_mul_ps(depth, len)), g);
        const __m256 is_inf = _mm256_cmp_ps(depth, inf, _CMP_EQ_OQ);
        // Depth <= 0 or NaN: no fog (tau = 0).
        const __m256 tau =
            _mm256_or_ps(_mm256_and_ps(finite, tau_finite), _mm256_and_ps(is_inf, tau_inf));
        const __m256 t = exp(_mm256_sub_ps(_mm256_setzero_ps(), tau));
        __m256 lobe = _mm256_setzero_ps();
        if (c.has_lobe) {
            const glm::vec3 &s = c.fog.sun_direction;
            const __m256 dot = _mm256_fmadd_ps(
                rx, set1(s.x), _mm256_fmadd_ps(ry, set1(s.y), _mm256_mul_ps(rz, set1(s.z))));
            const __m256 d = _mm256_max_ps(
                _mm256_fnmadd_ps(set1(c.lobe_b), _mm256_div_ps(dot, len), set1(c.lobe_a)),
                set1(1e-6f));
            lobe = _mm256_div_ps(set1(1.0f), _mm256_mul_ps(d, _mm256_sqrt_ps(d)));
        }
        // Lanes left to the scalar path: finite depth looking down far enough to risk overflow.
        const int bad = _mm256_movemask_ps(
            _mm256_andnot_ps(_mm256_cmp_ps(xk, set1(-40.0f), _CMP_GT_OQ), finite));
        if (bad == 0 && channels == 4) {
            // Two RGBA pixels per register: pixel * (T, T, T, 1) + (1 - T) (colour + lobe sun).
            float *p = row + std::size_t(x) * 4;
            const __m256 one_minus_t = _mm256_sub_ps(set1(1.0f), t);
            for (int pair = 0; pair < 4; ++pair) {
                const __m256i idx = _mm256_setr_epi32(2 * pair,
                                                      2 * pair,
                                                      2 * pair,
                                                      2 * pair,
                                                      2 * pair + 1,
                                                      2 * pair + 1,
                                                      2 * pair + 1,
                                                      2 * pair + 1);
                const __m256 factor =
                    _mm256_blend_ps(_mm256_permutevar8x32_ps(t, idx), set1(1.0f), 0x88);
                const __m256 radiance =
                    _mm256_fmadd_ps(_mm256_permutevar8x32_ps(lobe, idx), sun_rgb2, fog_rgb2);
                const __m256 inscatter =
                    _mm256_mul_ps(_mm256_permutevar8x32_ps(one_minus_t, idx), radiance);
                _mm256_storeu_ps(p + 8 * pair,
                                 _mm256_fmadd_ps(_mm256_loadu_ps(p + 8 * pair), factor, inscatter));
            }
            continue;
        }
        _mm256_store_ps(t8, t);
        _mm256_store_ps(l8, lobe);
        for (int i = 0; i < 8; ++i) {
            if (bad & (1 << i)) {
                scalar(x + i);
                continue;
            }
            // pixel = pixel * (T, T, T, 1) + (1 - T) * (colour + lobe * sun)
            float *p = row + std::size_t(x + i) * std::size_t(channels);
            const __m128 ti = _mm_broadcast_ss(&t8[i]);
            const __m128 radiance = _mm_fmadd_ps(_mm_broadcast_ss(&l8[i]), sun_rgb, fog_rgb);
            const __m128 inscatter = _mm_mul_ps(_mm_sub_ps(_mm_set1_ps(1.0f), ti), radiance);
            if (channels == 4) {
                const __m128 factor = _mm_or_ps(_mm_and_ps(keep_alpha, ti),
                                                _mm_andnot_ps(keep_alpha, _mm_set1_ps(1.0f)));
                _mm_storeu_ps(p, _mm_fmadd_ps(_mm_loadu_ps(p), factor, inscatter));
            } else {
                alignas(16) float s4[4];
                _mm_store_ps(s4, inscatter);
                for (int ch = 0; ch < 3; ++ch) {
                    p[ch] = std::fma(p[ch], t8[i], s4[ch]);
                }
            }
        }
    }
    for (; x < x1; ++x) {
        scalar(x);
    }
}
#endif

}  // namespace

void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      Image &color)
{
    apply_height_fog(fog, rays, depth, color, color);
}

void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      const Image &source,
                      Image &color)
{
    assert(color.channels() >= 3 && depth.channels() == 1);
    assert(color.width() == depth.width() && color.height() == depth.height());
    assert(source.width() == color.width() && source.height() == color.height() &&
           source.channels() == color.channels());
    const HeightFogCamera c = prepare_height_fog(fog, rays.position());
    const std::size_t row_bytes =
        sizeof(float) * std::size_t(color.width()) * std::size_t(color.channels());
    if (c.empty) {
        if (&source != &color) {
            parallel_for(0, color.height(), [&](int y) {
                std::memcpy(color.pixel(0, y), source.pixel(0, y), row_bytes);
            });
        }
        return;
    }
    const float inv_w = 1.0f / float(color.width());
    const float inv_h = 1.0f / float(color.height());
    const int channels = color.channels();
    // The 4-wide path needs the fast path's preconditions for the whole frame.
    const bool fast = c.fog.start_distance == 0.0f && c.density_at_camera > 1e-20f;
    const bool avx2 = simd::avx2();
    // Bands of whole rows: the pass streams through memory (it is bandwidth-bound: a 64-pixel
    // tile row is only 1 KiB of RGBA, too short for the hardware prefetcher).
    const int band = 4, bands = (color.height() + band - 1) / band;
    parallel_for(0, bands, [&](int b) {
        const Rect tile{0, b * band, color.width(), std::min(color.height(), (b + 1) * band)};
        for (int y = tile.y0; y < tile.y1; ++y) {
            const float v = (float(y) + 0.5f) * inv_h;
            const float *z = depth.pixel(0, y);
            float *row = color.pixel(0, y);
            if (&source != &color) {
                std::memcpy(row, source.pixel(0, y), row_bytes);  // then in place, in cache
            }
            const auto scalar = [&](int x) {
                const glm::vec3 ray = rays.depth_ray((float(x) + 0.5f) * inv_w, v);
                const float len = glm::length(ray);
                composite(row + std::size_t(x) * channels,
                          height_fog(c, ray * (1.0f / len), z[x] * len));
            };
            int x = tile.x0;
#if POSTHASTE_HAVE_AVX2_TARGET
            if (fast && avx2) {
                const glm::vec3 row_origin = rays.depth_ray(0.0f, v);
                fog_row_avx2(c,
                             row_origin,
                             rays.depth_ray(1.0f, v) - row_origin,
                             inv_w,
                             z,
                             row,
                             channels,
                             tile.x0,
                             tile.x1,
                             scalar);
                continue;
            }
#endif
#if defined(__SSE2__)
            if (fast) {
                const glm::vec3 row_origin = rays.depth_ray(0.0f, v);
                const glm::vec3 du = rays.depth_ray(1.0f, v) - row_origin;
                alignas(16) float t4[4], l4[4];
                const __m128 rgb_mask = _mm_castsi128_ps(_mm_setr_epi32(-1, -1, -1, 0));
                const __m128 alpha_one = _mm_setr_ps(0.0f, 0.0f, 0.0f, 1.0f);
                const __m128 fog_rgb =
                    _mm_setr_ps(c.fog.color.x, c.fog.color.y, c.fog.color.z, 0.0f);
                const __m128 sun_rgb =
                    _mm_setr_ps(c.lobe_scale.x, c.lobe_scale.y, c.lobe_scale.z, 0.0f);
                for (; x + 4 <= tile.x1; x += 4) {
                    const __m128 u = _mm_mul_ps(
                        _mm_add_ps(_mm_set1_ps(float(x)), _mm_setr_ps(0.5f, 1.5f, 2.5f, 3.5f)),
                        _mm_set1_ps(inv_w));
                    __m128 t, l;
                    const int ok = fog4(c, row_origin, du, u, _mm_loadu_ps(z + x), t, l);
                    if (ok == 0xf && channels == 4) {
                        // RGBA: pixel = pixel * (T, T, T, 1) + (1 - T) * (colour + lobe * sun).
                        const __m128 one_minus_t = _mm_sub_ps(_mm_set1_ps(1.0f), t);
                        float *p = row + std::size_t(x) * 4;
                        const __m128 lanes[4] = {_mm_shuffle_ps(t, t, 0x00),
                                                 _mm_shuffle_ps(t, t, 0x55),
                                                 _mm_shuffle_ps(t, t, 0xaa),
                                                 _mm_shuffle_ps(t, t, 0xff)};
                        const __m128 omt[4] = {_mm_shuffle_ps(one_minus_t, one_minus_t, 0x00),
                                               _mm_shuffle_ps(one_minus_t, one_minus_t, 0x55),
                                               _mm_shuffle_ps(one_minus_t, one_minus_t, 0xaa),
                                               _mm_shuffle_ps(one_minus_t, one_minus_t, 0xff)};
                        const __m128 lobes[4] = {_mm_shuffle_ps(l, l, 0x00),
                                                 _mm_shuffle_ps(l, l, 0x55),
                                                 _mm_shuffle_ps(l, l, 0xaa),
                                                 _mm_shuffle_ps(l, l, 0xff)};
                        for (int i = 0; i < 4; ++i) {
                            const __m128 factor =
                                _mm_or_ps(_mm_and_ps(rgb_mask, lanes[i]), alpha_one);
                            const __m128 radiance =
                                _mm_add_ps(fog_rgb, _mm_mul_ps(lobes[i], sun_rgb));
                            const __m128 px = _mm_loadu_ps(p + 4 * i);
                            _mm_storeu_ps(
                                p + 4 * i,
                                _mm_add_ps(_mm_mul_ps(px, factor), _mm_mul_ps(omt[i], radiance)));
                        }
                        continue;
                    }
                    _mm_store_ps(t4, t);
                    _mm_store_ps(l4, l);
                    for (int i = 0; i < 4; ++i) {
                        if (!(ok & (1 << i))) {
                            scalar(x + i);
                            continue;
                        }
                        const glm::vec3 radiance = c.fog.color + c.lobe_scale * l4[i];
                        FogResult f;
                        f.transmittance = t4[i];
                        f.inscatter = (1.0f - t4[i]) * radiance;
                        composite(row + std::size_t(x + i) * channels, f);
                    }
                }
            }
#else
            (void)fast;
#endif
            for (; x < tile.x1; ++x) {
                scalar(x);
            }
        }
    });
}

}  // namespace posthaste::shading
