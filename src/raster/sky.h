#pragma once
// The sky seen by the rasterizer: background radiance and the source of ambient light. A simple
// analytic gradient for now; it is the one place the Hillaire atmosphere (shading/atmosphere)
// plugs in later.

#include <glm/vec3.hpp>

namespace posthaste::raster {

/// Scene-linear radiance of the sky in unit direction `dir` (world, y up) with the sun toward
/// unit `sun_dir`: a zenith-to-horizon gradient, a darker ground below the horizon, and a soft
/// glow around the sun (the sun disc itself is not drawn). Finite for every unit input.
glm::vec3 sky_radiance(const glm::vec3 &dir, const glm::vec3 &sun_dir);

/// Cosine-weighted irradiance from the sky onto a surface with unit normal n, divided by pi
/// (so that albedo * sky_ambient_radiance(n) is the reflected diffuse radiance). Approximated by
/// a hemispherical blend of the zenith, horizon and ground radiances.
glm::vec3 sky_ambient_radiance(const glm::vec3 &n, const glm::vec3 &sun_dir);

}  // namespace posthaste::raster
