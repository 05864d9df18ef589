#include "raster/render.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>
#include <limits>
#include <map>
#include <mutex>
#include <optional>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/error.h"
#include "core/hash.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
#include "core/timing.h"
#include "raster/mesh.h"
#include "raster/raster.h"
#include "raster/scene_cache.h"
#include "shading/brdf.h"
#include "shading/lighting.h"
#include "shading/scene_sky.h"
#include "shading/sky.h"

namespace posthaste::raster {

namespace {

using Clock = std::chrono::steady_clock;

// glm's mat4 * vec4 in its own order of operations, so the same bits, but always inlined: GCC
// had outlined glm's operator, and the per-pixel calls (shadow maps, motion) took ~20% of a
// frame (perf).
[[gnu::always_inline]] inline glm::vec4 mul(const glm::mat4 &m, const glm::vec4 &v)
{
    return (m[0] * v.x + m[1] * v.y) + (m[2] * v.z + m[3] * v.w);
}

// world_to_pixel (core/camera.h), with the inlined product.
[[gnu::always_inline]] inline bool to_pixel(
    const glm::mat4 &world_to_ndc, const glm::vec3 &p, int width, int height, glm::vec2 &pixel)
{
    const glm::vec4 h = mul(world_to_ndc, glm::vec4(p, 1.0f));
    if (!(h.w > 0.0f)) {
        return false;
    }
    pixel = glm::vec2(h.x / h.w * float(width), h.y / h.w * float(height));
    return true;
}

Image fresh_image(int width, int height, int channels)
{
    // Image::uninitialized advises huge pages (core/memory.h): every pass of a 1080p frame is
    // ~190 MB, and faulting that in 4 KiB pages cost ~16 % of a frame (perf).
    return Image::uninitialized(width, height, channels);
}

// One mesh placed in the world at the render time and at the previous frame.
struct Instance {
    const Mesh *mesh = nullptr;
    glm::mat4 m{1.0f}, m_prev{1.0f};
    bool identity = true;    // static world: m = m_prev = identity
    std::uint32_t base = 0;  // triangle ids are base + index
};

// Triangle ids: instance index in the high 16 bits, triangle index in the low 16 (chunks hold at
// most 24576 triangles, spheres at most 32400; scenes have fewer than 65535 instances).
constexpr int kInstanceShift = 16;

struct Geometry {
    std::vector<Instance> instances;
    std::size_t dynamic_begin = 0;  // instances from here on move
};

Geometry make_geometry(const Scene &s, const SceneMeshes &meshes, double t, double t_prev)
{
    Geometry g;
    auto add = [&](const Mesh &mesh, const glm::mat4 &m, const glm::mat4 &mp, bool identity) {
        const auto base = std::uint32_t(g.instances.size()) << kInstanceShift;
        g.instances.push_back({&mesh, m, mp, identity, base});
    };
    for (const Mesh &c : meshes.chunks) {
        add(c, glm::mat4(1.0f), glm::mat4(1.0f), true);
    }
    g.dynamic_begin = g.instances.size();
    for (std::size_t i = 0; i < s.balls.size(); ++i) {
        add(meshes.balls[i], s.balls[i].transform(t), s.balls[i].transform(t_prev), false);
    }
    for (std::size_t i = 0; i < s.movers.size(); ++i) {
        add(meshes.movers[i], s.movers[i].transform(t), s.movers[i].transform(t_prev), false);
    }
    return g;
}

// A camera for one render: pinhole, or a thin-lens sample (lens point in camera space, metres).
struct View {
    int width = 0, height = 0;
    glm::mat4 cam_to_world{1.0f}, world_to_camera{1.0f}, world_to_ndc{1.0f};
    float sx = 1, sy = 1, near_clip = 0.05f;
    glm::vec2 lens{0.0f};
    float focus = 1.0f;      // focus distance when lens != 0
    glm::mat4 raster{1.0f};  // world -> (X, Y, Q = 1, W = z)
    glm::vec3 origin{0.0f};  // ray origin (world)
    glm::vec3 dir00{0.0f}, dir_dx{0.0f},
        dir_dy{0.0f};  // ray direction = dir00 + x dir_dx + y dir_dy

    glm::vec3 ray_dir(float x, float y) const { return dir00 + x * dir_dx + y * dir_dy; }
};

View make_view(const CameraState &c, int width, int height, float near_clip, glm::vec2 lens)
{
    View v;
    v.width = width;
    v.height = height;
    v.near_clip = near_clip;
    v.cam_to_world = c.camera_to_world();
    const float aspect = float(width) / float(height);
    const CameraMatrices cm = make_camera_matrices(
        v.cam_to_world, c.focal_length_mm, c.sensor_width_mm, aspect, near_clip);
    v.world_to_camera = cm.world_to_camera;
    v.world_to_ndc = cm.world_to_ndc;
    v.sx = c.focal_length_mm / c.sensor_width_mm;
    v.sy = v.sx * aspect;
    v.lens = lens;
    v.focus = c.focus_distance;
    const float W = float(width), H = float(height);
    glm::mat4 r(0.0f);  // glm: r[column][row]
    if (lens == glm::vec2(0.0f)) {
        // Pixel = NDC * size: the rows of worldToNDC, so raster and header agree exactly.
        for (int col = 0; col < 4; ++col) {
            r[col][0] = cm.world_to_ndc[col][0] * W;
            r[col][1] = cm.world_to_ndc[col][1] * H;
            r[col][3] = cm.world_to_ndc[col][3];
        }
    } else {
        // Thin lens: a point seen through lens point L lands where the line L -> p meets the
        // focus plane, i.e. x' = x - ox (1 - z / focus) before the pinhole projection.
        const float ox = lens.x, oy = lens.y, fd = c.focus_distance;
        glm::mat4 cam(0.0f);
        cam[0][0] = W * v.sx;
        cam[2][0] = W * (v.sx * ox / fd + 0.5f);
        cam[3][0] = -W * v.sx * ox;
        cam[1][1] = -H * v.sy;
        cam[2][1] = H * (-v.sy * oy / fd + 0.5f);
        cam[3][1] = H * v.sy * oy;
        cam[2][3] = 1.0f;
        r = cam * cm.world_to_camera;
    }
    r[3][2] = 1.0f;  // Q = 1: key = 1 / z
    v.raster = r;
    // Rays through pixel (x, y): camera-space direction ((u - .5) / sx f - ox, (.5 - v) / sy f -
    // oy, f) with u = x / W, v = y / H and f the focus distance (1 for a pinhole).
    const float f = lens == glm::vec2(0.0f) ? 1.0f : c.focus_distance;
    const glm::mat3 rot(v.cam_to_world);
    v.origin = glm::vec3(v.cam_to_world * glm::vec4(lens.x, lens.y, 0.0f, 1.0f));
    v.dir00 = rot * glm::vec3(-0.5f / v.sx * f - lens.x, 0.5f / v.sy * f - lens.y, f);
    v.dir_dx = rot * glm::vec3(f / (v.sx * W), 0.0f, 0.0f);
    v.dir_dy = rot * glm::vec3(0.0f, -f / (v.sy * H), 0.0f);
    return v;
}

// World-space AABB of a mesh under a transform.
void transformed_bounds(
    const Mesh &m, const glm::mat4 &t, bool identity, glm::vec3 &lo, glm::vec3 &hi)
{
    if (identity) {
        lo = m.bounds_min;
        hi = m.bounds_max;
        return;
    }
    lo = glm::vec3(std::numeric_limits<float>::infinity());
    hi = -lo;
    for (int i = 0; i < 8; ++i) {
        const glm::vec3 c((i & 1) ? m.bounds_max.x : m.bounds_min.x,
                          (i & 2) ? m.bounds_max.y : m.bounds_min.y,
                          (i & 4) ? m.bounds_max.z : m.bounds_min.z);
        const glm::vec3 p(t * glm::vec4(c, 1.0f));
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
}

// True when the box is entirely outside one plane of the raster frustum (W >= near,
// 0 <= X <= width W, 0 <= Y <= height W) or of an orthographic map.
bool outside_frustum(const glm::mat4 &r,
                     float width,
                     float height,
                     float near_w,
                     const glm::vec3 &lo,
                     const glm::vec3 &hi)
{
    unsigned all = 0x1f;
    for (int i = 0; i < 8; ++i) {
        const glm::vec3 c((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
        const glm::vec4 h = r * glm::vec4(c, 1.0f);
        unsigned o = 0;
        o |= h.w < near_w ? 1u : 0u;
        o |= h.x < 0.0f ? 2u : 0u;
        o |= h.x > width * h.w ? 4u : 0u;
        o |= h.y < 0.0f ? 8u : 0u;
        o |= h.y > height * h.w ? 16u : 0u;
        all &= o;
    }
    return all != 0;
}

// Raster-space vertices of the instances that survive culling.
struct Batches {
    std::vector<std::vector<glm::vec4>> vertices;
    std::vector<DrawBatch> draws;
    std::size_t triangles = 0;
};

Batches make_batches(const Geometry &g,
                     std::size_t begin,
                     std::size_t end,
                     const glm::mat4 &r,
                     int width,
                     int height,
                     float near_w)
{
    Batches b;
    std::vector<std::size_t> visible;
    for (std::size_t i = begin; i < end; ++i) {
        const Instance &in = g.instances[i];
        glm::vec3 lo, hi;
        transformed_bounds(*in.mesh, in.m, in.identity, lo, hi);
        if (!outside_frustum(r, float(width), float(height), near_w, lo, hi)) {
            visible.push_back(i);
        }
    }
    b.vertices.resize(visible.size());
    parallel_for(0, int(visible.size()), [&](int k) {
        const Instance &in = g.instances[visible[std::size_t(k)]];
        const glm::mat4 m = in.identity ? r : r * in.m;
        std::vector<glm::vec4> &out = b.vertices[std::size_t(k)];
        out.resize(in.mesh->positions.size());
        for (std::size_t v = 0; v < out.size(); ++v) {
            out[v] = mul(m, glm::vec4(in.mesh->positions[v], 1.0f));
        }
    });
    for (std::size_t k = 0; k < visible.size(); ++k) {
        const Instance &in = g.instances[visible[k]];
        b.draws.push_back(
            {b.vertices[k].data(), in.mesh->triangles.data(), in.mesh->triangle_count(), in.base});
        b.triangles += in.mesh->triangle_count();
    }
    return b;
}

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

// The surface seen through one pixel.
struct Hit {
    glm::vec3 p, p_prev, n, t;
    int material;
};

// Intersects pixel rays with the triangle the rasterizer found (Moller-Trumbore, no culling or
// bounds: coverage was decided by the rasterizer) and interpolates its attributes. Neighbouring
// pixels mostly see the same triangle, so its world-space setup is kept between calls.
class SurfaceHitter {
   public:
    /// All rays start at `origin` (one view).
    SurfaceHitter(const Geometry &g, const glm::vec3 &origin) : g_(g), o_(origin) {}

    Hit hit(std::uint32_t id, const glm::vec3 &d)
    {
        if (id != id_) {
            load(id);
        }
        // Ray-plane distance, then barycentrics from the dual basis of (e1, e2).
        const float dn = glm::dot(ng_, d);
        const float t = dn != 0.0f ? plane_ / dn : 0.0f;
        Hit h;
        h.p = o_ + d * t;
        const glm::vec3 ap = h.p - a_;
        const float u = glm::dot(ap, b1_), v = glm::dot(ap, b2_), w = 1.0f - u - v;
        h.material = material_;
        if (flat_) {
            h.n = n_[0];
            h.t = t_[0];
        } else {
            h.n = glm::normalize(w * n_[0] + u * n_[1] + v * n_[2]);
            glm::vec3 tg = w * t_[0] + u * t_[1] + v * t_[2];
            tg -= h.n * glm::dot(h.n, tg);
            const float tl = glm::length(tg);
            h.t = tl > 1e-12f ? tg / tl : glm::vec3(0.0f);
        }
        h.p_prev = moving_
                       ? glm::vec3(mul(prev_, glm::vec4(w * l_[0] + u * l_[1] + v * l_[2], 1.0f)))
                       : h.p;
        return h;
    }

   private:
    void load(std::uint32_t id)
    {
        id_ = id;
        const Instance &in = g_.instances[id >> kInstanceShift];
        const std::uint32_t tri = id & ((1u << kInstanceShift) - 1u);
        const Mesh &m = *in.mesh;
        const glm::uvec3 ix = m.triangles[tri];
        material_ = m.materials[tri];
        glm::vec3 p[3];
        for (int k = 0; k < 3; ++k) {
            l_[k] = p[k] = m.positions[ix[k]];
            n_[k] = m.normals[ix[k]];
            t_[k] = m.tangents[ix[k]];
        }
        moving_ = !in.identity;
        if (moving_) {
            const glm::mat3 rot(in.m);
            for (int k = 0; k < 3; ++k) {
                p[k] = glm::vec3(in.m * glm::vec4(p[k], 1.0f));
                n_[k] = rot * n_[k];
                t_[k] = rot * t_[k];
            }
            prev_ = in.m_prev;
        }
        // Voxel faces: one normal and tangent, already orthonormal.
        flat_ = n_[0] == n_[1] && n_[0] == n_[2] && t_[0] == t_[1] && t_[0] == t_[2];
        a_ = p[0];
        const glm::vec3 e1 = p[1] - p[0], e2 = p[2] - p[0];
        ng_ = glm::cross(e1, e2);
        const float n2 = glm::dot(ng_, ng_);
        const float inv = n2 > 0.0f ? 1.0f / n2 : 0.0f;
        b1_ = glm::cross(e2, ng_) * inv;
        b2_ = glm::cross(ng_, e1) * inv;
        plane_ = glm::dot(ng_, a_ - o_);
    }

    const Geometry &g_;
    glm::vec3 o_;
    std::uint32_t id_ = kNoTriangle;
    glm::vec3 a_{0.0f}, ng_{0.0f}, b1_{0.0f}, b2_{0.0f};
    float plane_ = 0.0f;
    glm::vec3 l_[3], n_[3], t_[3];  // local positions, world normals and tangents
    glm::mat4 prev_{1.0f};
    bool moving_ = false, flat_ = false;
    int material_ = 0;
};

struct MaterialTable {
    Material m[256];
    explicit MaterialTable(const Scene &s)
    {
        for (int i = 0; i < 256; ++i) {
            m[i].id = i;
            m[i].albedo = glm::vec3(0.0f);
        }
        for (const Material &mat : s.materials) {
            m[mat.id] = mat;
        }
    }
};

struct Lighting {
    const Scene *scene;
    const ShadowMap *static_map = nullptr;
    const ShadowMap *dynamic_map = nullptr;
    const MaterialTable *materials;
};

// Per-tile sky state: the scene sky looked up once, and the ambient of recent normals in a small
// direct-mapped table (voxel faces share six normals, which get distinct slots, so a row that
// alternates between top and side faces no longer re-evaluates the harmonics; perf had the
// single-entry memo at ~2% of a frame).
struct SkyCache {
    const shading::SceneSky *sky;
    struct Slot {
        glm::vec3 n{std::numeric_limits<float>::quiet_NaN()};  // NaN: matches nothing
        glm::vec3 amb{0.0f};
    };
    std::array<Slot, 16> slots;

    explicit SkyCache(const Scene &s) : sky(&shading::scene_sky(s.sun.direction)) {}
    const glm::vec3 &ambient(const glm::vec3 &normal)
    {
        const std::uint32_t h = bits(normal.x) * 0x9E3779B1u + bits(normal.y) * 0x85EBCA77u +
                                bits(normal.z) * 0xC2B2AE3Du;
        Slot &s = slots[h >> 28];
        if (normal != s.n) {
            s.n = normal;
            s.amb = sky->ambient(normal);
        }
        return s.amb;
    }
    static std::uint32_t bits(float f)
    {
        std::uint32_t u;
        std::memcpy(&u, &f, sizeof u);
        return u;
    }
    glm::vec3 radiance(const glm::vec3 &dir) const
    {
        return sky->radiance(dir, glm::vec3(0.0f, shading::kSkyCameraY, 0.0f), false);
    }
};

glm::vec3 shade(const Lighting &lt, const Hit &h, const glm::vec3 &view_dir, SkyCache &sky)
{
    const Scene &s = *lt.scene;
    const Material &mat = lt.materials->m[h.material];
    const glm::vec3 v = -view_dir;
    glm::vec3 n = h.n;
    if (glm::dot(n, v) < 0.0f) {
        n = -n;  // seen from behind (near-plane cuts): shade the side we see
    }
    shading::Surface surf;
    surf.albedo = mat.albedo;
    surf.roughness = mat.roughness;
    surf.metallic = mat.metallic;
    surf.anisotropy = mat.anisotropy;
    surf.tangent = h.t;
    const glm::vec3 l = s.sun.direction;
    float vis = glm::dot(n, l) > 0.0f ? 1.0f : 0.0f;
    if (vis > 0.0f && lt.static_map) {
        vis *= shadow_lookup(*lt.static_map, h.p, n);
    }
    if (vis > 0.0f && lt.dynamic_map) {
        vis *= shadow_lookup(*lt.dynamic_map, h.p, n);
    }
    const glm::vec3 e_sun = s.sun.color * s.sun.illuminance * vis;
    glm::vec3 c(0.0f);
    if (vis > 0.0f) {
        // Toon materials: n.l quantised to thirds, plus the specular lobe (shading/lighting.h).
        shading::DirectOptions direct;
        direct.toon_bands = mat.toon ? 3 : 0;
        c = shading::direct_response(surf, n, v, l, direct) * e_sun;
    }
    return shading::add_sky_light(c, surf, n, v, *sky.sky, sky.ambient(n), s.sky_ambient);
}

// Surface pixels of one row in struct-of-arrays form for the AVX2 beauty kernel. Everything per
// pixel that branches or looks up tables (hit, material, shadow map, memoised ambient) is done
// by the scalar prelude in ColorRow::add_surface; the kernel does the BRDF and sky light.
struct SurfaceLanes {
    std::vector<float> nx, ny, nz, vx, vy, vz, ar, ag, ab, rough, metal, vis, amb_r, amb_g, amb_b,
        env_r, env_g, env_b, px, py, pz;
    std::vector<float> out_r, out_g, out_b;

    void resize(std::size_t n)
    {
        for (std::vector<float> *a :
             {&nx,    &ny,    &nz,    &vx,    &vy,    &vz,    &ar,    &ag,
              &ab,    &rough, &metal, &vis,   &amb_r, &amb_g, &amb_b, &env_r,
              &env_g, &env_b, &out_r, &out_g, &out_b, &px,    &py,    &pz}) {
            a->assign(n, 0.0f);
        }
    }
};

// Sun and sky constants of the kernel.
struct KernelLight {
    glm::vec3 l;        // toward the sun
    glm::vec3 sun_rgb;  // sun colour * illuminance
    float scale;        // scene sky_ambient
};

#if POSTHASTE_HAVE_AVX2_TARGET
namespace v8 = simd::v8;

#if defined(__clang__)
#define POSTHASTE_NO_CONTRACT  // clang fuses a * b + c only within one source expression
#else
#define POSTHASTE_NO_CONTRACT __attribute__((optimize("fp-contract=off")))
#endif

POSTHASTE_AVX2_INLINE v8::V dot3(v8::V ax, v8::V ay, v8::V az, v8::V bx, v8::V by, v8::V bz)
{
    return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ax, bx), _mm256_mul_ps(ay, by)),
                         _mm256_mul_ps(az, bz));
}

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

// The expressions of shading::evaluate (isotropic, height-correlated Smith) and
// shading::add_sky_light, eight lanes at a time, for lanes [0, count) (arrays padded to 8).
POSTHASTE_AVX2 void shade_lanes_avx2(SurfaceLanes &s, int count, const KernelLight &kl)
{
    using v8::set1;
    using v8::V;
    const V zero = _mm256_setzero_ps(), one = set1(1.0f);
    const V lx = set1(kl.l.x), ly = set1(kl.l.y), lz = set1(kl.l.z);
    const V inv_pi = set1(1.0f / shading::kPi), pi = set1(shading::kPi);
    const V min_cos = set1(shading::kMinCosine), f0d = set1(0.04f), scale = set1(kl.scale);
    const V sun[3] = {set1(kl.sun_rgb.x), set1(kl.sun_rgb.y), set1(kl.sun_rgb.z)};
    for (int i = 0; i < count; i += 8) {
        const V nx = _mm256_loadu_ps(&s.nx[i]), ny = _mm256_loadu_ps(&s.ny[i]),
                nz = _mm256_loadu_ps(&s.nz[i]);
        const V vx = _mm256_loadu_ps(&s.vx[i]), vy = _mm256_loadu_ps(&s.vy[i]),
                vz = _mm256_loadu_ps(&s.vz[i]);
        const V rough = _mm256_loadu_ps(&s.rough[i]), metal = _mm256_loadu_ps(&s.metal[i]);
        const V vis = _mm256_loadu_ps(&s.vis[i]);
        const V alb[3] = {
            _mm256_loadu_ps(&s.ar[i]), _mm256_loadu_ps(&s.ag[i]), _mm256_loadu_ps(&s.ab[i])};

        const V nl = dot3(nx, ny, nz, lx, ly, lz);
        const V nv_raw = dot3(nx, ny, nz, vx, vy, vz);
        const V nv = _mm256_max_ps(nv_raw, min_cos);
        V hx = _mm256_add_ps(vx, lx), hy = _mm256_add_ps(vy, ly), hz = _mm256_add_ps(vz, lz);
        const V hlen = _mm256_sqrt_ps(dot3(hx, hy, hz, hx, hy, hz));
        const V hok = _mm256_cmp_ps(hlen, set1(1e-8f), _CMP_GT_OQ);
        hx = _mm256_blendv_ps(nx, _mm256_div_ps(hx, hlen), hok);
        hy = _mm256_blendv_ps(ny, _mm256_div_ps(hy, hlen), hok);
        hz = _mm256_blendv_ps(nz, _mm256_div_ps(hz, hlen), hok);
        const V nh = _mm256_max_ps(dot3(nx, ny, nz, hx, hy, hz), zero);
        const V vh = _mm256_max_ps(dot3(vx, vy, vz, hx, hy, hz), zero);
        const V r = v8::clamp(rough, set1(shading::kMinRoughness), one);
        const V alpha = _mm256_mul_ps(r, r);
        const V a2 = _mm256_mul_ps(alpha, alpha);
        // D (zero for n.h <= 0) times the correlated Smith V.
        const V d =
            _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nh, nh), _mm256_sub_ps(a2, one)), one);
        V dggx = _mm256_div_ps(a2, _mm256_mul_ps(_mm256_mul_ps(pi, d), d));
        dggx = _mm256_and_ps(dggx, _mm256_cmp_ps(nh, zero, _CMP_GT_OQ));
        const V nlc = _mm256_max_ps(nl, min_cos);
        const V one_a2 = _mm256_sub_ps(one, a2);
        const V gv = _mm256_mul_ps(
            nlc, _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nv, nv), one_a2), a2)));
        const V gl = _mm256_mul_ps(
            nv, _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nlc, nlc), one_a2), a2)));
        const V dv = _mm256_mul_ps(dggx, _mm256_div_ps(set1(0.5f), _mm256_add_ps(gv, gl)));
        // Schlick at v.h (direct) and at n.v (sky).
        const V mh = _mm256_sub_ps(one, v8::clamp(vh, zero, one));
        const V mh5 =
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(mh, mh), _mm256_mul_ps(mh, mh)), mh);
        const V nv2 = _mm256_max_ps(nv_raw, zero);
        const V mv = _mm256_sub_ps(one, v8::clamp(nv2, zero, one));
        const V mv5 =
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(mv, mv), _mm256_mul_ps(mv, mv)), mv);
        const V lit = _mm256_cmp_ps(vis, zero, _CMP_GT_OQ);  // vis > 0 implies n.l > 0
        const V gloss = _mm256_mul_ps(_mm256_sub_ps(one, rough), _mm256_sub_ps(one, rough));
        const V glossy = _mm256_cmp_ps(gloss, set1(0.05f), _CMP_GE_OQ);
        const V one_metal = _mm256_sub_ps(one, metal);
        const V amb_in[3] = {_mm256_loadu_ps(&s.amb_r[i]),
                             _mm256_loadu_ps(&s.amb_g[i]),
                             _mm256_loadu_ps(&s.amb_b[i])};
        const V env_in[3] = {_mm256_loadu_ps(&s.env_r[i]),
                             _mm256_loadu_ps(&s.env_g[i]),
                             _mm256_loadu_ps(&s.env_b[i])};
        float *out[3] = {&s.out_r[i], &s.out_g[i], &s.out_b[i]};
        for (int c = 0; c < 3; ++c) {
            const V f0 = _mm256_add_ps(_mm256_mul_ps(f0d, one_metal), _mm256_mul_ps(alb[c], metal));
            const V one_f0 = _mm256_sub_ps(one, f0);
            const V diffuse = _mm256_mul_ps(alb[c], one_metal);
            const V f = _mm256_add_ps(f0, _mm256_mul_ps(one_f0, mh5));
            const V direct = _mm256_mul_ps(
                _mm256_add_ps(_mm256_mul_ps(diffuse, inv_pi), _mm256_mul_ps(f, dv)), nl);
            V col = _mm256_and_ps(_mm256_mul_ps(direct, _mm256_mul_ps(sun[c], vis)), lit);
            const V amb = _mm256_mul_ps(amb_in[c], scale);
            col = _mm256_add_ps(col, _mm256_mul_ps(diffuse, amb));
            const V env_mix = _mm256_add_ps(_mm256_mul_ps(amb, _mm256_sub_ps(one, gloss)),
                                            _mm256_mul_ps(_mm256_mul_ps(env_in[c], scale), gloss));
            const V env = _mm256_blendv_ps(amb, env_mix, glossy);
            const V fs = _mm256_add_ps(f0, _mm256_mul_ps(one_f0, mv5));
            col = _mm256_add_ps(col, _mm256_mul_ps(fs, env));
            _mm256_storeu_ps(out[c], col);
        }
    }
}
#endif

// The beauty of one row of visibility samples. The scalar path shades each pixel as it is added
// (shade() and the sky); the AVX2 path defers surfaces to shade_lanes_avx2 and the sky to the
// 4-wide SkyView::radiance_n. Toon and anisotropic materials always take shade().
class ColorRow {
   public:
    ColorRow(const Lighting &lt, SkyCache &sky, int capacity)
        : lt_(lt), sky_(sky), vector_(simd::avx2()), out_(std::size_t(capacity))
    {
        if (vector_) {
            const std::size_t padded = std::size_t(capacity + 8);
            lanes_.resize(padded);
            lane_slot_.resize(padded);
            for (std::vector<float> *a : {&sky_x_, &sky_y_, &sky_z_, &env_x_, &env_y_, &env_z_}) {
                a->resize(padded);
            }
            sky_slot_.resize(padded);
            env_lane_.resize(padded);
            sky_out_.resize(padded);
            kl_.l = lt.scene->sun.direction;
            kl_.sun_rgb = lt.scene->sun.color * lt.scene->sun.illuminance;
            kl_.scale = lt.scene->sky_ambient;
        }
    }

    void add_sky(int slot, const glm::vec3 &dn)
    {
        if (!vector_) {
            out_[std::size_t(slot)] = sky_.radiance(dn);
            return;
        }
        sky_x_[sky_n_] = dn.x;
        sky_y_[sky_n_] = dn.y;
        sky_z_[sky_n_] = dn.z;
        sky_slot_[sky_n_++] = slot;
    }

    void add_surface(int slot, const Hit &h, const glm::vec3 &dn)
    {
        const Material &mat = lt_.materials->m[h.material];
        if (!vector_ || mat.toon || mat.anisotropy != 0.0f) {
            out_[std::size_t(slot)] = shade(lt_, h, dn, sky_);
            return;
        }
        // The branchy part of shade(), in the same order.
        const glm::vec3 v = -dn;
        glm::vec3 n = h.n;
        if (glm::dot(n, v) < 0.0f) {
            n = -n;
        }
        const glm::vec3 &l = lt_.scene->sun.direction;
        const float vis = glm::dot(n, l) > 0.0f ? 1.0f : 0.0f;  // shadows: shadow_lanes_avx2
        const glm::vec3 &amb = sky_.ambient(n);
        const std::size_t k = lane_n_++;
        SurfaceLanes &s = lanes_;
        s.nx[k] = n.x, s.ny[k] = n.y, s.nz[k] = n.z;
        s.vx[k] = v.x, s.vy[k] = v.y, s.vz[k] = v.z;
        s.ar[k] = mat.albedo.x, s.ag[k] = mat.albedo.y, s.ab[k] = mat.albedo.z;
        s.rough[k] = mat.roughness, s.metal[k] = mat.metallic, s.vis[k] = vis;
        s.px[k] = h.p.x, s.py[k] = h.p.y, s.pz[k] = h.p.z;
        s.amb_r[k] = amb.x, s.amb_g[k] = amb.y, s.amb_b[k] = amb.z;
        lane_slot_[k] = slot;
        const float gloss = (1.0f - mat.roughness) * (1.0f - mat.roughness);
        if (gloss >= 0.05f) {
            const glm::vec3 r = glm::reflect(-v, n);
            env_x_[env_n_] = r.x;
            env_y_[env_n_] = r.y;
            env_z_[env_n_] = r.z;
            env_lane_[env_n_++] = k;
        }
    }

    /// Colours of the row's slots (valid for every slot added since the last finish()).
    const std::vector<glm::vec3> &finish()
    {
#if POSTHASTE_HAVE_AVX2_TARGET
        if (vector_) {
            finish_vector();
        }
#endif
        return out_;
    }

   private:
#if POSTHASTE_HAVE_AVX2_TARGET
    void finish_vector()
    {
        const glm::vec3 cam(0.0f, shading::kSkyCameraY, 0.0f);
        const shading::SkyView &view = sky_.sky->atmosphere().cached_sky_view();
        if (sky_n_ > 0) {
            view.radiance_n(
                sky_x_.data(), sky_y_.data(), sky_z_.data(), int(sky_n_), sky_out_.data());
            for (std::size_t i = 0; i < sky_n_; ++i) {
                const glm::vec3 d(sky_x_[i], sky_y_[i], sky_z_[i]);
                out_[std::size_t(sky_slot_[i])] = sky_out_[i] + sky_.sky->ground(d, cam);
            }
        }
        if (env_n_ > 0) {
            view.radiance_n(
                env_x_.data(), env_y_.data(), env_z_.data(), int(env_n_), sky_out_.data());
            for (std::size_t i = 0; i < env_n_; ++i) {
                const glm::vec3 d(env_x_[i], env_y_[i], env_z_[i]);
                const glm::vec3 e = sky_out_[i] + sky_.sky->ground(d, cam);
                const std::size_t k = env_lane_[i];
                lanes_.env_r[k] = e.x, lanes_.env_g[k] = e.y, lanes_.env_b[k] = e.z;
            }
        }
        if (lane_n_ > 0) {
            if (lt_.static_map) {
                shadow_lanes_avx2(*lt_.static_map, lanes_, int(lane_n_));
            }
            if (lt_.dynamic_map) {
                shadow_lanes_avx2(*lt_.dynamic_map, lanes_, int(lane_n_));
            }
            shade_lanes_avx2(lanes_, int(lane_n_), kl_);
            for (std::size_t k = 0; k < lane_n_; ++k) {
                out_[std::size_t(lane_slot_[k])] =
                    glm::vec3(lanes_.out_r[k], lanes_.out_g[k], lanes_.out_b[k]);
            }
        }
        sky_n_ = env_n_ = lane_n_ = 0;
    }
#endif

    const Lighting &lt_;
    SkyCache &sky_;
    bool vector_;
    std::vector<glm::vec3> out_;
    SurfaceLanes lanes_;
    KernelLight kl_{};
    std::vector<int> lane_slot_, sky_slot_;
    std::vector<std::size_t> env_lane_;
    std::vector<float> sky_x_, sky_y_, sky_z_, env_x_, env_y_, env_z_;
    std::vector<glm::vec3> sky_out_;
    std::size_t sky_n_ = 0, env_n_ = 0, lane_n_ = 0;
};

// Visibility buffer of a view.
struct Visibility {
    int width = 0, height = 0;
    std::unique_ptr<float[]> keys;
    std::unique_ptr<std::uint32_t[]> ids;
};

Visibility visibility(const Geometry &g, const View &v, RenderStats *stats)
{
    auto t0 = Clock::now();
    const Batches b =
        make_batches(g, 0, g.instances.size(), v.raster, v.width, v.height, v.near_clip);
    Visibility vis;
    vis.width = v.width;
    vis.height = v.height;
    const std::size_t n = std::size_t(v.width) * std::size_t(v.height);
    vis.keys.reset(new float[n]);  // uninitialised: rasterize() clears
    vis.ids.reset(new std::uint32_t[n]);
    advise_huge_pages(vis.keys.get(), n * sizeof(float));
    advise_huge_pages(vis.ids.get(), n * sizeof(std::uint32_t));
    RasterParams rp;
    rp.width = v.width;
    rp.height = v.height;
    rp.near_w = v.near_clip;
    if (stats) {
        stats->setup_bin_ms += ms_since(t0);
        t0 = Clock::now();
    }
    const RasterCounts counts = rasterize(b.draws, rp, {vis.keys.get(), vis.ids.get()});
    if (stats) {
        stats->raster_ms += ms_since(t0);
        stats->triangles += counts.submitted;
        stats->triangles_binned += counts.binned;
    }
    return vis;
}

// One tile row of a pass, built in cache and then written to the image in one sweep with
// streaming stores: the row overwrites whole cache lines, so reading them first (what plain
// stores do) would double the memory traffic of ~190 MB of passes per 1080p frame.
class RowBuffer {
   public:
    RowBuffer(Image &image, int width) : image_(image.empty() ? nullptr : &image)
    {
        if (image_) {
            values_.resize(std::size_t(width) * std::size_t(image.channels()));
        }
    }
    bool active() const { return image_ != nullptr; }
    float *at(int i) { return values_.data() + std::size_t(i) * std::size_t(image_->channels()); }
    /// Copy the row to pixels (x0, y) onwards.
    void write(int x0, int y)
    {
        if (!image_) {
            return;
        }
        float *dst = image_->pixel(x0, y);
        const float *src = values_.data();
        const std::size_t n = values_.size();
        std::size_t i = 0;
#if defined(__SSE2__)
        for (; i < n && (reinterpret_cast<std::uintptr_t>(dst + i) & 15u) != 0; ++i) {
            dst[i] = src[i];
        }
        for (; i + 4 <= n; i += 4) {
            _mm_stream_ps(dst + i, _mm_loadu_ps(src + i));
        }
#endif
        for (; i < n; ++i) {
            dst[i] = src[i];
        }
    }

   private:
    Image *image_;
    std::vector<float> values_;
};

// Depth and motion of one tile row, from what the per-pixel loop gathered: for a surface pixel
// its world position now and one frame ago, for a sky pixel its ray direction (a point at
// infinity). Kept apart from that loop so the projective divisions run eight pixels at a time.
struct DepthMotionRow {
    std::vector<float> px, py, pz;  // position (surface) or ray direction (sky)
    std::vector<float> qx, qy, qz;  // previous position (surface); unused for sky
    std::vector<std::int32_t> sky;  // -1 sky, 0 surface (a lane mask for the vector path)

    explicit DepthMotionRow(int n)
        : px(std::size_t(n)),
          py(std::size_t(n)),
          pz(std::size_t(n)),
          qx(std::size_t(n)),
          qy(std::size_t(n)),
          qz(std::size_t(n)),
          sky(std::size_t(n))
    {
    }
    void surface(int i, const glm::vec3 &p, const glm::vec3 &p_prev)
    {
        const std::size_t k = std::size_t(i);
        px[k] = p.x, py[k] = p.y, pz[k] = p.z;
        qx[k] = p_prev.x, qy[k] = p_prev.y, qz[k] = p_prev.z;
        sky[k] = 0;
    }
    void background(int i, const glm::vec3 &d)
    {
        const std::size_t k = std::size_t(i);
        px[k] = d.x, py[k] = d.y, pz[k] = d.z;
        sky[k] = -1;
    }
};

struct DepthMotionParams {
    glm::vec4 zrow;
    glm::mat4 cur, prev;  // world to NDC now and one frame ago
    int width, height;
};

// The reference: pixels [begin, end) of the row, depth to depth[i] and motion to motion[2i]
// (either may be null).
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

// Beauty of one view into `out` (RGBA), averaging ss x ss samples per pixel when vis is ss times
// the output size.
void shade_color(
    const Geometry &g, const View &v, const Visibility &vis, const Lighting &lt, int ss, Image &out)
{
    parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
        SurfaceHitter hitter(g, v.origin);
        SkyCache sky(*lt.scene);
        const int x0 = tile.x0 * ss, x1 = tile.x1 * ss;
        ColorRow row(lt, sky, x1 - x0);
        std::vector<glm::vec3> sum(std::size_t(tile.x1 - tile.x0));
        for (int y = tile.y0; y < tile.y1; ++y) {
            std::fill(sum.begin(), sum.end(), glm::vec3(0.0f));
            for (int sy = 0; sy < ss; ++sy) {
                const int Y = y * ss + sy;
                const std::uint32_t *ids = &vis.ids[std::size_t(Y) * std::size_t(vis.width)];
                for (int X = x0; X < x1; ++X) {
                    const std::uint32_t id = ids[X];
                    const glm::vec3 d = v.ray_dir(float(X) + 0.5f, float(Y) + 0.5f);
                    const glm::vec3 dn = glm::normalize(d);
                    if (id == kNoTriangle) {
                        row.add_sky(X - x0, dn);
                    } else {
                        row.add_surface(X - x0, hitter.hit(id, d), dn);
                    }
                }
                // Per pixel the samples add up in the order (sy, sx), as one loop per pixel.
                const std::vector<glm::vec3> &c = row.finish();
                for (std::size_t i = 0; i < sum.size(); ++i) {
                    for (int sx = 0; sx < ss; ++sx) {
                        sum[i] += c[i * std::size_t(ss) + std::size_t(sx)];
                    }
                }
            }
            for (int x = tile.x0; x < tile.x1; ++x) {
                const glm::vec3 c = sum[std::size_t(x - tile.x0)] / float(ss * ss);
                float *px = out.pixel(x, y);
                px[0] = c.x;
                px[1] = c.y;
                px[2] = c.z;
                px[3] = 1.0f;
            }
        }
    });
}

// Sun shadow maps and materials for the beauty at one time.
struct LightingState {
    MaterialTable materials;
    std::shared_ptr<const ShadowMap> static_map;
    std::unique_ptr<ShadowMap> dynamic_map;
    Lighting lighting;

    LightingState(const Scene &s,
                  SceneCache &cache,
                  const Geometry &g,
                  const RenderOptions &o,
                  RenderStats *stats)
        : materials(s), lighting{&s, nullptr, nullptr, &materials}
    {
        if (o.shadows) {
            const auto t0 = Clock::now();
            static_map = static_shadow(s, cache, g, o.greedy_meshing, o.shadow_map_size);
            dynamic_map = dynamic_shadow(s, g);
            lighting.static_map = static_map.get();
            lighting.dynamic_map = dynamic_map.get();
            if (stats) {
                stats->shadow_ms += ms_since(t0);
            }
        }
    }
};

// Render the beauty of the scene at time t through `lens` into out (RGBA, options size).
void render_color(const Scene &s,
                  SceneCache &cache,
                  double t,
                  glm::vec2 lens,
                  const CameraState &cam,
                  const RenderOptions &o,
                  Image &out,
                  RenderStats *stats)
{
    const auto meshes = scene_meshes(s, cache, o.greedy_meshing);
    const Geometry g = make_geometry(s, *meshes, t, t - 1.0);
    const LightingState ls(s, cache, g, o, stats);
    const View v =
        make_view(cam, o.width * o.supersample, o.height * o.supersample, s.near_clip, lens);
    const Visibility vis = visibility(g, v, stats);
    auto t0 = Clock::now();
    shade_color(g, v, vis, ls.lighting, o.supersample, out);
    if (stats) {
        stats->shade_ms += ms_since(t0);
    }
}

void fill_header(const Scene &s, int frame, const RenderOptions &o, Frame &f)
{
    f.number = frame;
    f.set_size(o.width, o.height);
    const CameraState c = s.camera_at(frame), cp = s.camera_at(frame - 1);
    const float aspect = float(o.width) / float(o.height);
    const CameraMatrices m = make_camera_matrices(
        c.camera_to_world(), c.focal_length_mm, c.sensor_width_mm, aspect, s.near_clip);
    const CameraMatrices mp = make_camera_matrices(
        cp.camera_to_world(), cp.focal_length_mm, cp.sensor_width_mm, aspect, s.near_clip);
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    f.camera.prev_world_to_camera = mp.world_to_camera;
    f.camera.prev_world_to_ndc = mp.world_to_ndc;
    f.camera.fstop = c.fstop;
    f.camera.focus_distance = c.focus_distance;
    f.camera.focal_length_mm = c.focal_length_mm;
    f.camera.sensor_width_mm = c.sensor_width_mm;
    f.camera.sensor_height_mm = c.sensor_width_mm / aspect;
    f.camera.shutter = c.shutter;
    f.camera.near_clip = s.near_clip;
    f.camera.far_clip =
        std::sqrt(float(s.world.nx) * float(s.world.nx) + float(s.world.ny) * float(s.world.ny) +
                  float(s.world.nz) * float(s.world.nz)) +
        1000.0f;
    f.attributes["posthaste:scene"] = s.name;
    f.attributes["posthaste:fps"] = float(s.fps);
}

SceneCache &cache_of(const Scene &s, std::shared_ptr<SceneCache> &local)
{
    if (s.cache) {
        return *s.cache;
    }
    local = make_scene_cache();
    return *local;
}

// Concentric mapping of [0,1)^2 onto the unit disc (Shirley & Chiu 1997).
glm::vec2 concentric_disc(float u1, float u2)
{
    const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) {
        return glm::vec2(0.0f);
    }
    const float pi4 = shading::kPi / 4.0f;
    if (std::abs(a) > std::abs(b)) {
        return a * glm::vec2(std::cos(pi4 * b / a), std::sin(pi4 * b / a));
    }
    return b * glm::vec2(std::cos(shading::kPi / 2 - pi4 * a / b),
                         std::sin(shading::kPi / 2 - pi4 * a / b));
}

}  // namespace

const std::set<std::string> &render_pass_names()
{
    static const std::set<std::string> names = {pass::kColor,
                                                pass::kDepth,
                                                pass::kNormal,
                                                pass::kPosition,
                                                pass::kMotion,
                                                pass::kAlbedo,
                                                pass::kMaterial,
                                                pass::kTangent,
                                                pass::kId};
    return names;
}

void validate(const RenderOptions &o)
{
    if (o.width <= 0 || o.height <= 0 || o.width > kMaxImageSide / 4 ||
        o.height > kMaxImageSide / 4) {
        throw_usage("render: expected a size in [1, ",
                    kMaxImageSide / 4,
                    "], got ",
                    o.width,
                    "x",
                    o.height);
    }
    if (o.supersample != 1 && o.supersample != 2 && o.supersample != 4) {
        throw_usage("render: \"supersample\": expected 1, 2 or 4, got ", o.supersample);
    }
    if (o.shadow_map_size < 16 || o.shadow_map_size > 16384) {
        throw_usage("render: \"shadow_map_size\": expected [16, 16384], got ", o.shadow_map_size);
    }
    for (const std::string &p : o.passes) {
        if (!render_pass_names().count(p)) {
            std::string known;
            for (const std::string &k : render_pass_names()) {
                known += (known.empty() ? "" : ", ") + k;
            }
            throw_usage("render: unknown pass ", posthaste::quoted(p), " (have: ", known, ")");
        }
    }
}

Frame render_frame(const Scene &s, int frame, const RenderOptions &o, RenderStats *stats)
{
    validate(o);
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    if (stats) {
        *stats = RenderStats{};
    }
    Frame f;
    fill_header(s, frame, o, f);
    const double t = frame;
    const CameraState cam = s.camera_at(t);
    auto has = [&](const char *p) { return o.passes.count(p) != 0; };

    auto t0 = Clock::now();
    const auto meshes = scene_meshes(s, cache, o.greedy_meshing);
    const Geometry g = make_geometry(s, *meshes, t, t - 1.0);
    if (stats) {
        stats->mesh_ms += ms_since(t0);
    }
    const bool want_color = has(pass::kColor);
    const bool data = std::any_of(
        o.passes.begin(), o.passes.end(), [](const std::string &p) { return p != pass::kColor; });
    std::unique_ptr<LightingState> ls;
    Image color;
    if (want_color) {
        ls = std::make_unique<LightingState>(s, cache, g, o, stats);
        color = fresh_image(o.width, o.height, 4);
        if (o.supersample > 1) {
            // The beauty gets its own visibility at the supersampled size.
            const View vs = make_view(cam,
                                      o.width * o.supersample,
                                      o.height * o.supersample,
                                      s.near_clip,
                                      glm::vec2(0.0f));
            const Visibility vis_ss = visibility(g, vs, stats);
            t0 = Clock::now();
            shade_color(g, vs, vis_ss, ls->lighting, o.supersample, color);
            if (stats) {
                stats->shade_ms += ms_since(t0);
            }
        }
    }
    const bool color_here = want_color && o.supersample == 1;
    if (!data && !color_here) {
        if (want_color) {
            f.set(pass::kColor, std::move(color));
        }
        return f;  // no pass asked for: the header and windows alone
    }
    const View v = make_view(cam, o.width, o.height, s.near_clip, glm::vec2(0.0f));
    const Visibility vis = visibility(g, v, stats);
    t0 = Clock::now();
    std::optional<MaterialTable> own_materials;
    if (!ls) {
        own_materials.emplace(s);
    }
    const MaterialTable &mats = ls ? ls->materials : *own_materials;
    const glm::mat4 prev_ndc = *f.camera.prev_world_to_ndc;
    const glm::mat4 cur_ndc = *f.camera.world_to_ndc;

    auto make = [&](const char *name, int channels) {
        return has(name) ? fresh_image(o.width, o.height, channels) : Image();
    };
    Image depth = make(pass::kDepth, 1), normal = make(pass::kNormal, 3);
    Image position = make(pass::kPosition, 3), motion = make(pass::kMotion, 2);
    Image albedo = make(pass::kAlbedo, 3), material = make(pass::kMaterial, 3);
    Image tangent = make(pass::kTangent, 3), id = make(pass::kId, 1);
    const glm::vec4 zrow(v.world_to_camera[0][2],
                         v.world_to_camera[1][2],
                         v.world_to_camera[2][2],
                         v.world_to_camera[3][2]);
    const DepthMotionParams dmp{zrow, cur_ndc, prev_ndc, o.width, o.height};

    parallel_for_tiles(Rect{0, 0, o.width, o.height}, [&](const Rect &tile) {
        SurfaceHitter hitter(g, v.origin);
        SkyCache sky(s);
        const int n = tile.x1 - tile.x0;
        std::optional<ColorRow> row;
        if (color_here) {
            row.emplace(ls->lighting, sky, n);
        }
        Image no_color;  // supersampled colour was shaded already: leave it alone
        RowBuffer color_row(color_here ? color : no_color, n), depth_row(depth, n);
        RowBuffer normal_row(normal, n);
        RowBuffer position_row(position, n), motion_row(motion, n), albedo_row(albedo, n);
        RowBuffer material_row(material, n), tangent_row(tangent, n), id_row(id, n);
        const bool depth_motion_here = depth_row.active() || motion_row.active();
        DepthMotionRow dm(depth_motion_here ? n : 0);
        for (int y = tile.y0; y < tile.y1; ++y) {
            const std::uint32_t *ids = &vis.ids[std::size_t(y) * std::size_t(o.width)];
            for (int i = 0; i < n; ++i) {
                const int x = tile.x0 + i;
                const std::uint32_t tid = ids[x];
                const glm::vec3 d = v.ray_dir(float(x) + 0.5f, float(y) + 0.5f);
                auto put3 = [&](RowBuffer &b, const glm::vec3 &c) {
                    if (b.active()) {
                        float *p = b.at(i);
                        p[0] = c.x;
                        p[1] = c.y;
                        p[2] = c.z;
                    }
                };
                if (tid == kNoTriangle) {
                    if (color_here) {
                        row->add_sky(i, glm::normalize(d));
                    }
                    if (depth_motion_here) {
                        dm.background(i, d);
                    }
                    put3(normal_row, glm::vec3(0.0f));
                    put3(position_row, glm::vec3(0.0f));
                    put3(albedo_row, glm::vec3(0.0f));
                    put3(material_row, glm::vec3(0.0f));
                    put3(tangent_row, glm::vec3(0.0f));
                    if (id_row.active()) {
                        *id_row.at(i) = 0.0f;
                    }
                    continue;
                }
                const Hit h = hitter.hit(tid, d);
                if (color_here) {
                    row->add_surface(i, h, glm::normalize(d));
                }
                if (depth_motion_here) {
                    dm.surface(i, h.p, h.p_prev);
                }
                const Material &m = mats.m[h.material];
                put3(normal_row, h.n);
                put3(position_row, h.p);
                put3(albedo_row, m.albedo);
                put3(material_row, glm::vec3(m.roughness, m.metallic, m.anisotropy));
                put3(tangent_row, h.t);
                if (id_row.active()) {
                    *id_row.at(i) = float(h.material);
                }
            }
            if (depth_motion_here) {
                depth_motion(dm,
                             n,
                             dmp,
                             depth_row.active() ? depth_row.at(0) : nullptr,
                             motion_row.active() ? motion_row.at(0) : nullptr);
            }
            if (color_here) {
                const std::vector<glm::vec3> &c = row->finish();
                for (int i = 0; i < n; ++i) {
                    float *p = color_row.at(i);
                    p[0] = c[std::size_t(i)].x;
                    p[1] = c[std::size_t(i)].y;
                    p[2] = c[std::size_t(i)].z;
                    p[3] = 1.0f;
                }
            }
            for (RowBuffer *b : {&color_row,
                                 &depth_row,
                                 &normal_row,
                                 &position_row,
                                 &motion_row,
                                 &albedo_row,
                                 &material_row,
                                 &tangent_row,
                                 &id_row}) {
                b->write(tile.x0, y);
            }
        }
        stream_fence();
    });
    if (stats) {
        stats->shade_ms += ms_since(t0);
    }
    auto store = [&](const char *name, Image &img) {
        if (!img.empty()) {
            f.set(name, std::move(img));
        }
    };
    store(pass::kColor, color);
    store(pass::kDepth, depth);
    store(pass::kNormal, normal);
    store(pass::kPosition, position);
    store(pass::kMotion, motion);
    store(pass::kAlbedo, albedo);
    store(pass::kMaterial, material);
    store(pass::kTangent, tangent);
    store(pass::kId, id);
    return f;
}

Frame render_truth(const Scene &s, int frame, const RenderOptions &o, const TruthOptions &truth)
{
    validate(o);
    if (truth.samples < 1 || truth.samples > 1 << 20) {
        throw_usage("render truth: \"samples\": expected [1, 1048576], got ", truth.samples);
    }
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    Frame f;
    fill_header(s, frame, o, f);
    const int n = truth.samples;
    // Time strata are a hashed permutation of the sample index, so that the joint (time, lens)
    // pattern is stratified in each dimension without correlating them.
    std::vector<int> perm(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        perm[std::size_t(i)] = i;
    }
    for (int i = n - 1; i > 0; --i) {
        const int j = int(hash4(std::uint32_t(i), std::uint32_t(frame), 17u, truth.seed) %
                          std::uint32_t(i + 1));
        std::swap(perm[std::size_t(i)], perm[std::size_t(j)]);
    }
    const std::uint32_t scramble = hash4(std::uint32_t(frame), 3u, 5u, truth.seed);
    Image acc(o.width, o.height, 4);
    Image sample = Image::uninitialized(o.width, o.height, 4);
    const CameraState centre = s.camera_at(frame);
    for (int i = 0; i < n; ++i) {
        double t = frame;
        if (truth.motion) {
            const float u =
                (float(truth.dof ? perm[std::size_t(i)] : i) + hash_unit(i, frame, 0, truth.seed)) /
                float(n);
            t = frame + (double(u) - 0.5) * double(centre.shutter);
        }
        const CameraState cam = s.camera_at(t);
        glm::vec2 lens(0.0f);
        if (truth.dof) {
            const float u1 = (float(i) + hash_unit(i, frame, 1, truth.seed)) / float(n);
            const float u2 =
                float((std::uint32_t(posthaste::radical_inverse_base2(std::uint32_t(i)) *
                                     16777216.0f) ^
                       (scramble >> 8)) &
                      0xffffffu) /
                16777216.0f;
            const float radius = 0.5f * cam.focal_length_mm / cam.fstop * 1e-3f;  // metres
            lens = concentric_disc(u1, u2) * radius;
        }
        render_color(s, cache, t, lens, cam, o, sample, nullptr);
        parallel_for(0, o.height, [&](int y) {
            float *a = acc.pixel(0, y);
            const float *b = sample.pixel(0, y);
            for (int k = 0; k < o.width * 4; ++k) {
                a[k] += b[k];
            }
        });
    }
    const float inv = 1.0f / float(n);
    parallel_for(0, o.height, [&](int y) {
        float *a = acc.pixel(0, y);
        for (int k = 0; k < o.width * 4; ++k) {
            a[k] *= inv;
        }
    });
    f.set(pass::kColor, std::move(acc));
    return f;
}

}  // namespace posthaste::raster
