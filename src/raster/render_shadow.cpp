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

}  // namespace posthaste::raster::render_detail
