// Exact ray queries and the ambient occlusion ground truth (see ray_cast.h).

#include "raster/ray_cast.h"

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

#include "core/hash.h"
#include "core/parallel.h"
#include "core/passes.h"

namespace posthaste::raster {

RayScene::RayScene(const Scene &scene, double t) : grid_(scene.world)
{
    for (const Ball &b : scene.balls) {
        spheres_.push_back({glm::vec3(b.transform(t)[3]), b.radius});
    }
    for (const Mover &m : scene.movers) {
        const glm::vec3 off(m.transform(t)[3]);
        boxes_.push_back({m.min + off, m.min + m.size + off});
    }
}

bool RayScene::voxels_hit(const glm::vec3 &o, const glm::vec3 &d, float max_dist) const
{
    // Clip the ray to the grid's bounds (outside is air), then walk the cells it crosses.
    const glm::vec3 lo(0.0f), hi(float(grid_.nx), float(grid_.ny), float(grid_.nz));
    float t0 = 0.0f, t1 = max_dist;
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0f) {
            if (o[a] < lo[a] || o[a] > hi[a]) {
                return false;
            }
            continue;
        }
        float ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        if (ta > tb) {
            std::swap(ta, tb);
        }
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (t0 > t1) {
        return false;
    }
    const glm::vec3 p = o + d * t0;
    glm::ivec3 cell(int(std::floor(p.x)), int(std::floor(p.y)), int(std::floor(p.z)));
    glm::ivec3 step;
    glm::vec3 next, delta;
    for (int a = 0; a < 3; ++a) {
        const float inf = std::numeric_limits<float>::infinity();
        step[a] = d[a] > 0.0f ? 1 : -1;
        delta[a] = d[a] != 0.0f ? std::abs(1.0f / d[a]) : inf;
        const float boundary = float(cell[a] + (d[a] > 0.0f ? 1 : 0));
        next[a] = d[a] != 0.0f ? t0 + (boundary - p[a]) / d[a] : inf;
    }
    float t = t0;
    while (t <= t1) {
        if (grid_.at(cell.x, cell.y, cell.z) != 0) {
            return true;
        }
        const int a = next.x < next.y ? (next.x < next.z ? 0 : 2) : (next.y < next.z ? 1 : 2);
        t = next[a];
        next[a] += delta[a];
        cell[a] += step[a];
    }
    return false;
}

bool RayScene::occluded(const glm::vec3 &o, const glm::vec3 &d, float max_dist) const
{
    for (const Sphere &s : spheres_) {
        const glm::vec3 oc = o - s.centre;
        const float c = glm::dot(oc, oc) - s.radius * s.radius;
        if (c <= 1e-3f * s.radius) {
            continue;  // the origin is on or in this ball
        }
        const float b = glm::dot(oc, d);
        const float disc = b * b - c;
        if (b < 0.0f && disc >= 0.0f) {
            const float hit = -b - std::sqrt(disc);
            if (hit > 0.0f && hit <= max_dist) {
                return true;
            }
        }
    }
    for (const Box &bx : boxes_) {
        constexpr float kEps = 1e-3f;
        if (glm::all(glm::greaterThan(o, bx.lo - kEps)) &&
            glm::all(glm::lessThan(o, bx.hi + kEps))) {
            continue;  // on or in this block
        }
        float t0 = 0.0f, t1 = max_dist;
        bool miss = false;
        for (int a = 0; a < 3 && !miss; ++a) {
            if (d[a] == 0.0f) {
                miss = o[a] < bx.lo[a] || o[a] > bx.hi[a];
                continue;
            }
            float ta = (bx.lo[a] - o[a]) / d[a], tb = (bx.hi[a] - o[a]) / d[a];
            if (ta > tb) {
                std::swap(ta, tb);
            }
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
            miss = t0 > t1;
        }
        if (!miss) {
            return true;
        }
    }
    return voxels_hit(o, d, max_dist);
}

float ao_truth_at(const RayScene &rays,
                  const glm::vec3 &p,
                  const glm::vec3 &nn,
                  float radius,
                  int samples,
                  int x,
                  int y,
                  std::uint32_t seed)
{
    const int strata = std::max(1, int(std::lround(std::sqrt(double(samples)))));
    const int n = strata * strata;
    // An orthonormal basis around the normal (Duff et al. 2017).
    const float sign = std::copysign(1.0f, nn.z);
    const float a = -1.0f / (sign + nn.z), b = nn.x * nn.y * a;
    const glm::vec3 t1(1.0f + sign * nn.x * nn.x * a, sign * b, -sign * nn.x);
    const glm::vec3 t2(b, sign + nn.y * nn.y * a, -nn.y);
    const glm::vec3 origin = p + nn * 1e-3f;
    int open = 0;
    for (int i = 0; i < n; ++i) {
        // Cosine-weighted: a uniform point of the unit disc lifted onto the hemisphere.
        const float u1 = (float(i / strata) + hash_unit(x, y, 2 * i, seed)) / float(strata);
        const float u2 = (float(i % strata) + hash_unit(x, y, 2 * i + 1, seed)) / float(strata);
        const float r = std::sqrt(u1), phi = 6.28318530718f * u2;
        const glm::vec3 dir = t1 * (r * std::cos(phi)) + t2 * (r * std::sin(phi)) +
                              nn * std::sqrt(std::max(0.0f, 1.0f - u1));
        open += rays.occluded(origin, glm::normalize(dir), radius) ? 0 : 1;
    }
    return float(open) / float(n);
}

Image render_ao_truth(const Scene &scene,
                      int frame,
                      const RenderOptions &options,
                      float radius,
                      int samples,
                      std::uint32_t seed)
{
    RenderOptions o = options;
    o.passes = {pass::kPosition, pass::kNormal, pass::kDepth};
    const Frame g = render_frame(scene, frame, o);
    const Image &pos = g.image(pass::kPosition), &nrm = g.image(pass::kNormal),
                &depth = g.image(pass::kDepth);
    const RayScene rays(scene, double(frame));
    Image out(pos.width(), pos.height(), 1);
    parallel_for(0, pos.height(), [&](int y) {
        for (int x = 0; x < pos.width(); ++x) {
            if (!std::isfinite(depth.at(x, y, 0))) {
                out.at(x, y, 0) = 1.0f;  // the sky
                continue;
            }
            const glm::vec3 p(pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2));
            const glm::vec3 nn(nrm.at(x, y, 0), nrm.at(x, y, 1), nrm.at(x, y, 2));
            out.at(x, y, 0) = ao_truth_at(rays, p, glm::normalize(nn), radius, samples, x, y, seed);
        }
    });
    return out;
}

}  // namespace posthaste::raster
