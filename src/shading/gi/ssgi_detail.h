#pragma once
// What ssgi's march (ssgi.cpp) and its trace of the sun reflected by glossy planes
// (ssgi_glint.cpp) share: the computed pixels' surfaces, and the planes found among them.

#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "shading/camera_rays.h"
#include "shading/lighting/brdf.h"

namespace posthaste::shading::gi_detail {

/// A computed pixel's surface as a lit sample reads it: the unit normal on the camera's side, the
/// lit colour (its block's mean).
struct Shade {
    glm::vec3 n{0.0f}, l{0.0f};
};

/// A computed pixel's surface for the re-shading: its material, the sun's visibility, and its
/// view-dependent shading as the camera sees it (sun response and sky light).
/// 48 bytes (a Surface with its unused tangent would make 64): the march reads one per lit
/// sample, scattered.
struct Reshade {
    glm::vec3 albedo{0.0f};
    float roughness = 0.0f, metallic = 0.0f;
    float vis = 0.0f;
    glm::vec3 ambient{0.0f}, seen{0.0f};

    Surface surface() const
    {
        Surface s;
        s.albedo = albedo;
        s.roughness = roughness;
        s.metallic = metallic;
        return s;
    }
};

/// The computed pixels' grid: ow x oh pixels, each the top-left of a stride x stride block of
/// the w x h passes, and a point of it at camera depth z in the world.
struct Grid {
    Grid(const CameraRays &r, int width, int height, int st)
        : rays(&r),
          w(width),
          h(height),
          stride(st),
          ow((width + st - 1) / st),
          oh((height + st - 1) / st),
          inv_w(1.0f / float(width)),
          inv_h(1.0f / float(height)),
          px_world_1(glm::length(r.ray_du()) * inv_w * float(st))
    {
    }

    const CameraRays *rays;
    int w, h, stride, ow, oh;
    float inv_w, inv_h;
    float px_world_1;  ///< World units per computed pixel at depth 1.

    glm::vec3 position(int ox, int oy, float z) const
    {
        return rays->position() + z * rays->depth_ray((float(ox * stride) + 0.5f) * inv_w,
                                                      (float(oy * stride) + 0.5f) * inv_h);
    }
};

inline constexpr int kGlintPlanes = 2;

/// The frame's glossy planes (SsgiParams::reflected_sun) and the computed pixels on them.
struct Glints {
    int count = 0;
    glm::vec3 normal[kGlintPlanes];  ///< Unit, facing the sun.
    glm::vec3 toward[kGlintPlanes];  ///< From a receiver to the sun's mirror image: s - 2 (n.s) n.
    /// The range of n.x over the plane's pixels x: where along n its surfaces lie.
    float lo[kGlintPlanes] = {}, hi[kGlintPlanes] = {};
    /// The lobe's directional albedo with F = 1 at the sun's angle to the plane, for the lobe
    /// roughness max(r, kReflectedSunMinRoughness) of a glossy surface: kAlbedoSteps values
    /// evenly from that least roughness to the most a glossy surface has.
    static constexpr int kAlbedoSteps = 5;
    float albedo[kGlintPlanes][kAlbedoSteps] = {};
    /// Per computed pixel: the plane it belongs to, -1 for none (empty without planes).
    std::vector<std::int8_t> family;
    /// From a world offset from the camera to (z, z u, z v): camera depth z and NDC (u, v).
    glm::mat3 to_ndc{1.0f};
};

/// The glossy planes among the computed pixels (`zs` camera depth, 0 for the sky; shades'
/// normals; reshades' roughness) for the sun in unit direction `sun`. Same bits for any thread
/// count.
Glints find_glints(const std::vector<float> &zs,
                   const std::vector<Shade> &shades,
                   const std::vector<Reshade> &reshades,
                   const glm::vec3 &sun,
                   const Grid &grid);

/// The sun's light the glossy planes reflect toward a computed pixel's surface (point P, unit
/// normal N, camera depth z; `jitter` in [0, 1) places the march's steps), per unit of the sun's
/// irradiance: sum over the planes of F E vis cos / pi (ssgi.md). `radius` bounds the march.
glm::vec3 glint_light(const Glints &g,
                      const std::vector<float> &zs,
                      const std::vector<Reshade> &reshades,
                      const Grid &grid,
                      const glm::vec3 &sun,
                      float radius,
                      const glm::vec3 &P,
                      const glm::vec3 &N,
                      float z,
                      float jitter);

}  // namespace posthaste::shading::gi_detail
