#pragma once
// The rasterizer's pieces (internal to src/raster/render*.cpp): the placed geometry, the views
// and the visibility buffer (render_geometry.cpp), the sun's shadow maps (render_shadow.cpp),
// the colour shading (render_shade.cpp), the data-pass rows (render_rows.cpp); render.cpp
// assembles a frame from them.

#include <chrono>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <memory>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/image.h"
#include "core/simd.h"
#include "core/timing.h"
#include "raster/mesh.h"
#include "raster/raster.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "raster/scene_cache.h"
#include "shading/lighting/brdf.h"
#include "shading/lighting/lighting.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"

namespace posthaste::raster::render_detail {

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

/// An image for a pass the renderer writes in full (uninitialized; Image::uninitialized
/// advises huge pages, core/memory.h: faulting a 1080p frame's ~190 MB of passes in 4 KiB pages
/// cost ~16 % of a frame, perf).
inline Image fresh_image(int width, int height, int channels)
{
    return Image::uninitialized(width, height, channels);
}

// ---- Geometry and views (render_geometry.cpp) ----------------------------------------------

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

Geometry make_geometry(const Scene &s, const SceneMeshes &meshes, double t, double t_prev);

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

View make_view(const CameraState &c, int width, int height, float near_clip, glm::vec2 lens);

// World-space AABB of a mesh under a transform.
void transformed_bounds(
    const Mesh &m, const glm::mat4 &t, bool identity, glm::vec3 &lo, glm::vec3 &hi);

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
                     float near_w);

// Visibility buffer of a view.
struct Visibility {
    int width = 0, height = 0;
    std::unique_ptr<float[]> keys;
    std::unique_ptr<std::uint32_t[]> ids;
};

Visibility visibility(const Geometry &g, const View &v, RenderStats *stats);

// ---- The passes from the visibility buffer (render_passes.cpp) -------------------------------

struct LightingState;

// Every data pass o.passes asks for, and colour (and its specular share) when `color_here` (one
// sample a pixel), from `vis` seen through `v`; set on `f`. `ls` is null when neither colour
// nor the shadow pass is asked for.
void shade_passes(const Scene &s,
                  const Geometry &g,
                  const View &v,
                  const Visibility &vis,
                  const RenderOptions &o,
                  const LightingState *ls,
                  bool color_here,
                  bool want_specular,
                  Image &color,
                  Image &specular,
                  Frame &f,
                  RenderStats *stats);

// ---- Cryptomatte (render_cryptomatte.cpp) ---------------------------------------------------

// The CryptoObject and CryptoMaterial rank layers o.passes asks for, from `vis` (o.supersample
// samples a pixel side): each pixel's IDs ranked by coverage, the share of its samples that see
// them (the sky is no ID), and the header's declarations with their manifests.
void add_cryptomattes(const Scene &s,
                      const Geometry &g,
                      const Visibility &vis,
                      const RenderOptions &o,
                      Frame &f);

// ---- Shadow maps (render_shadow.cpp) --------------------------------------------------------

std::shared_ptr<const ShadowMap> static_shadow(
    const Scene &s, SceneCache &cache, const Geometry &g, bool greedy, int size);

std::unique_ptr<ShadowMap> dynamic_shadow(const Scene &s, const Geometry &g);

// Fraction of sun light reaching p (1 lit, 0 shadowed): 2x2 percentage-closer filter.
float shadow_lookup(const ShadowMap &sm, const glm::vec3 &p, const glm::vec3 &n);

// ---- Surfaces and colour (render_shade.cpp) -------------------------------------------------

// The surface seen through one pixel.
struct Hit {
    glm::vec3 p, p_prev, n, t;
    int material;
    bool curved;                    ///< Smooth-shaded (a ball): a sphere about its object's origin.
    glm::vec3 origin, origin_prev;  ///< The object's origin now and one frame ago (world).
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
        h.curved = !flat_;
        h.origin = origin_;
        h.origin_prev = origin_prev_;
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
        origin_ = glm::vec3(in.m[3]);
        origin_prev_ = glm::vec3(in.m_prev[3]);
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
    glm::vec3 origin_{0.0f}, origin_prev_{0.0f};
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

// Beauty of one view into `out` (RGBA), averaging ss x ss samples per pixel when vis is ss times
// the output size; with `specular` (RGB, the output size), also its view-dependent share.
void shade_color(const Geometry &g,
                 const View &v,
                 const Visibility &vis,
                 const Lighting &lt,
                 int ss,
                 Image &out,
                 Image *specular = nullptr);

// Render the beauty of the scene at time t through `lens` into out (RGBA, options size).
void render_color(const Scene &s,
                  SceneCache &cache,
                  double t,
                  glm::vec2 lens,
                  const CameraState &cam,
                  const RenderOptions &o,
                  Image &out,
                  RenderStats *stats);
// ---- Data-pass rows (render_rows.cpp) -------------------------------------------------------

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

// The row's n pixels: depth to depth[i] and motion to motion[2i] (either may be null), on the
// CPU's best Highway target (render_rows.cpp; every target gives the same bits).
void depth_motion(
    const DepthMotionRow &r, int n, const DepthMotionParams &q, float *depth, float *motion);

// Order this thread's streaming stores before the tile is reported done.
void stream_fence();

}  // namespace posthaste::raster::render_detail
