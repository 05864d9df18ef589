#pragma once
// Environment maps in the latitude-longitude (equirectangular) layout: what a renderer's
// panoramic camera writes, and the reflection probe `render` makes with `projection: latlong`.
// The layout, world +y up: column u in [0, 1) turns once around the vertical axis, u = 0.5
// looking down -z (the direction a camera with no rotation looks), u increasing toward +x;
// row v in [0, 1] from straight up (v = 0, the top row) to straight down. A direction d maps
// to u = 0.5 + atan2(d.x, -d.z) / 2 pi, v = acos(d.y) / pi.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
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

/// A latitude-longitude map resampled onto the six faces of a cube (the nearest texel of the
/// map at each cube texel's centre), so that a look-up is a division instead of an arctangent
/// and an arccosine. T is what a texel holds, made from the map's pixel by `texel`.
template <typename T>
class LatLongCube {
   public:
    LatLongCube() = default;
    /// Faces of n x n texels; texel(const float *pixel) -> T.
    template <typename Texel>
    LatLongCube(const Image &latlong, int n, Texel texel)
        : LatLongCube(from_directions(n, [&](const glm::vec3 &d) {
              const glm::vec2 uv = latlong_uv(d);
              const int x = std::min(int(uv.x * float(latlong.width())), latlong.width() - 1);
              const int y = std::min(int(uv.y * float(latlong.height())), latlong.height() - 1);
              return texel(latlong.pixel(x, y));
          }))
    {
    }

    /// Faces of n x n texels, each `texel(d)` of the unit direction d through its centre.
    template <typename Texel>
    static LatLongCube from_directions(int n, Texel texel)
    {
        LatLongCube c;
        c.n_ = n;
        c.texels_.resize(std::size_t(6) * std::size_t(n) * std::size_t(n));
        for (int f = 0; f < 6; ++f) {
            const int m = f / 2, u = (m + 1) % 3, v = (m + 2) % 3;
            for (int j = 0; j < n; ++j) {
                for (int i = 0; i < n; ++i) {
                    glm::vec3 d(0.0f);
                    d[m] = f % 2 == 0 ? 1.0f : -1.0f;
                    d[u] = (float(i) + 0.5f) / float(n) * 2.0f - 1.0f;
                    d[v] = (float(j) + 0.5f) / float(n) * 2.0f - 1.0f;
                    c.texels_[c.index(f, i, j)] = texel(glm::normalize(d));
                }
            }
        }
        return c;
    }

    /// The texel seen in the direction of x (any non-zero vector).
    const T &at(const glm::vec3 &x) const
    {
        const glm::vec3 a = glm::abs(x);
        const int m = a.x >= a.y ? (a.x >= a.z ? 0 : 2) : (a.y >= a.z ? 1 : 2);
        const int u = (m + 1) % 3, v = (m + 2) % 3;
        const float inv = 0.5f * float(n_) / a[m];
        const int i = std::clamp(int((x[u] + a[m]) * inv), 0, n_ - 1);
        const int j = std::clamp(int((x[v] + a[m]) * inv), 0, n_ - 1);
        return texels_[index(2 * m + (x[m] >= 0.0f ? 0 : 1), i, j)];
    }
    int size() const { return n_; }

   private:
    std::size_t index(int f, int i, int j) const
    {
        return (std::size_t(f) * std::size_t(n_) + std::size_t(j)) * std::size_t(n_) +
               std::size_t(i);
    }
    int n_ = 1;
    std::vector<T> texels_;  ///< Face-major: face (0..5: +x -x +y -y +z -z), row, column.
};

/// A probe's distances on a cube (LatLongCube), so that a march looks them up with a division
/// per step.
class DistanceCube {
   public:
    /// From a latitude-longitude distance map (one channel, >= 0 or +inf; NaN reads as +inf),
    /// faces of `size` x `size` texels (0: a quarter of the map's width, at most 128).
    explicit DistanceCube(const Image &latlong, int size = 0);

    /// The distance seen in the direction of x (any non-zero vector).
    float at(const glm::vec3 &x) const { return cube_.at(x); }
    /// The farthest finite distance (0 when there is none): past the sphere of this radius
    /// around the probe a ray meets nothing the probe saw.
    float reach() const { return reach_; }
    int size() const { return cube_.size(); }

   private:
    LatLongCube<float> cube_;
    float reach_ = 0.0f;
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
