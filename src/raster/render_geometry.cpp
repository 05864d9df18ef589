// The rasterizer's geometry: meshes placed at the render time and the previous frame, the
// camera's view, frustum culling into batches, and the visibility buffer.
#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "core/memory.h"
#include "core/parallel.h"
#include "core/timing.h"
#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {

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

namespace {

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

}  // namespace

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

}  // namespace posthaste::raster::render_detail
