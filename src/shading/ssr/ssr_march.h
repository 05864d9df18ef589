#pragma once
// The screen-space reflection march of one ray (shading/ssr/ssr.h): its segment on screen, the
// scalar march through the traced grid's 1 / depth, the vector march's results read back
// (ssr_kernels.h), a crossing bisected and checked. Internal to ssr.cpp.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>
#include <optional>

#include "shading/lighting/lighting.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/ssr/ssr.h"
#include "shading/ssr/ssr_kernels.h"

namespace posthaste::shading::ssr_detail {

constexpr float kNear = 1e-3f;  // camera z the march's far end is clipped to (world units)

/// A point of the ray's projected segment: pixel coordinates and 1 / camera z, both affine in
/// the segment's screen parameter.
struct ScreenPoint {
    float x, y, inv_z;
};

/// The part of a reflected ray on screen, ready to march: its ends projected, the stretch
/// [t_start, t_end] of it that is marched, and the number of steps (0: none, the sky).
struct RaySegment {
    ScreenPoint a{}, b{};
    float t_start = 0.0f, t_end = 0.0f;
    int steps = 0;
};

/// The index of the pixel or cell holding coordinate v, in [0, n): converted after clamping in
/// float, so that no value (huge, or NaN) reaches the integer conversion out of range.
inline int clamp_index(float v, int n)
{
    return v > 0.0f ? (v < float(n - 1) ? int(v) : n - 1) : 0;
}

class Marcher {
   public:
    /// `inv_depth`: 1 / depth on the traced grid (grid_w x grid_h cells of `stride` pixels).
    Marcher(const SsrInputs &in,
            const SsrParams &p,
            const float *inv_depth,
            int grid_w,
            int grid_h,
            int stride)
        : in_(in),
          p_(p),
          width_(in.depth->width()),
          height_(in.depth->height()),
          inv_depth_(inv_depth),
          grid_w_(grid_w),
          grid_h_(grid_h),
          inv_stride_(1.0f / float(stride))
    {
        grid_.inv_depth = inv_depth;
        grid_.w = grid_w;
        grid_.h = grid_h;
        grid_.inv_stride = inv_stride_;
        grid_.thickness = p.thickness;
    }

    /// The part of the ray origin + s dir on screen (steps 0: none, the ray sees the sky).
    RaySegment segment(const glm::vec3 &origin, const glm::vec3 &dir) const
    {
        RaySegment seg;
        // Camera z along the ray, to clip its far end in front of the camera.
        const glm::vec4 oc = in_.world_to_camera * glm::vec4(origin, 1.0f);
        const glm::vec4 dc = in_.world_to_camera * glm::vec4(dir, 0.0f);
        float length = p_.max_distance;
        if (oc.z + dc.z * length < kNear) {
            if (dc.z >= 0.0f) {
                return seg;  // the origin itself is behind the near plane
            }
            length = (kNear - oc.z) / dc.z;
        }
        if (!(length > 0.0f)) {
            return seg;
        }
        const ScreenPoint a = project(origin), b = project(origin + dir * length);
        if (!std::isfinite(a.x + a.y + a.inv_z + b.x + b.y + b.inv_z)) {
            return seg;
        }
        // The part of the segment on screen: t in [0, t_end].
        float t_end = 1.0f;
        const float dx = b.x - a.x, dy = b.y - a.y;
        if (dx > 0.0f) {
            t_end = std::min(t_end, (float(width_) - a.x) / dx);
        } else if (dx < 0.0f) {
            t_end = std::min(t_end, -a.x / dx);
        }
        if (dy > 0.0f) {
            t_end = std::min(t_end, (float(height_) - a.y) / dy);
        } else if (dy < 0.0f) {
            t_end = std::min(t_end, -a.y / dy);
        }
        if (!(t_end > 0.0f)) {
            return seg;
        }
        // No more samples than pixels crossed; spaced as t = s^2, closer near the origin where
        // contact reflections need them, jittered per ray.
        const float length_px = std::sqrt(dx * dx + dy * dy);
        // The march starts a pixel and a half out: before that it would meet its own pixel,
        // whose one depth stands for a surface that slopes across it.
        seg.t_start = std::min(t_end, 1.5f / std::max(length_px, 1e-6f));
        seg.t_end = t_end;
        seg.a = a;
        seg.b = b;
        const float pixels = length_px * (t_end - seg.t_start);
        // In float first: a segment projected from near the camera plane can be huge.
        seg.steps = std::max(1, int(std::min(float(p_.steps), std::ceil(pixels))));
        return seg;
    }

    /// What ssr_segments needs to compute segment() in vectors.
    SsrSegmentCamera segment_camera() const
    {
        SsrSegmentCamera c;
        for (int col = 0; col < 4; ++col) {
            for (int row = 0; row < 4; ++row) {
                c.world_to_camera[4 * col + row] = in_.world_to_camera[col][row];
                c.world_to_ndc[4 * col + row] = in_.world_to_ndc[col][row];
            }
        }
        c.width = width_;
        c.height = height_;
        c.max_distance = p_.max_distance;
        c.max_steps = p_.steps;
        c.near = kNear;
        return c;
    }

    /// The segment as the vector march's kernel takes it.
    SsrSegment kernel_segment(const RaySegment &seg, float jitter) const
    {
        SsrSegment k;
        k.ax = seg.a.x;
        k.ay = seg.a.y;
        k.a_inv_z = seg.a.inv_z;
        k.bx = seg.b.x;
        k.by = seg.b.y;
        k.b_inv_z = seg.b.inv_z;
        k.t_start = seg.t_start;
        k.t_end = seg.t_end;
        k.jitter = jitter;
        k.steps = seg.steps;
        return k;
    }
    const SsrDepthGrid &grid() const { return grid_; }

    /// What the ray meets on screen: the colour there and its weight against the sky (1, less
    /// near the screen's edges); weight 0 when it meets nothing there. The scalar march (the
    /// reference of the vector kernel), for a segment with steps.
    glm::vec4 march(const RaySegment &seg, const glm::vec3 &dir, float jitter) const
    {
        const ScreenPoint &a = seg.a, &b = seg.b;
        float t_prev = 0.0f;
        float inv_prev = a.inv_z;
        for (int i = 0; i < seg.steps; ++i) {
            const float s = (float(i) + jitter) / float(seg.steps);
            const float t = std::max(seg.t_start + s * s * (seg.t_end - seg.t_start), t_prev);
            const ScreenPoint q = lerp(a, b, t);
            const float inv_scene = inv_depth(q);
            // At or behind the depth pass (in 1 / z: the sky's 0 is never reached) and the
            // step's stretch of ray [z_prev, z] overlapping the slab [depth, depth + thickness].
            const bool crossed =
                q.inv_z <= inv_scene &&
                std::min(1.0f / inv_prev, 1.0f / q.inv_z) <= 1.0f / inv_scene + p_.thickness;
            if (crossed) {
                if (const std::optional<glm::vec4> r = crossing(a, b, dir, t_prev, t)) {
                    return *r;
                }
            }
            t_prev = t;
            inv_prev = q.inv_z;
        }
        return off_screen(seg, t_prev);
    }

    /// march()'s result from the vector kernel's steps (ssr_march_steps: each step's t and
    /// whether it crossed): each crossing in order as march() takes it.
    glm::vec4 march_result(const RaySegment &seg,
                           const glm::vec3 &dir,
                           const float *ts,
                           const float *crossed) const
    {
        float t_prev = 0.0f;
        for (int i = 0; i < seg.steps; ++i) {
            if (crossed[i] != 0.0f) {
                if (const std::optional<glm::vec4> r = crossing(seg.a, seg.b, dir, t_prev, ts[i])) {
                    return *r;
                }
            }
            t_prev = ts[i];
        }
        return off_screen(seg, t_prev);
    }

   private:
    /// A ray that met nothing up to its last sample (t_last): off the screen in front of what
    /// that sample saw. With `extend`, that surface is taken to go on past the edge (a wall cut
    /// by the frame) and the ray to meet it there; else the sky.
    glm::vec4 off_screen(const RaySegment &seg, float t_last) const
    {
        if (p_.extend && seg.t_end < 1.0f) {
            const ScreenPoint e = lerp(seg.a, seg.b, t_last);
            const int ex = clamp_index(e.x, width_);
            const int ey = clamp_index(e.y, height_);
            const float scene_z = in_.depth->at(ex, ey, 0);
            if (std::isfinite(scene_z) && 1.0f / e.inv_z < scene_z) {
                const Image &c = *in_.color;
                return glm::vec4(c.at(ex, ey, 0), c.at(ex, ey, 1), c.at(ex, ey, 2), 1.0f);
            }
        }
        return glm::vec4(0.0f);
    }

    /// A crossing between t_prev and t: bisected for the first point at or behind the depth
    /// pass; the colour there (weight as trace()), the sky (weight 0) for the back of a
    /// surface, or nothing when the ray passed beside the surface (the march goes on).
    std::optional<glm::vec4> crossing(const ScreenPoint &a,
                                      const ScreenPoint &b,
                                      const glm::vec3 &dir,
                                      float t_prev,
                                      float t) const
    {
        float lo = t_prev, hi = t;
        for (int k = 0; k < p_.refine; ++k) {
            const float mid = 0.5f * (lo + hi);
            const ScreenPoint m = lerp(a, b, mid);
            if (m.inv_z <= inv_depth(m)) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        const ScreenPoint h = lerp(a, b, hi);
        const int hx = clamp_index(h.x, width_);
        const int hy = clamp_index(h.y, height_);
        // Where the bisection lands, the ray must lie within the slab too: a long step that
        // ends behind a surface it never crossed (the ray passed above or beside it, hidden by
        // it) is not a hit; the march goes on.
        if (1.0f / h.inv_z - in_.depth->at(hx, hy, 0) > p_.thickness) {
            return std::nullopt;
        }
        // The back of a surface (its normal along the ray): what the ray meets is hidden from
        // the camera, so the colour pass does not have it.
        const Image &nrm = *in_.normal;
        const glm::vec3 nh(nrm.at(hx, hy, 0), nrm.at(hx, hy, 1), nrm.at(hx, hy, 2));
        if (glm::dot(nh, dir) > 0.0f) {
            return glm::vec4(0.0f);
        }
        const Image &c = *in_.color;
        const float edge =
            std::min(std::min(h.x, float(width_) - h.x), std::min(h.y, float(height_) - h.y));
        const float fade_px = p_.edge_fade * float(std::min(width_, height_));
        const float w = fade_px > 0.0f ? std::clamp(edge / fade_px, 0.0f, 1.0f) : 1.0f;
        glm::vec3 col(c.at(hx, hy, 0), c.at(hx, hy, 1), c.at(hx, hy, 2));
        if (p_.sun_irradiance != glm::vec3(0.0f)) {
            col += reshade(hx, hy, nh, dir);
        }
        return glm::vec4(col, w);
    }

    /// The change of a hit's shading from the camera's view to the reflected ray's (toward
    /// -dir): its sun response (the truth's hit lobe, roughness at least
    /// kReflectedSunMinRoughness; the shadow pass's visibility) and its sky light
    /// (add_sky_light: the sky reflected about the normal, Fresnel at n.v).
    glm::vec3 reshade(int hx, int hy, glm::vec3 n, const glm::vec3 &dir) const
    {
        const glm::vec3 l = p_.sun_direction;
        const float u = (float(hx) + 0.5f) / float(width_), v = (float(hy) + 0.5f) / float(height_);
        const glm::vec3 ray = rays_.depth_ray(u, v);
        const glm::vec3 v_cam = -ray / std::sqrt(glm::dot(ray, ray));
        if (glm::dot(n, v_cam) < 0.0f) {
            n = -n;
        }
        Surface surf;
        surf.albedo = glm::vec3(
            in_.albedo->at(hx, hy, 0), in_.albedo->at(hx, hy, 1), in_.albedo->at(hx, hy, 2));
        surf.roughness = std::clamp(in_.material->at(hx, hy, 0), 0.0f, 1.0f);
        surf.metallic = std::clamp(in_.material->at(hx, hy, 1), 0.0f, 1.0f);
        glm::vec3 seen(0.0f), reflected(0.0f);
        const float vis = in_.shadow ? in_.shadow->at(hx, hy, 0) : 1.0f;
        if (vis > 0.0f && glm::dot(n, l) > 0.0f) {
            Surface lobe = surf;
            lobe.roughness = std::max(lobe.roughness, kReflectedSunMinRoughness);
            const DirectOptions direct;
            const glm::vec3 e = p_.sun_irradiance * vis;
            seen = direct_response(surf, n, v_cam, l, direct) * e;
            reflected = direct_response(lobe, n, -dir, l, direct) * e;
        }
        const glm::vec3 ambient = sky_.ambient(n);
        seen = add_sky_light(seen, surf, n, v_cam, sky_, ambient, p_.sky_scale);
        reflected = add_sky_light(reflected, surf, n, -dir, sky_, ambient, p_.sky_scale);
        return reflected - seen;
    }

    /// 1 / the depth of the traced grid's cell under q (clamped to the grid), 0 on the sky.
    float inv_depth(const ScreenPoint &q) const
    {
        const int cx = clamp_index(q.x * inv_stride_, grid_w_);
        const int cy = clamp_index(q.y * inv_stride_, grid_h_);
        return inv_depth_[std::size_t(cy) * std::size_t(grid_w_) + std::size_t(cx)];
    }

    ScreenPoint project(const glm::vec3 &w) const
    {
        const glm::vec4 h = in_.world_to_ndc * glm::vec4(w, 1.0f);
        const float z = (in_.world_to_camera * glm::vec4(w, 1.0f)).z;
        return {h.x / h.w * float(width_), h.y / h.w * float(height_), 1.0f / z};
    }
    static ScreenPoint lerp(const ScreenPoint &a, const ScreenPoint &b, float t)
    {
        return {a.x + (b.x - a.x) * t, a.y + (b.y - a.y) * t, a.inv_z + (b.inv_z - a.inv_z) * t};
    }

    const SsrInputs &in_;
    const SsrParams &p_;
    CameraRays rays_{in_.world_to_camera, in_.world_to_ndc};
    const SceneSky &sky_ = scene_sky(p_.sun_direction);
    int width_, height_;
    const float *inv_depth_;  ///< grid_w_ x grid_h_, row-major
    int grid_w_, grid_h_;
    float inv_stride_;
    SsrDepthGrid grid_;
};

}  // namespace posthaste::shading::ssr_detail
