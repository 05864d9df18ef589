#pragma once
// Environment maps in the latitude-longitude (equirectangular) layout: what a renderer's
// panoramic camera writes, and the reflection probe `render` makes with `projection: latlong`.
// The layout, world +y up: column u in [0, 1) turns once around the vertical axis, u = 0.5
// looking down -z (the direction a camera with no rotation looks), u increasing toward +x;
// row v in [0, 1] from straight up (v = 0, the top row) to straight down. A direction d maps
// to u = 0.5 + atan2(d.x, -d.z) / 2 pi, v = acos(d.y) / pi.

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <limits>
#include <vector>

#include "core/image.h"

namespace posthaste::shading {

/// The (u, v) of a unit direction (see the file comment). u in [0, 1], v in [0, 1].
glm::vec2 latlong_uv(const glm::vec3 &d);

/// The unit direction at (u, v): the inverse of latlong_uv.
glm::vec3 latlong_direction(float u, float v);

/// A latitude-longitude map held by reference: bilinear lookups of its first three channels,
/// wrapping around in u and clamped at the poles. The image must be finite (the node sanitises
/// it) and outlive the map.
class LatLongMap {
   public:
    explicit LatLongMap(const Image &image) : image_(&image) {}

    /// The map's RGB in direction d (unit).
    glm::vec3 radiance(const glm::vec3 &d) const;

   private:
    const Image *image_;
};

/// A probe's distances resampled onto the six faces of a cube (nearest texel of the
/// latitude-longitude map at each cube texel's centre), so that a march looks them up with a
/// division instead of an arctangent and an arccosine per step.
class DistanceCube {
   public:
    /// From a latitude-longitude distance map (one channel, >= 0 or +inf; NaN reads as +inf),
    /// faces of `size` x `size` texels (0: a quarter of the map's width, at most 128).
    explicit DistanceCube(const Image &latlong, int size = 0);

    /// The distance seen in the direction of x (any non-zero vector).
    float at(const glm::vec3 &x) const;
    /// The farthest finite distance (0 when there is none): past the sphere of this radius
    /// around the probe a ray meets nothing the probe saw.
    float reach() const { return reach_; }
    int size() const { return n_; }

   private:
    int n_;
    float reach_ = 0.0f;
    std::vector<float> texels_;  ///< Face-major: face (0..5: +x -x +y -y +z -z), row, column.
};

/// A reflection probe taken at `position`: its radiance map and, optionally, the distance from
/// the position to the surface each texel sees (+inf for the sky). Without distances a ray sees
/// the map in its own direction (everything infinitely far: no parallax); with them, a ray from
/// `origin` sees the probe's surface where it first crosses it (a march through the distances,
/// as the screen-space march through the depth pass), and the map in its own direction where it
/// crosses none.
struct Probe {
    const Image *radiance = nullptr;         ///< RGB(A), finite.
    const DistanceCube *distance = nullptr;  ///< Null: everything infinitely far.
    glm::vec3 position{0.0f};
    float max_distance = 60.0f;  ///< How far a ray is marched.
    float thickness = 0.5f;      ///< How far a surface is taken to extend behind its distance.
    int march_steps = 16;
    int refine_steps = 5;

    /// What the ray origin + s dir (dir unit) sees of the probe.
    glm::vec3 seen(const glm::vec3 &origin, const glm::vec3 &dir) const;
};

}  // namespace posthaste::shading
