// The sun's shadow maps: the static world's, built once per scene and size (scene_cache.h), and
// the moving objects', per frame; the lookups, one point or eight lanes at a time.
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/parallel.h"
#include "raster/color_row.h"
#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {
namespace {

// Orthographic map looking down -sun over a world-space box.
ShadowMap make_shadow_frame(const glm::vec3 &sun,
                            const glm::vec3 &lo,
                            const glm::vec3 &hi,
                            int size)
{
    ShadowMap sm;
    sm.size = size;
    const glm::vec3 helper = std::abs(sun.y) < 0.9f ? glm::vec3(0, 1, 0) : glm::vec3(1, 0, 0);
    const glm::vec3 e1 = glm::normalize(glm::cross(helper, sun));
    const glm::vec3 e2 = glm::cross(sun, e1);
    glm::vec3 mn(std::numeric_limits<float>::infinity()),
        mx(-std::numeric_limits<float>::infinity());
    for (int i = 0; i < 8; ++i) {
        const glm::vec3 c((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
        const glm::vec3 p(glm::dot(c, e1), glm::dot(c, e2), glm::dot(c, sun));
        mn = glm::min(mn, p);
        mx = glm::max(mx, p);
    }
    const float extent = std::max(mx.x - mn.x, mx.y - mn.y) + 1e-3f;
    const float scale = float(size) / extent;
    sm.texel_m = extent / float(size);
    glm::mat4 r(0.0f);
    for (int c = 0; c < 3; ++c) {
        r[c][0] = e1[c] * scale;
        r[c][1] = e2[c] * scale;
        r[c][2] = sun[c];
    }
    r[3][0] = -mn.x * scale;
    r[3][1] = -mn.y * scale;
    r[3][2] = -mn.z + 1.0f;
    r[3][3] = 1.0f;
    sm.raster = r;
    sm.keys.assign(std::size_t(size) * std::size_t(size), -std::numeric_limits<float>::infinity());
    return sm;
}

void draw_shadow(ShadowMap &sm, const Geometry &g, std::size_t begin, std::size_t end)
{
    const Batches b = make_batches(g, begin, end, sm.raster, sm.size, sm.size, 0.5f);
    RasterParams rp;
    rp.width = rp.height = sm.size;
    rp.cull_backfaces = false;
    rp.near_w = 0.5f;
    rasterize_over(b.draws, rp, {sm.keys.data(), nullptr});
}

}  // namespace

std::shared_ptr<const ShadowMap> static_shadow(
    const Scene &s, SceneCache &cache, const Geometry &g, bool greedy, int size)
{
    std::lock_guard<std::mutex> lock(cache.mutex);
    auto &slot = cache.shadows[{greedy, size}];
    if (!slot) {
        auto sm = std::make_shared<ShadowMap>(
            make_shadow_frame(s.sun.direction,
                              glm::vec3(0.0f),
                              glm::vec3(float(s.world.nx), float(s.world.ny), float(s.world.nz)),
                              size));
        tbb::this_task_arena::isolate([&] { draw_shadow(*sm, g, 0, g.dynamic_begin); });
        slot = std::move(sm);
    }
    return slot;
}

std::unique_ptr<ShadowMap> dynamic_shadow(const Scene &s, const Geometry &g)
{
    if (g.dynamic_begin == g.instances.size()) {
        return nullptr;
    }
    glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo);
    for (std::size_t i = g.dynamic_begin; i < g.instances.size(); ++i) {
        glm::vec3 a, b;
        transformed_bounds(*g.instances[i].mesh, g.instances[i].m, false, a, b);
        lo = glm::min(lo, a);
        hi = glm::max(hi, b);
    }
    auto sm =
        std::make_unique<ShadowMap>(make_shadow_frame(s.sun.direction, lo - 0.5f, hi + 0.5f, 512));
    draw_shadow(*sm, g, g.dynamic_begin, g.instances.size());
    return sm;
}

// Fraction of sun light reaching p (1 lit, 0 shadowed): 2x2 percentage-closer filter.
float shadow_lookup(const ShadowMap &sm, const glm::vec3 &p, const glm::vec3 &n)
{
    const glm::vec3 q = p + n * (1.5f * sm.texel_m);  // normal offset against acne
    const glm::vec4 h = mul(sm.raster, glm::vec4(q, 1.0f));
    const float x = h.x - 0.5f, y = h.y - 0.5f;
    const float limit = float(sm.size);
    if (!(x > -1.0f && y > -1.0f && x < limit && y < limit)) {
        return 1.0f;  // outside the map: nothing there casts a shadow
    }
    const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
    const float fx = x - float(x0), fy = y - float(y0);
    const float bias = 0.5f * sm.texel_m;
    float lit[4];
    for (int i = 0; i < 4; ++i) {
        const int xi = x0 + (i & 1), yi = y0 + (i >> 1);
        if (xi < 0 || yi < 0 || xi >= sm.size || yi >= sm.size) {
            lit[i] = 1.0f;
            continue;
        }
        lit[i] = sm.keys[std::size_t(yi) * std::size_t(sm.size) + std::size_t(xi)] > h.z + bias
                     ? 0.0f
                     : 1.0f;
    }
    return (lit[0] * (1 - fx) + lit[1] * fx) * (1 - fy) + (lit[2] * (1 - fx) + lit[3] * fx) * fy;
}

#if POSTHASTE_HAVE_AVX2_TARGET
// shadow_lookup for eight lanes at a time: vis *= the 2x2 PCF of `sm` where vis > 0. Without
// fused multiply-adds, so the map coordinates round as in the scalar code: one ulp of a 2048-texel
// coordinate moves the PCF weights by ~1e-4, which would make the two paths disagree visibly.
POSTHASTE_AVX2 POSTHASTE_NO_CONTRACT void shadow_lanes_avx2(const ShadowMap &sm,
                                                            SurfaceLanes &s,
                                                            int count)
{
    using v8::set1;
    using v8::V;
    const V zero = _mm256_setzero_ps(), one = set1(1.0f);
    const V offset = set1(1.5f * sm.texel_m), bias = set1(0.5f * sm.texel_m);
    const V limit = set1(float(sm.size));
    const __m256i size = _mm256_set1_epi32(sm.size);
    const glm::mat4 &r = sm.raster;
    for (int i = 0; i < count; i += 8) {
        const V vis = _mm256_loadu_ps(&s.vis[i]);
        const V lit_mask = _mm256_cmp_ps(vis, zero, _CMP_GT_OQ);
        if (_mm256_movemask_ps(lit_mask) == 0) {
            continue;
        }
        const V qx = _mm256_add_ps(_mm256_loadu_ps(&s.px[i]),
                                   _mm256_mul_ps(_mm256_loadu_ps(&s.nx[i]), offset));
        const V qy = _mm256_add_ps(_mm256_loadu_ps(&s.py[i]),
                                   _mm256_mul_ps(_mm256_loadu_ps(&s.ny[i]), offset));
        const V qz = _mm256_add_ps(_mm256_loadu_ps(&s.pz[i]),
                                   _mm256_mul_ps(_mm256_loadu_ps(&s.nz[i]), offset));
        V h[3];
        for (int c = 0; c < 3; ++c) {
            h[c] = _mm256_add_ps(
                _mm256_add_ps(_mm256_mul_ps(set1(r[0][c]), qx), _mm256_mul_ps(set1(r[1][c]), qy)),
                _mm256_add_ps(_mm256_mul_ps(set1(r[2][c]), qz), set1(r[3][c])));
        }
        const V x = _mm256_sub_ps(h[0], set1(0.5f)), y = _mm256_sub_ps(h[1], set1(0.5f));
        const V inside = _mm256_and_ps(_mm256_and_ps(_mm256_cmp_ps(x, set1(-1.0f), _CMP_GT_OQ),
                                                     _mm256_cmp_ps(y, set1(-1.0f), _CMP_GT_OQ)),
                                       _mm256_and_ps(_mm256_cmp_ps(x, limit, _CMP_LT_OQ),
                                                     _mm256_cmp_ps(y, limit, _CMP_LT_OQ)));
        const V use = _mm256_and_ps(inside, lit_mask);
        if (_mm256_movemask_ps(use) == 0) {
            continue;
        }
        const V fx0 = _mm256_floor_ps(x), fy0 = _mm256_floor_ps(y);
        const V fx = _mm256_sub_ps(x, fx0), fy = _mm256_sub_ps(y, fy0);
        // Out-of-map lanes are masked below; clamp first so the conversion stays in range.
        const __m256i x0 = _mm256_cvttps_epi32(v8::clamp(fx0, set1(-2.0f), limit));
        const __m256i y0 = _mm256_cvttps_epi32(v8::clamp(fy0, set1(-2.0f), limit));
        const V depth = _mm256_add_ps(h[2], bias);
        V lit[4];
        for (int k = 0; k < 4; ++k) {
            const __m256i xi = _mm256_add_epi32(x0, _mm256_set1_epi32(k & 1));
            const __m256i yi = _mm256_add_epi32(y0, _mm256_set1_epi32(k >> 1));
            const __m256i in_x = _mm256_andnot_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), xi),
                                                     _mm256_cmpgt_epi32(size, xi));
            const __m256i in_y = _mm256_andnot_si256(_mm256_cmpgt_epi32(_mm256_setzero_si256(), yi),
                                                     _mm256_cmpgt_epi32(size, yi));
            const V valid = _mm256_and_ps(_mm256_castsi256_ps(_mm256_and_si256(in_x, in_y)), use);
            const __m256i index = _mm256_add_epi32(_mm256_mullo_epi32(yi, size), xi);
            const V key = _mm256_mask_i32gather_ps(zero, sm.keys.data(), index, valid, 4);
            const V shadowed = _mm256_and_ps(valid, _mm256_cmp_ps(key, depth, _CMP_GT_OQ));
            lit[k] = _mm256_andnot_ps(shadowed, one);
        }
        const V one_fx = _mm256_sub_ps(one, fx), one_fy = _mm256_sub_ps(one, fy);
        const V pcf = _mm256_add_ps(
            _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(lit[0], one_fx), _mm256_mul_ps(lit[1], fx)),
                          one_fy),
            _mm256_mul_ps(_mm256_add_ps(_mm256_mul_ps(lit[2], one_fx), _mm256_mul_ps(lit[3], fx)),
                          fy));
        _mm256_storeu_ps(&s.vis[i], _mm256_blendv_ps(vis, _mm256_mul_ps(vis, pcf), use));
    }
}
#endif

}  // namespace posthaste::raster::render_detail
