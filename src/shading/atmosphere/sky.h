#pragma once
// The scene sky: what the rasterizer sees, its background and the source of its ambient light: the
// Hillaire 2020 atmosphere (shading/atmosphere/atmosphere.h) with the lit ground below the horizon
// (shading/atmosphere/scene_sky.h), for a sun of illuminance kSkyIlluminance. The relight node lights with
// the same functions, and the render node writes that illuminance into the header
// (posthaste:sunIlluminance) so the fog node's atmosphere draws the same sky.

#include <glm/vec3.hpp>

namespace posthaste::shading {

class SceneSky;

/// Sun illuminance (per channel) the scene sky is computed for; a brightness choice that keeps
/// the sky's exposure near the surfaces lit by the scene's sun.
inline constexpr float kSkyIlluminance = 10.0f;
/// World y (scene units) of the camera the sky is computed for.
inline constexpr float kSkyCameraY = 1.7f;

/// The scene sky for a sun toward unit `sun_dir` (a zero vector: the default sun
/// (0.4, 0.75, 0.3)), built once per direction and kept for the process. Thread-safe.
const SceneSky &scene_sky(const glm::vec3 &sun_dir);

/// Scene-linear radiance of the sky in unit direction `dir` (world, y up), without the sun disc.
glm::vec3 sky_radiance(const glm::vec3 &dir, const glm::vec3 &sun_dir);

/// Cosine-weighted irradiance from the sky and ground onto a surface with unit normal n, divided
/// by pi (so that albedo * sky_ambient_radiance(n) is the reflected diffuse radiance).
glm::vec3 sky_ambient_radiance(const glm::vec3 &n, const glm::vec3 &sun_dir);

}  // namespace posthaste::shading
