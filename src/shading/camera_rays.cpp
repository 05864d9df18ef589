#include "shading/camera_rays.h"

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec4.hpp>

namespace posthaste::shading {
namespace {

// The camera-space point at depth 1 on the ray through NDC (u, v): unproject two points of the
// ray, take their difference in camera space and scale it to z = 1.
glm::vec3 camera_depth_ray(const glm::mat4 &ndc_to_camera, float u, float v)
{
    const glm::vec4 a = ndc_to_camera * glm::vec4(u, v, 0.25f, 1.0f);
    const glm::vec4 b = ndc_to_camera * glm::vec4(u, v, 0.75f, 1.0f);
    const glm::vec3 d = glm::vec3(b) / b.w - glm::vec3(a) / a.w;
    return d / d.z;
}

}  // namespace

CameraRays::CameraRays(const glm::mat4 &world_to_camera, const glm::mat4 &world_to_ndc)
{
    const glm::mat4 camera_to_world = glm::inverse(world_to_camera);
    const glm::mat4 ndc_to_camera = world_to_camera * glm::inverse(world_to_ndc);
    const glm::mat3 rotation(camera_to_world);
    position_ = glm::vec3(camera_to_world[3]);
    const glm::vec3 p00 = rotation * camera_depth_ray(ndc_to_camera, 0.0f, 0.0f);
    const glm::vec3 p10 = rotation * camera_depth_ray(ndc_to_camera, 1.0f, 0.0f);
    const glm::vec3 p01 = rotation * camera_depth_ray(ndc_to_camera, 0.0f, 1.0f);
    origin_ = p00;
    du_ = p10 - p00;
    dv_ = p01 - p00;
}

glm::vec3 CameraRays::direction(float u, float v) const
{
    return glm::normalize(depth_ray(u, v));
}

}  // namespace posthaste::shading
