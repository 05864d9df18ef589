#pragma once
// Fog models shared by the fog node and the rasterizer's ground truth.
//
// Exponential height fog with the exact line integral of the density
//   sigma(y) = density * exp(-falloff * (y - base_height))      [1/scene unit]
// along a straight ray, plus the classic OpenGL-style linear, exp and exp^2 fog factors.
// Conventions: world y is up, scene units are metres, directions are unit vectors. A "fog factor"
// or transmittance T is the fraction of surface radiance that survives; the composite is
//   L = L_surface * T + inscatter,   inscatter = (1 - T) * fog radiance.
// Departure from a single-scattering model: the fog radiance is taken as constant along the ray
// (fog colour plus an optional Henyey-Greenstein sun lobe), which is what makes the integral exact.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "core/image.h"
#include "shading/camera_rays.h"
#include "shading/fast_math.h"

namespace posthaste::shading {

/// Parameters of exponential height fog. Every length is in scene units.
struct HeightFog {
    float density = 0.01f;        ///< extinction coefficient at base_height, per scene unit (>= 0).
    float falloff = 0.1f;         ///< b: density scales by exp(-b) per unit of height (>= 0).
    float base_height = 0.0f;     ///< h0: world y where the density equals `density`.
    float start_distance = 0.0f;  ///< no fog closer than this to the camera (along the ray, >= 0).
    glm::vec3 color{0.6f, 0.7f, 0.8f};  ///< fog radiance (scene-linear RGB), isotropic part.
    glm::vec3 sun_color{0.0f};          ///< sun lobe radiance scale; 0 disables the lobe.
    glm::vec3 sun_direction{0.0f, 1.0f, 0.0f};  ///< unit vector towards the sun (world).
    float sun_g = 0.7f;  ///< Henyey-Greenstein asymmetry of the sun lobe, in (-1, 1).
    /// Sky pixels (+inf depth) show the fog's radiance alone (transmittance 0), as if the fog went
    /// on for ever in every direction; otherwise they get the fog of the infinite ray.
    bool opaque_sky = true;
};

/// Transmittance and in-scattered radiance of a fog segment.
struct FogResult {
    float transmittance = 1.0f;  ///< in [0, 1]
    glm::vec3 inscatter{0.0f};   ///< radiance added in front of the surface
};

/// Henyey-Greenstein phase function (1/sr), normalised over the sphere. `cos_theta` is the cosine
/// between the propagation direction of the light and the view ray towards the camera reversed,
/// i.e. dot(view_dir, direction_to_light) for a forward lobe at the light.
inline float henyey_greenstein_phase(float cos_theta, float g)
{
    const float g2 = g * g;
    const float denom = std::max(1.0f + g2 - 2.0f * g * cos_theta, 1e-8f);
    return (1.0f - g2) / (4.0f * 3.14159265358979f * denom * std::sqrt(denom));
}

/// (1 - exp(-x)) / x for any x, with the limit 1 at x = 0; relative error < 2e-6 in float. The
/// integral over [0, L] of exp(-k t) dt equals L * one_minus_exp_over_x(k * L). Overflows to +inf
/// for x < -88.
inline float one_minus_exp_over_x(float x)
{
    if (std::fabs(x) < 0.03f) {
        // Taylor series; truncation error < x^4 / 120 < 7e-9 here.
        return 1.0f - x * (0.5f - x * (1.0f / 6.0f - x * (1.0f / 24.0f)));
    }
    // exp is much cheaper than expm1; the cancellation costs at most about 1 ulp / 0.03 = 4e-6.
    return (1.0f - fast_exp(-x)) / x;
}

/// Per-camera constants of height fog, so that per-pixel work is about two exponentials.
struct HeightFogCamera {
    HeightFog fog;
    glm::vec3 camera{0.0f};
    float log_density_at_camera = 0.0f;  ///< log(density * exp(-b (c_y - h0)))
    float density_at_camera = 0.0f;      ///< exp(log_density_at_camera)
    glm::vec3 lobe_scale{0.0f};          ///< sun_color * (1 - g^2): 4 pi HG = this / d^1.5
    float lobe_a = 1.0f, lobe_b = 0.0f;  ///< d = lobe_a - lobe_b * cos_theta = 1 + g^2 - 2 g cos
    bool has_lobe = false;
    bool empty = true;  ///< density == 0 (or NaN parameters): no fog at all
};

/// Precompute the constants for a camera at `camera` (world position, scene units). Parameters
/// that are NaN, a negative density or a negative falloff disable the fog (`empty`).
inline HeightFogCamera prepare_height_fog(const HeightFog &fog, const glm::vec3 &camera)
{
    HeightFogCamera c;
    c.fog = fog;
    c.camera = camera;
    c.empty = !(fog.density > 0.0f) || !(fog.falloff >= 0.0f) || !std::isfinite(fog.density) ||
              !std::isfinite(fog.falloff) || !std::isfinite(fog.base_height) ||
              !std::isfinite(camera.y);
    c.fog.start_distance =
        std::isfinite(fog.start_distance) ? std::max(fog.start_distance, 0.0f) : 0.0f;
    c.log_density_at_camera =
        c.empty ? 0.0f : std::log(fog.density) - fog.falloff * (camera.y - fog.base_height);
    c.density_at_camera = c.empty ? 0.0f : std::exp(c.log_density_at_camera);
    const float g = std::clamp(std::isfinite(fog.sun_g) ? fog.sun_g : 0.0f, -0.999f, 0.999f);
    c.has_lobe = fog.sun_color != glm::vec3(0.0f);
    c.lobe_scale = fog.sun_color * (1.0f - g * g);
    c.lobe_a = 1.0f + g * g;
    c.lobe_b = 2.0f * g;
    return c;
}

/// Exact optical depth of height fog along the ray camera + t * dir for t in
/// [start_distance, distance], where `dir` is a unit vector (its y component is what matters).
///   tau = a exp(-b (c_y - h0)) * exp(-k t0) * (1 - exp(-k L)) / k,   k = b d_y, L = distance - t0,
/// evaluated as L * (1 - exp(-kL)) / (kL) with a series near kL = 0 (one_minus_exp_over_x) so
/// horizontal rays (k = 0) and b -> 0 are exact. Works with the camera inside, below or above
/// the fog base. Contract: returns 0 when the density is 0 or distance <= start_distance; +inf
/// distance integrates to infinity (finite when looking up with b > 0, +inf otherwise); a NaN
/// distance or direction counts as 0 (no fog). Overflow (looking far down into dense fog)
/// returns +inf, i.e. transmittance 0. Accuracy: <= 1e-5 relative (tests/unit/height_fog_test).
inline float height_fog_optical_depth(const HeightFogCamera &c,
                                      const glm::vec3 &dir,
                                      float distance)
{
    const float t0 = c.fog.start_distance;
    if (c.empty || !(distance > t0) || !(std::fabs(dir.y) <= 1.0f)) {
        return 0.0f;
    }
    const float k = c.fog.falloff * dir.y;
    if (t0 == 0.0f && std::isfinite(distance)) {
        const float x = k * distance;
        // Fast path: one exponential per pixel while the product cannot lose range.
        if (c.density_at_camera > 1e-20f && x > -40.0f) {
            return c.density_at_camera * distance * one_minus_exp_over_x(x);
        }
    }
    float log_a = c.log_density_at_camera;
    if (t0 > 0.0f) {
        log_a -= k * t0;  // density at the start of the segment
    }
    if (std::isinf(distance)) {
        return k > 0.0f && !c.fog.opaque_sky ? fast_exp(log_a) / k : INFINITY;
    }
    const float length = distance - t0;
    const float x = k * length;
    if (x >= 0.0f) {
        return fast_exp(log_a) * length * one_minus_exp_over_x(x);
    }
    // Looking down: (exp(-x) - 1) / -x = exp(-x) * (1 - exp(x)) / -x, so the growing exponential
    // joins the density's exponent instead of overflowing on its own.
    return fast_exp(log_a - x) * length * one_minus_exp_over_x(-x);
}

/// Height fog for one pixel: transmittance exp(-tau) and inscatter (1 - T) * (colour + sun lobe),
/// where the sun lobe is sun_color * 4 pi * HG(dot(dir, sun_direction), sun_g) (so g = 0 adds
/// sun_color). Finite for any input; see height_fog_optical_depth for the NaN/inf contract.
inline FogResult height_fog(const HeightFogCamera &c, const glm::vec3 &dir, float distance)
{
    FogResult r;
    const float tau = height_fog_optical_depth(c, dir, distance);
    if (tau <= 0.0f) {
        return r;
    }
    r.transmittance = fast_exp(-tau);
    glm::vec3 radiance = c.fog.color;
    if (c.has_lobe) {
        // 4 pi * HG(cos) = (1 - g^2) / d^1.5, d = 1 + g^2 - 2 g cos (>= (1 - |g|)^2 > 0).
        const float d = std::max(c.lobe_a - c.lobe_b * glm::dot(dir, c.fog.sun_direction), 1e-6f);
        radiance += c.lobe_scale / (d * std::sqrt(d));
    }
    r.inscatter = (1.0f - r.transmittance) * radiance;
    return r;
}

/// Convenience form: prepares the camera constants on every call (slower per pixel).
inline float height_fog_optical_depth(const HeightFog &fog,
                                      const glm::vec3 &camera,
                                      const glm::vec3 &dir,
                                      float distance)
{
    return height_fog_optical_depth(prepare_height_fog(fog, camera), dir, distance);
}

/// OpenGL linear fog factor (fraction of surface kept): 1 before `start`, 0 after `end`, linear in
/// between. end <= start gives a hard step at start. NaN distance gives 1.
inline float linear_fog_factor(float distance, float start, float end)
{
    if (!(distance > start)) {
        return 1.0f;
    }
    if (!(end > start) || distance >= end) {
        return 0.0f;
    }
    return (end - distance) / (end - start);
}

/// OpenGL exp fog factor exp(-density * distance); distance <= 0 or NaN gives 1.
inline float exp_fog_factor(float distance, float density)
{
    return distance > 0.0f ? std::exp(-std::max(density, 0.0f) * distance) : 1.0f;
}

/// OpenGL exp^2 fog factor exp(-(density * distance)^2); distance <= 0 or NaN gives 1.
inline float exp2_fog_factor(float distance, float density)
{
    if (!(distance > 0.0f)) {
        return 1.0f;
    }
    const float x = std::max(density, 0.0f) * distance;
    return std::exp(-x * x);
}

/// Apply height fog to a whole frame: for each pixel, distance = depth * |ray at depth 1|, then
/// RGB = RGB * T + inscatter (alpha untouched). `color` has >= 3 channels, `depth` 1 channel of
/// camera-space z (scene units, +inf for the sky, which gets the fog of an infinite ray) and both
/// have the same size. Parallel over tiles; results do not depend on the thread count.
void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      Image &color);
/// apply_height_fog reading `source` and writing `color` (same size and channels; they may be the
/// same image): one sweep over memory instead of a copy and a sweep.
void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      const Image &source,
                      Image &color);

}  // namespace posthaste::shading
