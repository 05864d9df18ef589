// Exact ray queries and the ambient occlusion ground truth (see ray_cast.h).

#include "raster/ray_cast.h"

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <utility>

#include "core/hash.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/lighting/lighting.h"
#include "shading/ssr/environment.h"

namespace posthaste::raster {

RayScene::RayScene(const Scene &scene, double t) : grid_(scene.world)
{
    for (const Ball &b : scene.balls) {
        spheres_.push_back({glm::vec3(b.transform(t)[3]), b.radius, b.material});
    }
    for (const Mover &m : scene.movers) {
        const glm::vec3 off(m.transform(t)[3]);
        boxes_.push_back({m.min + off, m.min + m.size + off, m.material});
    }
}

namespace {

/// Distance to a sphere along unit d for 0 < s <= limit; none when the origin is on or in it
/// (within 1e-3 of its radius: the rendered ball is a tessellation inside the sphere).
std::optional<float> sphere_distance(
    const glm::vec3 &centre, float radius, const glm::vec3 &o, const glm::vec3 &d, float limit)
{
    const glm::vec3 oc = o - centre;
    const float c = glm::dot(oc, oc) - radius * radius;
    if (c <= 1e-3f * radius) {
        return std::nullopt;
    }
    const float b = glm::dot(oc, d);
    const float disc = b * b - c;
    if (b < 0.0f && disc >= 0.0f) {
        const float hit = -b - std::sqrt(disc);
        if (hit > 0.0f && hit <= limit) {
            return hit;
        }
    }
    return std::nullopt;
}

// The part t in [enter, exit] of the ray o + t d, t in [0, limit], inside the box [lo, hi]
// (slabs), and the axis of the face it enters through (-1: the origin is inside); nothing when
// it misses.
struct SlabSpan {
    float enter, exit;
    int axis;
};
std::optional<SlabSpan> slab_span(
    const glm::vec3 &lo, const glm::vec3 &hi, const glm::vec3 &o, const glm::vec3 &d, float limit)
{
    float t0 = 0.0f, t1 = limit;
    int axis = -1;
    for (int a = 0; a < 3; ++a) {
        if (d[a] == 0.0f) {
            if (o[a] < lo[a] || o[a] > hi[a]) {
                return std::nullopt;
            }
            continue;
        }
        float ta = (lo[a] - o[a]) / d[a], tb = (hi[a] - o[a]) / d[a];
        if (ta > tb) {
            std::swap(ta, tb);
        }
        if (ta > t0) {
            t0 = ta;
            axis = a;
        }
        t1 = std::min(t1, tb);
        if (t0 > t1) {
            return std::nullopt;
        }
    }
    return SlabSpan{t0, t1, axis};
}

/// Entry distance into the box [lo, hi] along d for 0 <= s <= limit and the axis of the face
/// entered (-1: none crossed, the ray starts in the slab of every axis); none when the origin
/// is on or in the box (within 1e-3).
std::optional<std::pair<float, int>> box_entry(
    const glm::vec3 &lo, const glm::vec3 &hi, const glm::vec3 &o, const glm::vec3 &d, float limit)
{
    constexpr float kEps = 1e-3f;
    if (glm::all(glm::greaterThan(o, lo - kEps)) && glm::all(glm::lessThan(o, hi + kEps))) {
        return std::nullopt;
    }
    const std::optional<SlabSpan> span = slab_span(lo, hi, o, d, limit);
    if (!span) {
        return std::nullopt;
    }
    return std::make_pair(span->enter, span->axis);
}

/// Rays that may cross the whole world: its diagonal plus a kilometre.
float world_reach(const Scene &scene)
{
    return glm::length(
               glm::vec3(float(scene.world.nx), float(scene.world.ny), float(scene.world.nz))) +
           1e3f;
}

/// The truths' strata a side for a sample count (its square root, rounded; at least 1).
int strata_for(int samples)
{
    return std::max(1, int(std::lround(std::sqrt(double(samples)))));
}

/// Sample i of strata x strata over [0, 1)^2: its stratum (row i / strata, column i % strata)
/// jittered by the pixel's and seed's hash.
glm::vec2 stratified(int i, int strata, int x, int y, std::uint32_t seed)
{
    const float u1 = (float(i / strata) + hash_unit(x, y, 2 * i, seed)) / float(strata);
    const float u2 = (float(i % strata) + hash_unit(x, y, 2 * i + 1, seed)) / float(strata);
    return {u1, u2};
}

}  // namespace

bool RayScene::voxels_hit(const glm::vec3 &o, const glm::vec3 &d, float max_dist) const
{
    return voxels_first(o, d, max_dist).has_value();
}

bool RayScene::occluded(const glm::vec3 &o, const glm::vec3 &d, float max_dist) const
{
    for (const Sphere &s : spheres_) {
        if (sphere_distance(s.centre, s.radius, o, d, max_dist)) {
            return true;
        }
    }
    for (const Box &bx : boxes_) {
        if (box_entry(bx.lo, bx.hi, o, d, max_dist)) {
            return true;
        }
    }
    return voxels_hit(o, d, max_dist);
}

std::optional<RayScene::Hit> RayScene::voxels_first(const glm::vec3 &o,
                                                    const glm::vec3 &d,
                                                    float max_dist) const
{
    const glm::vec3 lo(0.0f), hi(float(grid_.nx), float(grid_.ny), float(grid_.nz));
    const std::optional<SlabSpan> span = slab_span(lo, hi, o, d, max_dist);
    if (!span) {
        return std::nullopt;
    }
    // entry_axis: the slab that set t0, the face the ray enters the grid through (-1: inside).
    const float t0 = span->enter, t1 = span->exit;
    const int entry_axis = span->axis;
    const glm::vec3 p = o + d * t0;
    glm::ivec3 cell(int(std::floor(p.x)), int(std::floor(p.y)), int(std::floor(p.z)));
    glm::ivec3 step;
    glm::vec3 next, delta;
    for (int a = 0; a < 3; ++a) {
        const float inf = std::numeric_limits<float>::infinity();
        step[a] = d[a] > 0.0f ? 1 : -1;
        if (a == entry_axis) {
            cell[a] = d[a] > 0.0f ? int(lo[a]) : int(hi[a]) - 1;  // no rounding across the face
        }
        delta[a] = d[a] != 0.0f ? std::abs(1.0f / d[a]) : inf;
        const float boundary = float(cell[a] + (d[a] > 0.0f ? 1 : 0));
        next[a] = d[a] != 0.0f ? t0 + (boundary - p[a]) / d[a] : inf;
    }
    float t = t0;
    int axis = entry_axis;
    while (t <= t1) {
        if (const std::uint8_t m = grid_.at(cell.x, cell.y, cell.z); m != 0) {
            glm::vec3 n(0.0f);
            if (axis >= 0) {
                n[axis] = d[axis] > 0.0f ? -1.0f : 1.0f;
            } else {
                n = -d;  // the ray starts inside a solid cell
            }
            return Hit{t, n, int(m)};
        }
        axis = next.x < next.y ? (next.x < next.z ? 0 : 2) : (next.y < next.z ? 1 : 2);
        t = next[axis];
        next[axis] += delta[axis];
        cell[axis] += step[axis];
    }
    return std::nullopt;
}

std::optional<RayScene::Hit> RayScene::closest(const glm::vec3 &o,
                                               const glm::vec3 &d,
                                               float max_dist) const
{
    std::optional<Hit> best = voxels_first(o, d, max_dist);
    float limit = best ? best->distance : max_dist;
    for (const Sphere &s : spheres_) {
        if (const auto hit = sphere_distance(s.centre, s.radius, o, d, limit)) {
            limit = *hit;
            best = Hit{*hit, glm::normalize(o + d * *hit - s.centre), s.material};
        }
    }
    for (const Box &bx : boxes_) {
        if (const auto entry = box_entry(bx.lo, bx.hi, o, d, limit); entry && entry->second >= 0) {
            glm::vec3 n(0.0f);
            n[entry->second] = d[entry->second] > 0.0f ? -1.0f : 1.0f;
            limit = entry->first;
            best = Hit{entry->first, n, bx.material};
        }
    }
    return best;
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
    const int strata = strata_for(samples);
    const int n = strata * strata;
    const glm::vec3 origin = p + nn * 1e-3f;
    int open = 0;
    for (int i = 0; i < n; ++i) {
        const glm::vec2 u = stratified(i, strata, x, y, seed);
        open +=
            rays.occluded(origin, shading::sample_cosine_hemisphere(nn, u.x, u.y), radius) ? 0 : 1;
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

namespace {

/// Radiance leaving a surface the truth's reflected ray meets, toward the ray's origin: the
/// rasterizer's shading (shading::direct_response with toon bands, add_sky_light) with the sun's
/// shadow from an exact ray instead of a shadow map. Isotropic (a hit has no tangent).
glm::vec3 shade_hit(const Scene &scene,
                    const RayScene &rays,
                    const shading::SceneSky &sky,
                    const glm::vec3 &p,
                    const RayScene::Hit &hit,
                    const glm::vec3 &v)
{
    const Material *mat = scene.material(hit.material);
    if (!mat) {
        return glm::vec3(0.0f);
    }
    shading::Surface surf;
    surf.albedo = mat->albedo;
    surf.roughness = mat->roughness;
    surf.metallic = mat->metallic;
    const glm::vec3 &n = hit.normal;
    const glm::vec3 l = scene.sun.direction;
    glm::vec3 c(0.0f);
    if (glm::dot(n, l) > 0.0f &&
        !rays.occluded(p + n * 1e-3f, l, std::numeric_limits<float>::infinity())) {
        shading::DirectOptions direct;
        direct.toon_bands = mat->toon ? 3 : 0;
        // Path regularisation (Kaplanyan and Dachsbacher 2013): the sun's highlight on a hit is
        // drawn with roughness at least kReflectedSunMinRoughness. A near-mirror hit would
        // otherwise show the sun's glint to a few rays in thousands (sun -> polished floor ->
        // glossy ball -> camera), noise that 256 rays do not average away.
        shading::Surface lobe = surf;
        lobe.roughness = std::max(lobe.roughness, shading::kReflectedSunMinRoughness);
        c = shading::direct_response(lobe, n, v, l, direct) * scene.sun.color *
            scene.sun.illuminance;
    }
    return shading::add_sky_light(c, surf, n, v, sky, sky.ambient(n), scene.sky_ambient);
}

}  // namespace

Image render_reflection_truth(
    const Scene &scene, int frame, const RenderOptions &options, int samples, std::uint32_t seed)
{
    RenderOptions o = options;
    o.supersample = 1;
    o.passes = {
        pass::kColor, pass::kPosition, pass::kNormal, pass::kDepth, pass::kAlbedo, pass::kMaterial};
    const Frame g = render_frame(scene, frame, o);
    const Image &pos = g.image(pass::kPosition), &nrm = g.image(pass::kNormal),
                &depth = g.image(pass::kDepth), &albedo = g.image(pass::kAlbedo),
                &material = g.image(pass::kMaterial);
    Image out = g.image(pass::kColor);
    const RayScene rays(scene, double(frame));
    const shading::SceneSky &sky = shading::scene_sky(scene.sun.direction);
    const glm::vec3 sky_camera(0.0f, shading::kSkyCameraY, 0.0f);
    const glm::vec3 eye = scene.camera_at(double(frame)).position;
    const float max_dist = world_reach(scene);
    const int strata = strata_for(samples);
    parallel_for(0, out.height(), [&](int y) {
        for (int x = 0; x < out.width(); ++x) {
            if (!std::isfinite(depth.at(x, y, 0))) {
                continue;  // the sky
            }
            shading::Surface surf;
            surf.albedo = glm::vec3(albedo.at(x, y, 0), albedo.at(x, y, 1), albedo.at(x, y, 2));
            surf.roughness = material.at(x, y, 0);
            surf.metallic = material.at(x, y, 1);
            const glm::vec3 p(pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2));
            glm::vec3 n =
                glm::normalize(glm::vec3(nrm.at(x, y, 0), nrm.at(x, y, 1), nrm.at(x, y, 2)));
            const glm::vec3 v = glm::normalize(eye - p);
            if (glm::dot(n, v) < 0.0f) {
                n = -n;  // as the rasterizer: shade the side we see
            }
            const glm::vec3 weight = shading::sky_reflection_weight(surf, n, v);
            if (weight == glm::vec3(0.0f)) {
                continue;
            }
            const float alpha = shading::roughness_to_alpha(surf.roughness);
            const glm::vec3 origin = p + n * 1e-3f;
            glm::vec3 sum(0.0f);
            float wsum = 0.0f;
            for (int i = 0; i < strata * strata; ++i) {
                const glm::vec2 u = stratified(i, strata, x, y, seed);
                const glm::vec3 l = shading::sample_ggx_reflection(n, v, alpha, u.x, u.y);
                const float nl = glm::dot(n, l);
                if (!(nl > 0.0f)) {
                    continue;
                }
                glm::vec3 radiance;
                if (const auto hit = rays.closest(origin, l, max_dist)) {
                    radiance = shade_hit(scene, rays, sky, origin + l * hit->distance, *hit, -l);
                } else {
                    radiance = sky.radiance(l, sky_camera, false) * scene.sky_ambient;
                }
                sum += radiance * nl;
                wsum += nl;
            }
            if (wsum <= 0.0f) {
                continue;
            }
            const glm::vec3 r = glm::reflect(-v, n);
            const glm::vec3 d =
                weight * (sum / wsum - sky.radiance(r, sky_camera, false) * scene.sky_ambient);
            float *px = out.pixel(x, y);
            px[0] += d.x;
            px[1] += d.y;
            px[2] += d.z;
        }
    });
    return out;
}

GiTruth render_gi_truth(
    const Scene &scene, int frame, const RenderOptions &options, int samples, std::uint32_t seed)
{
    RenderOptions o = options;
    o.passes = {
        pass::kColor, pass::kPosition, pass::kNormal, pass::kDepth, pass::kAlbedo, pass::kMaterial};
    const Frame g = render_frame(scene, frame, o);
    const Image &pos = g.image(pass::kPosition), &nrm = g.image(pass::kNormal),
                &depth = g.image(pass::kDepth), &albedo = g.image(pass::kAlbedo),
                &material = g.image(pass::kMaterial);
    GiTruth out{g.image(pass::kColor), Image(pos.width(), pos.height(), 3)};
    const RayScene rays(scene, double(frame));
    const shading::SceneSky &sky = shading::scene_sky(scene.sun.direction);
    const glm::vec3 eye = scene.camera_at(double(frame)).position;
    const float max_dist = world_reach(scene);
    const int strata = strata_for(samples);
    parallel_for(0, pos.height(), [&](int y) {
        for (int x = 0; x < pos.width(); ++x) {
            if (!std::isfinite(depth.at(x, y, 0))) {
                continue;  // the sky
            }
            const glm::vec3 diffuse =
                glm::vec3(albedo.at(x, y, 0), albedo.at(x, y, 1), albedo.at(x, y, 2)) *
                (1.0f - material.at(x, y, 1));
            if (diffuse == glm::vec3(0.0f)) {
                continue;
            }
            const glm::vec3 p(pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2));
            glm::vec3 n =
                glm::normalize(glm::vec3(nrm.at(x, y, 0), nrm.at(x, y, 1), nrm.at(x, y, 2)));
            if (glm::dot(n, eye - p) < 0.0f) {
                n = -n;  // as the rasterizer: shade the side we see
            }
            const glm::vec3 origin = p + n * 1e-3f;
            glm::vec3 sum(0.0f);
            for (int i = 0; i < strata * strata; ++i) {
                const glm::vec2 u = stratified(i, strata, x, y, seed);
                const glm::vec3 l = shading::sample_cosine_hemisphere(n, u.x, u.y);
                if (const auto hit = rays.closest(origin, l, max_dist)) {
                    sum += shade_hit(scene, rays, sky, origin + l * hit->distance, *hit, -l);
                }
            }
            // Cosine-weighted rays: irradiance pi mean(L), a Lambertian surface returns
            // albedo / pi of it.
            const glm::vec3 add = diffuse * sum / float(strata * strata);
            float *px = out.color.pixel(x, y);
            float *ind = out.indirect.pixel(x, y);
            for (int c = 0; c < 3; ++c) {
                px[c] += add[c];
                ind[c] = add[c];
            }
        }
    });
    return out;
}

EnvironmentProbe render_environment_probe(
    const Scene &scene, int frame, int width, int height, int samples, std::uint32_t seed)
{
    EnvironmentProbe probe;
    probe.color = Image(width, height, 4);
    probe.distance = Image(width, height, 1);
    probe.position = scene.camera_at(double(frame)).position;
    const RayScene rays(scene, double(frame));
    const shading::SceneSky &sky = shading::scene_sky(scene.sun.direction);
    const glm::vec3 sky_camera(0.0f, shading::kSkyCameraY, 0.0f);
    const float max_dist = world_reach(scene);
    const int strata = strata_for(samples);
    const float inf = std::numeric_limits<float>::infinity();
    const glm::vec3 o = probe.position;
    const auto radiance = [&](const glm::vec3 &l) {
        if (const auto hit = rays.closest(o, l, max_dist)) {
            return shade_hit(scene, rays, sky, o + l * hit->distance, *hit, -l);
        }
        return sky.radiance(l, sky_camera, false) * scene.sky_ambient;
    };
    parallel_for(0, height, [&](int y) {
        for (int x = 0; x < width; ++x) {
            glm::vec3 sum(0.0f);
            for (int i = 0; i < strata * strata; ++i) {
                const float jx = (float(i % strata) + hash_unit(x, y, 2 * i, seed)) / float(strata);
                const float jy =
                    (float(i / strata) + hash_unit(x, y, 2 * i + 1, seed)) / float(strata);
                sum += radiance(shading::latlong_direction((float(x) + jx) / float(width),
                                                           (float(y) + jy) / float(height)));
            }
            sum /= float(strata * strata);
            float *px = probe.color.pixel(x, y);
            px[0] = sum.x;
            px[1] = sum.y;
            px[2] = sum.z;
            px[3] = 1.0f;
            const glm::vec3 centre = shading::latlong_direction((float(x) + 0.5f) / float(width),
                                                                (float(y) + 0.5f) / float(height));
            const auto hit = rays.closest(o, centre, max_dist);
            probe.distance.at(x, y, 0) = hit ? hit->distance : inf;
        }
    });
    return probe;
}

}  // namespace posthaste::raster
