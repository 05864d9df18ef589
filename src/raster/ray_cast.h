#pragma once
// Exact ray queries against a Minecrappy scene at one instant: the voxel grid by 3-D DDA
// (Amanatides and Woo 1987), the balls as analytic spheres, the moving blocks as boxes. The
// ground truth of screen-space lighting (ambient occlusion) is built on them.

#include <cstdint>
#include <glm/vec3.hpp>
#include <optional>
#include <vector>

#include "core/image.h"
#include "raster/render.h"
#include "raster/scene.h"

namespace posthaste::raster {

class RayScene {
   public:
    /// The scene's geometry at time t (frames): balls and movers placed by their motion.
    RayScene(const Scene &scene, double t);

    /// True when the ray origin + s dir (dir unit length) meets a surface for 0 < s <= max_dist.
    /// A ball or block that holds the origin is ignored (rays leave the surface they start on;
    /// the rendered ball is a tessellation that lies up to 0.2 % of its radius inside the
    /// sphere).
    bool occluded(const glm::vec3 &origin, const glm::vec3 &dir, float max_dist) const;

    /// The first surface the ray meets for 0 < s <= max_dist, with the same rule for balls and
    /// blocks that hold the origin: distance, unit normal facing the ray, material id.
    struct Hit {
        float distance;
        glm::vec3 normal;
        int material;
    };
    std::optional<Hit> closest(const glm::vec3 &origin, const glm::vec3 &dir, float max_dist) const;

   private:
    bool voxels_hit(const glm::vec3 &origin, const glm::vec3 &dir, float max_dist) const;
    /// The DDA of voxels_hit, reporting the first solid cell: distance, entry face, material.
    std::optional<Hit> voxels_first(const glm::vec3 &origin,
                                    const glm::vec3 &dir,
                                    float max_dist) const;

    struct Sphere {
        glm::vec3 centre;
        float radius;
        int material;
    };
    struct Box {
        glm::vec3 lo, hi;
        int material;
    };
    const VoxelGrid &grid_;
    std::vector<Sphere> spheres_;
    std::vector<Box> boxes_;
};

/// The ground truth's estimate at one surface point: the cosine-weighted fraction of `samples`
/// stratified rays around `normal` (unit) that meet no surface within `radius`; jitter hashed
/// from (x, y, sample, seed).
float ao_truth_at(const RayScene &rays,
                  const glm::vec3 &point,
                  const glm::vec3 &normal,
                  float radius,
                  int samples,
                  int x,
                  int y,
                  std::uint32_t seed);

/// Ground-truth ambient occlusion of frame `frame` at options.width x height: at each pixel
/// centre (the surface point and normal of the render's data passes), the cosine-weighted
/// fraction of the hemisphere from which no surface lies within `radius` metres, estimated with
/// `samples` stratified rays (a sqrt(samples)^2 grid of jittered cells, cosine-mapped; jitter
/// hashed from pixel, sample and seed: the same bits for any thread count). 1 on the sky. One
/// channel, in [0, 1].
Image render_ao_truth(const Scene &scene,
                      int frame,
                      const RenderOptions &options,
                      float radius,
                      int samples,
                      std::uint32_t seed);

/// Ground-truth reflections of frame `frame` at options.width x height (supersample 1): the
/// rasterizer's beauty with the sky lookup of its specular term (shading::add_sky_light) replaced
/// by the radiance the reflected rays really meet. At each pixel of a glossy surface (roughness
/// up to 0.78), `samples` stratified GGX directions (shading::sample_ggx_reflection) are traced
/// exactly; a ray that meets a surface sees it shaded as the rasterizer shades (sun with an
/// exact shadow ray, sky light; one bounce: the hit's own specular reflects the sky, hits
/// are shaded isotropic, and the sun's highlight on a hit has roughness at least 0.3: path
/// regularisation, which keeps near-mirror sun glints from turning into fireflies), one that leaves
/// the scene sees the sky times the scene's sky_ambient. Their n.l-weighted mean replaces the sky
/// lookup (shading::sky_reflection_weight). RGBA, premultiplied as the beauty; jitter hashed from
/// pixel, sample and seed.
Image render_reflection_truth(
    const Scene &scene, int frame, const RenderOptions &options, int samples, std::uint32_t seed);

/// Ground-truth one-bounce diffuse global illumination of frame `frame` (data passes one sample
/// a pixel): the rasterizer's beauty plus, at each surface pixel, the light one diffuse bounce
/// brings: `samples` stratified cosine-weighted rays around the normal (the side facing the
/// camera), each surface they meet shaded by its direct light as render_reflection_truth shades
/// it (the sun with an exact shadow ray, the sky light), times the receiver's diffuse albedo
/// (albedo (1 - metallic)); rays that leave the scene add nothing (the beauty's sky light has
/// the whole sky). Returns {color (RGBA, premultiplied as the beauty), the added light alone
/// (RGB)}; jitter hashed from pixel, sample and seed.
struct GiTruth {
    Image color;
    Image indirect;
};
GiTruth render_gi_truth(
    const Scene &scene, int frame, const RenderOptions &options, int samples, std::uint32_t seed);

/// A reflection probe: the radiance seen from one point in every direction, exactly traced, in
/// the latitude-longitude layout of shading/ssr/environment.h.
struct EnvironmentProbe {
    Image color;     ///< RGBA, alpha 1: each hit shaded as render_reflection_truth shades it
                     ///< (viewed from the probe), the sky times sky_ambient where rays leave.
    Image distance;  ///< One channel: distance to the surface met by the texel's centre ray,
                     ///< +inf for the sky.
    glm::vec3 position{0.0f};  ///< Where it was taken.
};

/// The probe of frame `frame` at the camera's position, width x height texels, each the mean of
/// `samples` stratified directions inside the texel (jitter hashed from texel, sample and seed).
EnvironmentProbe render_environment_probe(
    const Scene &scene, int frame, int width, int height, int samples, std::uint32_t seed);

}  // namespace posthaste::raster
