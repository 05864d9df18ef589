// The sun that a frame's glossy planes reflect, traced for ssgi (docs/nodes/ssgi.md,
// `reflected_sun`): the planes are found among the computed pixels' normals, and each receiver
// marches one ray toward the sun's mirror image in each plane.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/parallel.h"
#include "shading/gi/ssgi_detail.h"
#include "shading/lighting/lighting.h"

namespace posthaste::shading::gi_detail {
namespace {

/// Glossy surfaces whose sun highlight the trace carries: roughness at most this (their lobe,
/// at least kReflectedSunMinRoughness wide, is narrow enough to stand for its mirror direction).
constexpr float kGlossy = 0.4f;
/// A surface belongs to a plane's family when its normal is within 5.7 degrees of the plane's.
constexpr float kFamilyCos = 0.995f;
/// A bin of normals is a plane when 90 % of its pixels lie within 0.8 degrees of its mean (a
/// curved surface's normals spread over the bin's 11 degrees).
constexpr float kFlatCos = 0.9999f;
constexpr int kBins = 16;
constexpr Geometry kLobe = Geometry::SmithCorrelated;  // the truth's, as render's

/// The lobe roughness of Glints::albedo's j-th value.
float albedo_roughness(int j)
{
    return kReflectedSunMinRoughness +
           (kGlossy - kReflectedSunMinRoughness) * float(j) / float(Glints::kAlbedoSteps - 1);
}
/// Steps of the march toward a plane (16 gave the same error on the glossy scene).
constexpr int kSteps = 8;

/// The bin of a unit normal on a kBins x kBins octahedral grid.
int octahedral_bin(const glm::vec3 &n)
{
    const float l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
    float u = n.x / l1, v = n.y / l1;
    if (n.z < 0.0f) {
        const float fu = (1.0f - std::abs(v)) * (u < 0.0f ? -1.0f : 1.0f);
        const float fv = (1.0f - std::abs(u)) * (v < 0.0f ? -1.0f : 1.0f);
        u = fu;
        v = fv;
    }
    const int bx = std::clamp(int((u * 0.5f + 0.5f) * float(kBins)), 0, kBins - 1);
    const int by = std::clamp(int((v * 0.5f + 0.5f) * float(kBins)), 0, kBins - 1);
    return by * kBins + bx;
}

}  // namespace

Glints find_glints(const std::vector<float> &zs,
                   const std::vector<Shade> &shades,
                   const std::vector<Reshade> &reshades,
                   const glm::vec3 &sun,
                   const Grid &grid)
{
    // The glossy computed pixels' normals binned, each bin's count and mean: in kBands bands
    // of rows, in parallel, then the bands in order (the same sums for any thread count).
    constexpr int kBands = 16;
    const std::size_t count = zs.size(), ow = std::size_t(grid.ow);
    std::vector<std::int16_t> bin(count, -1);
    std::vector<int> band_counts(std::size_t(kBands) * kBins * kBins, 0), band_surfaces(kBands, 0);
    std::vector<glm::dvec3> band_sums(std::size_t(kBands) * kBins * kBins, glm::dvec3(0.0));
    parallel_for(0, kBands, [&](int band) {
        int *counts = &band_counts[std::size_t(band) * kBins * kBins];
        glm::dvec3 *sums = &band_sums[std::size_t(band) * kBins * kBins];
        const std::size_t y0 = std::size_t(band * grid.oh / kBands);
        const std::size_t y1 = std::size_t((band + 1) * grid.oh / kBands);
        for (std::size_t i = y0 * ow; i < y1 * ow; ++i) {
            if (zs[i] == 0.0f) {
                continue;
            }
            ++band_surfaces[std::size_t(band)];
            if (!(reshades[i].roughness <= kGlossy)) {
                continue;
            }
            const int b = octahedral_bin(shades[i].n);
            bin[i] = std::int16_t(b);
            ++counts[b];
            sums[b] += glm::dvec3(shades[i].n);
        }
    });
    std::vector<int> counts(kBins * kBins, 0);
    std::vector<glm::dvec3> sums(kBins * kBins, glm::dvec3(0.0));
    int surfaces = 0;
    for (int band = 0; band < kBands; ++band) {
        surfaces += band_surfaces[std::size_t(band)];
        for (std::size_t b = 0; b < counts.size(); ++b) {
            counts[b] += band_counts[std::size_t(band) * counts.size() + b];
            sums[b] += band_sums[std::size_t(band) * counts.size() + b];
        }
    }
    // The fullest bins that hold at least 2 % of the surface pixels, are flat and face the sun.
    Glints g;
    const int least = std::max(16, surfaces / 50);
    while (g.count < kGlintPlanes) {
        const auto most = std::max_element(counts.begin(), counts.end());
        if (*most < least) {
            break;
        }
        const int b = int(most - counts.begin()), in_bin = *most;
        *most = 0;
        const glm::vec3 n = glm::vec3(glm::normalize(sums[std::size_t(b)]));
        const float ns = glm::dot(n, sun);
        if (!(ns > 0.01f)) {
            continue;
        }
        std::vector<int> band_flat(kBands, 0);
        parallel_for(0, kBands, [&](int band) {
            const std::size_t y0 = std::size_t(band * grid.oh / kBands);
            const std::size_t y1 = std::size_t((band + 1) * grid.oh / kBands);
            for (std::size_t i = y0 * ow; i < y1 * ow; ++i) {
                band_flat[std::size_t(band)] += bin[i] == b && glm::dot(shades[i].n, n) >= kFlatCos;
            }
        });
        int flat = 0;
        for (const int f : band_flat) {
            flat += f;
        }
        if (flat * 10 < in_bin * 9) {
            continue;
        }
        g.normal[g.count] = n;
        g.toward[g.count] = glm::normalize(sun - 2.0f * ns * n);
        // A few lobes' albedos at this angle, not the Kulla-Conty table (2 million BRDF values,
        // tens of milliseconds in a process's first frame).
        for (int j = 0; j < Glints::kAlbedoSteps; ++j) {
            g.albedo[g.count][j] = specular_albedo(albedo_roughness(j), ns, kLobe, 1024);
        }
        ++g.count;
    }
    if (g.count == 0) {
        return g;
    }
    const CameraRays &rays = *grid.rays;
    g.to_ndc = glm::inverse(glm::mat3(rays.ray_origin(), rays.ray_du(), rays.ray_dv()));
    // Each computed pixel's plane, and per plane the range of n.x over its pixels (per row,
    // then over the rows: a minimum and maximum, the same whatever the order).
    g.family.assign(count, -1);
    const int oh = grid.oh;
    std::vector<float> row_lo(std::size_t(oh) * kGlintPlanes, INFINITY);
    std::vector<float> row_hi(std::size_t(oh) * kGlintPlanes, -INFINITY);
    parallel_for(0, oh, [&](int oy) {
        for (int ox = 0; ox < grid.ow; ++ox) {
            const std::size_t i = std::size_t(oy) * ow + std::size_t(ox);
            if (bin[i] < 0) {
                continue;
            }
            for (int k = 0; k < g.count; ++k) {
                if (glm::dot(shades[i].n, g.normal[k]) >= kFamilyCos) {
                    g.family[i] = std::int8_t(k);
                    const float d = glm::dot(g.normal[k], grid.position(ox, oy, zs[i]));
                    float &lo = row_lo[std::size_t(oy) * kGlintPlanes + std::size_t(k)];
                    float &hi = row_hi[std::size_t(oy) * kGlintPlanes + std::size_t(k)];
                    lo = std::min(lo, d);
                    hi = std::max(hi, d);
                    break;
                }
            }
        }
    });
    for (int k = 0; k < g.count; ++k) {
        g.lo[k] = INFINITY;
        g.hi[k] = -INFINITY;
        for (int oy = 0; oy < oh; ++oy) {
            g.lo[k] = std::min(g.lo[k], row_lo[std::size_t(oy) * kGlintPlanes + std::size_t(k)]);
            g.hi[k] = std::max(g.hi[k], row_hi[std::size_t(oy) * kGlintPlanes + std::size_t(k)]);
        }
    }
    return g;
}

glm::vec3 glint_light(const Glints &g,
                      const std::vector<float> &zs,
                      const std::vector<Reshade> &reshades,
                      const Grid &grid,
                      const glm::vec3 &sun,
                      float radius,
                      const glm::vec3 &P,
                      const glm::vec3 &N,
                      float z,
                      float jitter)
{
    const CameraRays &rays = *grid.rays;
    const float sx_scale = float(grid.w) / float(grid.stride);
    const float sy_scale = float(grid.h) / float(grid.stride);
    // Past the point's own pixels: two computed pixels at its depth.
    const float t0 = 2.0f * z * grid.px_world_1;
    glm::vec3 light(0.0f);
    for (int k = 0; k < g.count; ++k) {
        const glm::vec3 &dir = g.toward[k];
        const float cos_r = glm::dot(N, dir);
        if (!(cos_r > 0.0f)) {
            continue;
        }
        // dir.n = -(n.s): the ray meets the plane's surfaces between these lengths.
        const float ns = glm::dot(g.normal[k], sun), np = glm::dot(g.normal[k], P);
        const float t_near = (np - g.hi[k]) / ns, t_far = (np - g.lo[k]) / ns;
        if (!(t_far > t0) || !(t_near <= radius)) {
            continue;  // no surface of the plane within reach
        }
        // Steps out to a little past the farthest surface, spaced evenly.
        const float t_end = std::min(radius, t_far * 1.1f + t0);
        // The ray's image in (z, z u, z v) is linear in its length: a step is three additions
        // and a division.
        const glm::vec3 q0 = g.to_ndc * (P - rays.position()), dq = g.to_ndc * dir;
        for (int i = 0; i < kSteps; ++i) {
            const float t = t0 + (t_end - t0) * ((float(i) + jitter) / float(kSteps));
            const glm::vec3 q = q0 + t * dq;
            if (!(q.x > 0.0f)) {
                break;  // behind the camera
            }
            const float inv = 1.0f / q.x;
            const float sx = q.y * inv * sx_scale, sy = q.z * inv * sy_scale;
            if (!(sx >= 0.0f && sy >= 0.0f && sx < float(grid.ow) && sy < float(grid.oh))) {
                break;  // off screen
            }
            const std::size_t qi =
                std::size_t(int(sy)) * std::size_t(grid.ow) + std::size_t(int(sx));
            const float qz = zs[qi];
            if (qz == 0.0f || q.x < qz || q.x - qz > 0.25f * radius) {
                continue;  // in front of the surface shown, or hidden behind it
            }
            if (g.family[qi] == k) {
                // The highlight's light integrated over its lobe: Schlick Fresnel at the mirror
                // angle times the lobe's directional albedo, from the image's direction.
                const Reshade &r = reshades[qi];
                const float f = std::clamp((r.roughness - kReflectedSunMinRoughness) /
                                               (kGlossy - kReflectedSunMinRoughness),
                                           0.0f,
                                           1.0f) *
                                float(Glints::kAlbedoSteps - 1);
                const int j = std::min(int(f), Glints::kAlbedoSteps - 2);
                const float e =
                    g.albedo[k][j] + (g.albedo[k][j + 1] - g.albedo[k][j]) * (f - float(j));
                light += fresnel_schlick(specular_f0(r.surface()), ns) * (r.vis * e * cos_r);
            }
            break;
        }
    }
    return light / kPi;
}

}  // namespace posthaste::shading::gi_detail
