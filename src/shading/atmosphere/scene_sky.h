#pragma once
// The sky of a scene, as both the rasterizer's beauty and the fog node show it: the Hillaire
// atmosphere's sky-view radiance above the horizon, and below it the lit planet ground (the
// scene is a small patch of it) seen through the atmosphere; plus the diffuse light all of that
// sends onto a surface, as order-2 spherical harmonics.
//
// Ground: Lambertian with the atmosphere's ground_albedo, lit by the sun (attenuated by the
// atmosphere) and by the sky (hemispherical irradiance); the view ray to it is attenuated by the
// ground-level extinction over the flat-ground distance camera altitude / -dir.y.

#include <array>
#include <glm/vec3.hpp>

#include "shading/atmosphere/atmosphere.h"

namespace posthaste::shading {

class SceneSky {
   public:
    /// Precomputes the ground's irradiance and the ambient harmonics from `atmosphere` (a few ms).
    /// The atmosphere must outlive this object.
    explicit SceneSky(const Atmosphere &atmosphere);

    /// Radiance toward the viewer from unit world direction `dir`, for a camera at `camera_pos`
    /// (world, scene units); with `sun_disc`, the sun's disc is included.
    glm::vec3 radiance(const glm::vec3 &dir, const glm::vec3 &camera_pos, bool sun_disc) const;
    /// The lit ground's contribution along a downward `dir` (0 above the horizon): what
    /// radiance() adds to the atmosphere's in-scatter there.
    glm::vec3 ground(const glm::vec3 &dir, const glm::vec3 &camera_pos) const;
    /// Irradiance / pi onto a surface with unit normal n from the whole sky and ground (no sun):
    /// albedo * ambient(n) is the reflected diffuse radiance.
    glm::vec3 ambient(const glm::vec3 &n) const;

    const Atmosphere &atmosphere() const { return *atmosphere_; }

   private:
    const Atmosphere *atmosphere_;
    glm::vec3 ground_radiance_{0.0f};  ///< Lambertian ground, before the view-ray attenuation.
    glm::vec3 extinction_{0.0f};       ///< Ground-level extinction per metre.
    std::array<glm::vec3, 9> sh_{};    ///< Irradiance / pi as SH coefficients.
};

}  // namespace posthaste::shading
