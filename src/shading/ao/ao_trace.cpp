// Screen-space ray-traced AO (see ao_trace.h).

#include "shading/ao/ao_trace.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "core/hash.h"
#include "core/parallel.h"
#include "shading/lighting/lighting.h"

namespace posthaste::shading {
namespace {

/// The depth pass as a height field: depth, normals and the camera's projection.
struct DepthField {
    const Image &depth, &normal;
    const CameraRays &rays;
    glm::mat3 m, minv;  ///< columns: depth_ray's origin, du, dv (and its inverse)
    float inv_w, inv_h;

    DepthField(const Image &d, const Image &n, const CameraRays &r)
        : depth(d),
          normal(n),
          rays(r),
          m(r.ray_origin(), r.ray_du(), r.ray_dv()),
          minv(glm::inverse(m)),
          inv_w(1.0f / float(d.width())),
          inv_h(1.0f / float(d.height()))
    {
    }

    /// The unit normal of pixel (x, y), or the reverse of its view ray r where there is none.
    glm::vec3 unit_normal(int x, int y, const glm::vec3 &r) const
    {
        const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
        const float len = glm::length(n);
        return len > 0.0f && std::isfinite(len) ? n / len : -glm::normalize(r);
    }

    /// Whether world vector q (from the camera) lies behind the depth pass's surface, by less
    /// than `thickness`; false where q leaves the screen (`left` set) or meets the sky.
    bool inside(const glm::vec3 &q, float thickness, const Image *occluder, bool &left) const
    {
        // q = z (origin + u du + v dv): camera depth z and NDC (u, v).
        const glm::vec3 s = minv * q;
        const float z = s.x;
        const float u = s.y / z, v = s.z / z;
        if (!(z > 0.0f) || !(u >= 0.0f && u < 1.0f && v >= 0.0f && v < 1.0f)) {
            left = true;
            return false;
        }
        const int x = std::min(depth.width() - 1, int(u * float(depth.width())));
        const int y = std::min(depth.height() - 1, int(v * float(depth.height())));
        const float zp = depth.at(x, y, 0);
        if (!(zp > 0.0f) || !std::isfinite(zp)) {
            return false;
        }
        // The pixel's plane (depth and normal) at q's exact screen position: voxel faces and
        // smooth surfaces alike are planar within a pixel, where the pixel's constant depth
        // would put a slanted face in front of itself.
        const glm::vec3 rp = rays.depth_ray((float(x) + 0.5f) * inv_w, (float(y) + 0.5f) * inv_h);
        const glm::vec3 n = unit_normal(x, y, rp);
        const glm::vec3 rq = m * glm::vec3(1.0f, u, v);
        const float den = glm::dot(n, rq);
        float zs = zp;
        if (std::abs(den) > 1e-3f * glm::length(rq)) {
            const float zplane = zp * glm::dot(n, rp) / den;
            if (zplane > 0.5f * zp && zplane < 2.0f * zp) {
                zs = zplane;
            }
        }
        const float deep = occluder ? std::min(thickness, occluder->at(x, y, 0)) : thickness;
        return z > zs * (1.0f + 1e-4f) && z < zs + deep;
    }
};

}  // namespace

Image ao_trace(const Image &depth,
               const Image &normal,
               const CameraRays &rays,
               const AoTraceParams &p)
{
    const int w = depth.width(), h = depth.height();
    const int st = std::max(1, p.stride);
    const int ow = (w + st - 1) / st, oh = (h + st - 1) / st;
    Image out = Image::uninitialized(ow, oh, 1);
    const DepthField field(depth, normal, rays);
    // World units per pixel at depth 1: the march starts 1.5 pixels out, past the pixel's own
    // footprint.
    const float px_world_1 = glm::length(rays.ray_du()) * field.inv_w;
    const int strata = std::max(1, int(std::lround(std::sqrt(double(std::max(1, p.rays))))));
    const int n = strata * strata;
    const int steps = std::max(1, p.steps);
    parallel_for(0, oh, [&](int oy) {
        for (int ox = 0; ox < ow; ++ox) {
            const int x = ox * st, y = oy * st;
            const float z = depth.at(x, y, 0);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                out.at(ox, oy, 0) = 1.0f;
                continue;
            }
            const glm::vec3 r =
                rays.depth_ray((float(x) + 0.5f) * field.inv_w, (float(y) + 0.5f) * field.inv_h);
            const glm::vec3 pt = r * z;  // from the camera
            const glm::vec3 nn = field.unit_normal(x, y, r);
            const float t0 = std::min(0.5f * p.radius, 1.5f * px_world_1 * z);
            int open = 0;
            for (int i = 0; i < n; ++i) {
                const float u1 =
                    (float(i / strata) + hash_unit(x, y, 2 * i, p.seed)) / float(strata);
                const float u2 =
                    (float(i % strata) + hash_unit(x, y, 2 * i + 1, p.seed)) / float(strata);
                const glm::vec3 d = sample_cosine_hemisphere(nn, u1, u2);
                const float jitter = hash_unit(x, y, 2 * n + i, p.seed);
                bool hit = false, left = false;
                for (int k = 0; k < steps && !hit && !left; ++k) {
                    // Quadratic spacing from t0 to the radius: dense where occluders are near.
                    const float f = (float(k) + jitter) / float(steps);
                    hit = field.inside(
                        pt + d * (t0 + (p.radius - t0) * f * f), p.thickness, p.occluder, left);
                }
                open += hit ? 0 : 1;
            }
            out.at(ox, oy, 0) = float(open) / float(n);
        }
    });
    return out;
}

}  // namespace posthaste::shading
