#pragma once
// Per-pixel view rays of a pinhole camera given its OpenEXR matrices (core/camera.h conventions:
// camera space left-handed, +Z forward; NDC [0,1]^2 with (0,0) top-left). Shared by the height fog
// and the aerial perspective so a depth pass converts to a distance along the ray the same way.

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

namespace posthaste::shading {

/// The camera position and, for every NDC point (u, v), the world-space vector from the camera to
/// the point at camera depth 1 on that pixel's ray (camera-space z = 1), which is affine in (u, v).
class CameraRays {
   public:
    CameraRays() = default;
    /// From worldToCamera and worldToNDC (both as in core/camera.h). Any projective pinhole
    /// projection works; an orthographic one does not (rays must meet at the camera).
    CameraRays(const glm::mat4 &world_to_camera, const glm::mat4 &world_to_ndc);

    /// World-space camera position, scene units.
    const glm::vec3 &position() const { return position_; }
    /// World vector to the camera-depth-1 point of NDC (u, v): its length is the distance along
    /// the ray per unit of depth (the `depth` pass is camera-space z).
    glm::vec3 depth_ray(float u, float v) const { return origin_ + u * du_ + v * dv_; }
    /// depth_ray's terms: depth_ray(u, v) = origin() + u du() + v dv(), rounded in that order.
    const glm::vec3 &ray_origin() const { return origin_; }
    const glm::vec3 &ray_du() const { return du_; }
    const glm::vec3 &ray_dv() const { return dv_; }
    /// Unit world-space view direction through NDC (u, v).
    glm::vec3 direction(float u, float v) const;

   private:
    glm::vec3 position_{0.0f};
    glm::vec3 origin_{0.0f, 0.0f, 1.0f}, du_{0.0f}, dv_{0.0f};
};

}  // namespace posthaste::shading
