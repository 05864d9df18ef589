// Screen-space reflections (see ssr.h).

#include "shading/ssr.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"
#include "shading/lighting.h"
#include "shading/scene_sky.h"
#include "shading/sky.h"

namespace posthaste::shading {
namespace {

constexpr float kNear = 1e-3f;  // camera z the march's far end is clipped to (world units)

/// A point of the ray's projected segment: pixel coordinates and 1 / camera z, both affine in
/// the segment's screen parameter.
struct ScreenPoint {
    float x, y, inv_z;
};

class Marcher {
   public:
    Marcher(const SsrInputs &in, const SsrParams &p, const float *inv_depth)
        : in_(in),
          p_(p),
          width_(in.depth->width()),
          height_(in.depth->height()),
          inv_depth_(inv_depth)
    {
    }

    /// What the ray origin + s dir meets on screen: the colour there and its weight against the
    /// sky (1, less near the screen's edges); weight 0 when it meets nothing there.
    glm::vec4 trace(const glm::vec3 &origin, const glm::vec3 &dir, float jitter) const
    {
        const glm::vec4 sky(0.0f);
        // Camera z along the ray, to clip its far end in front of the camera.
        const glm::vec4 oc = in_.world_to_camera * glm::vec4(origin, 1.0f);
        const glm::vec4 dc = in_.world_to_camera * glm::vec4(dir, 0.0f);
        float length = p_.max_distance;
        if (oc.z + dc.z * length < kNear) {
            if (dc.z >= 0.0f) {
                return sky;  // the origin itself is behind the near plane
            }
            length = (kNear - oc.z) / dc.z;
        }
        if (!(length > 0.0f)) {
            return sky;
        }
        const ScreenPoint a = project(origin), b = project(origin + dir * length);
        if (!std::isfinite(a.x + a.y + a.inv_z + b.x + b.y + b.inv_z)) {
            return sky;
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
            return sky;
        }
        // No more samples than pixels crossed; spaced as t = s^2, closer near the origin where
        // contact reflections need them, jittered per ray.
        const float length_px = std::sqrt(dx * dx + dy * dy);
        // The march starts a pixel and a half out: before that it would meet its own pixel,
        // whose one depth stands for a surface that slopes across it.
        const float t_start = std::min(t_end, 1.5f / std::max(length_px, 1e-6f));
        const float pixels = length_px * (t_end - t_start);
        const int steps = std::max(1, std::min(p_.steps, int(std::ceil(pixels))));
        float t_prev = 0.0f;
        float inv_prev = a.inv_z;
        for (int i = 0; i < steps; ++i) {
            const float s = (float(i) + jitter) / float(steps);
            const float t = std::max(t_start + s * s * (t_end - t_start), t_prev);
            const ScreenPoint q = lerp(a, b, t);
            const float inv_scene = inv_depth(q);
            // At or behind the depth pass (in 1 / z: the sky's 0 is never reached) and the
            // step's stretch of ray [z_prev, z] overlapping the slab [depth, depth + thickness].
            const bool crossed =
                q.inv_z <= inv_scene &&
                std::min(1.0f / inv_prev, 1.0f / q.inv_z) <= 1.0f / inv_scene + p_.thickness;
            if (crossed) {
                // Bisect [t_prev, t] for the first point at or behind the depth pass.
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
                const int hx = std::clamp(int(h.x), 0, width_ - 1);
                const int hy = std::clamp(int(h.y), 0, height_ - 1);
                // Where the bisection lands, the ray must lie within the slab too: a long step
                // that ends behind a surface it never crossed (the ray passed above or beside
                // it, hidden by it) is not a hit; the march goes on.
                if (1.0f / h.inv_z - in_.depth->at(hx, hy, 0) > p_.thickness) {
                    t_prev = t;
                    inv_prev = q.inv_z;
                    continue;
                }
                // The back of a surface (its normal along the ray): what the ray meets is
                // hidden from the camera, so the colour pass does not have it.
                const Image &nrm = *in_.normal;
                const glm::vec3 nh(nrm.at(hx, hy, 0), nrm.at(hx, hy, 1), nrm.at(hx, hy, 2));
                if (glm::dot(nh, dir) > 0.0f) {
                    return sky;
                }
                const Image &c = *in_.color;
                const float edge = std::min(std::min(h.x, float(width_) - h.x),
                                            std::min(h.y, float(height_) - h.y));
                const float fade_px = p_.edge_fade * float(std::min(width_, height_));
                const float w = fade_px > 0.0f ? std::clamp(edge / fade_px, 0.0f, 1.0f) : 1.0f;
                return glm::vec4(c.at(hx, hy, 0), c.at(hx, hy, 1), c.at(hx, hy, 2), w);
            }
            t_prev = t;
            inv_prev = q.inv_z;
        }
        // Off the screen in front of what the last sample saw: with `extend`, that surface is
        // taken to go on past the edge (a wall cut by the frame) and the ray to meet it there.
        if (p_.extend && t_end < 1.0f) {
            const ScreenPoint e = lerp(a, b, t_prev);
            const int ex = std::clamp(int(e.x), 0, width_ - 1);
            const int ey = std::clamp(int(e.y), 0, height_ - 1);
            const float scene_z = in_.depth->at(ex, ey, 0);
            if (std::isfinite(scene_z) && 1.0f / e.inv_z < scene_z) {
                const Image &c = *in_.color;
                return glm::vec4(c.at(ex, ey, 0), c.at(ex, ey, 1), c.at(ex, ey, 2), 1.0f);
            }
        }
        return sky;
    }

   private:
    /// 1 / the depth pass at the pixel under q (clamped to the image), 0 on the sky.
    float inv_depth(const ScreenPoint &q) const
    {
        const int px = std::clamp(int(q.x), 0, width_ - 1);
        const int py = std::clamp(int(q.y), 0, height_ - 1);
        return inv_depth_[std::size_t(py) * std::size_t(width_) + std::size_t(px)];
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
    int width_, height_;
    const float *inv_depth_;  ///< width_ x height_, row-major
};

}  // namespace

Image ssr(const SsrInputs &in, const SsrParams &p, SsrStats *stats)
{
    const Image &depth = *in.depth, &normal = *in.normal, &albedo = *in.albedo,
                &material = *in.material;
    const int w = depth.width(), h = depth.height();
    // Per pixel: the change of the reflected radiance (RGB; traced pixels), the weight that turns
    // it into the colour's change (RGB), and a flag: 0 nothing to do, 1 glossy, 2 glossy and
    // traced.
    Image change(w, h, 7);
    const CameraRays rays(in.world_to_camera, in.world_to_ndc);
    const SceneSky &sky = scene_sky(p.sun_direction);
    const glm::vec3 sky_camera(0.0f, kSkyCameraY, 0.0f);
    // The march compares in 1 / z: no division per step, and the sky (+inf) is 0.
    std::vector<float> inv_depth(std::size_t(w) * std::size_t(h));
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x, y, 0);
            inv_depth[std::size_t(y) * std::size_t(w) + std::size_t(x)] =
                z > 0.0f ? 1.0f / z : 0.0f;
        }
    });
    const Marcher marcher(in, p, inv_depth.data());
    std::atomic<long long> n_pixels{0}, n_rays{0}, n_hits{0};
    parallel_for(0, h, [&](int y) {
        long long row_pixels = 0, row_rays = 0, row_hits = 0;
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x, y, 0);
            const float roughness = material.at(x, y, 0);
            // Sky, and surfaces too rough to reflect more than the ambient: nothing to do.
            if (!(z > 0.0f) || !std::isfinite(z) || !(roughness <= p.max_roughness)) {
                continue;
            }
            glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
            const float nlen = glm::length(n);
            if (!(nlen > 0.0f)) {
                continue;
            }
            n /= nlen;
            const float u = (float(x) + 0.5f) / float(w), v = (float(y) + 0.5f) / float(h);
            const glm::vec3 point = rays.position() + rays.depth_ray(u, v) * z;
            const glm::vec3 view = -rays.direction(u, v);
            if (glm::dot(n, view) < 0.0f) {
                n = -n;  // as the renderer: the side we see
            }
            Surface surf;
            surf.albedo = glm::vec3(albedo.at(x, y, 0), albedo.at(x, y, 1), albedo.at(x, y, 2));
            surf.roughness = roughness;
            surf.metallic = material.at(x, y, 1);
            const glm::vec3 weight = sky_reflection_weight(surf, n, view);
            if (weight == glm::vec3(0.0f)) {
                continue;
            }
            float *px = change.pixel(x, y);
            px[3] = weight.x, px[4] = weight.y, px[5] = weight.z;
            px[6] = 1.0f;
            if (p.stride > 1 && (x % p.stride != 0 || y % p.stride != 0)) {
                continue;  // half resolution: the resolve fills this pixel from its neighbours
            }
            const float alpha = roughness_to_alpha(roughness);
            const int count =
                std::clamp(int(std::ceil(float(p.rays) * roughness / 0.35f)), 1, p.rays);
            // The origin leaves the surface by a fraction of its distance (depth precision).
            const glm::vec3 origin = point + n * (1e-3f * z + 1e-3f);
            glm::vec3 sum(0.0f);
            float wsum = 0.0f;
            for (int i = 0; i < count; ++i) {
                // Stratified in the first coordinate (the lobe's angle from its axis).
                const float u1 = (float(i) + hash_unit(x, y, 3 * i, p.seed)) / float(count);
                const float u2 = hash_unit(x, y, 3 * i + 1, p.seed);
                const glm::vec3 l = sample_ggx_reflection(n, view, alpha, u1, u2);
                const float nl = glm::dot(n, l);
                if (!(nl > 0.0f)) {
                    continue;
                }
                const glm::vec4 hit = marcher.trace(origin, l, hash_unit(x, y, 3 * i + 2, p.seed));
                glm::vec3 radiance(hit);
                if (hit.w < 1.0f) {  // the sky, for what the screen does not show
                    const glm::vec3 sky_l = sky.radiance(l, sky_camera, false) * p.sky_scale;
                    radiance = sky_l + (radiance - sky_l) * hit.w;
                }
                sum += radiance * nl;
                wsum += nl;
                ++row_rays;
                row_hits += hit.w > 0.0f ? 1 : 0;
            }
            ++row_pixels;
            if (!(wsum > 0.0f)) {
                continue;
            }
            const glm::vec3 r = glm::reflect(-view, n);
            const glm::vec3 d = sum / wsum - sky.radiance(r, sky_camera, false) * p.sky_scale;
            px[0] = d.x, px[1] = d.y, px[2] = d.z;
            px[6] = 2.0f;
        }
        n_pixels += row_pixels;
        n_rays += row_rays;
        n_hits += row_hits;
    });
    // The resolve: each pixel's change averaged with its neighbours' on the same surface (depth
    // within 5 %, normals within 25 degrees) over a (2 denoise + 1)^2 window, then weighted by
    // its own Fresnel and gloss. The rays' noise falls by the number of neighbours; the blur is
    // that of the window on sharp reflections.
    Image out = *in.color;
    const int radius = std::max(p.denoise, p.stride - 1);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float *c = change.pixel(x, y);
            if (c[6] == 0.0f) {
                continue;
            }
            const float z = depth.at(x, y, 0);
            const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
            glm::vec3 sum(0.0f);
            float count = 0.0f;
            if (c[6] == 2.0f) {
                sum = glm::vec3(c[0], c[1], c[2]);
                count = 1.0f;
            }
            // Only traced pixels hold rays: at half resolution, every other row and column.
            const int st = p.stride;
            const int y_lo = std::max(0, y - radius), x_lo = std::max(0, x - radius);
            for (int yy = y_lo + (st - y_lo % st) % st; yy <= std::min(h - 1, y + radius);
                 yy += st) {
                for (int xx = x_lo + (st - x_lo % st) % st; xx <= std::min(w - 1, x + radius);
                     xx += st) {
                    if (xx == x && yy == y) {
                        continue;
                    }
                    const float *o = change.pixel(xx, yy);
                    if (o[6] != 2.0f || std::abs(depth.at(xx, yy, 0) - z) > 0.05f * z) {
                        continue;
                    }
                    const glm::vec3 m(
                        normal.at(xx, yy, 0), normal.at(xx, yy, 1), normal.at(xx, yy, 2));
                    if (glm::dot(m, n) < 0.9f) {  // unit normals (zero where not finite)
                        continue;
                    }
                    sum += glm::vec3(o[0], o[1], o[2]);
                    count += 1.0f;
                }
            }
            if (count == 0.0f) {
                continue;  // no traced neighbour on this surface
            }
            const glm::vec3 d = glm::vec3(c[3], c[4], c[5]) * (sum / count) * p.intensity;
            float *px = out.pixel(x, y);
            px[0] += d.x;
            px[1] += d.y;
            px[2] += d.z;
        }
    });
    if (stats) {
        stats->pixels = n_pixels;
        stats->rays = n_rays;
        stats->hits = n_hits;
    }
    return out;
}

}  // namespace posthaste::shading
