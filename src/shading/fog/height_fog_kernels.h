#pragma once
// The closed-form height fog of one image row (shading/fog/height_fog.h), written once over
// Highway's lane types (height_fog_kernels.cpp): compiled for each x86 target Highway supports,
// dispatched at run time, and for the portable scalar target that tests compare it with.

#include <cstdint>

namespace posthaste::shading {

/// Per-row constants of the closed form (start distance 0, density at the camera > 1e-20).
struct FogRowParams {
    /// depth_ray(u, v) of this row = origin + u du (world vector to the depth-1 point at NDC u).
    float origin[3] = {}, du[3] = {};
    float inv_w = 1.0f;                    ///< 1 / image width (u of pixel x is (x + 0.5) inv_w)
    float falloff = 0.0f, density = 0.0f;  ///< b, and the density at the camera a
    bool opaque_sky = false;
    bool has_lobe = false;
    float sun[3] = {};                   ///< unit vector towards the sun
    float lobe_a = 1.0f, lobe_b = 0.0f;  ///< HG denominator d = a - b cos_theta
    float fog_rgb[3] = {}, lobe_rgb[3] = {};
};

/// The fog over the n pixels of one row (`channels` >= 3 floats each, RGB first; the others are
/// left alone), whose depths are z[0 .. n): pixel = pixel * T + (1 - T) (fog colour + sun lobe),
/// by the closed form with its series near the horizon, sky (+inf depth) and no-fog (depth <= 0
/// or NaN) lanes. Pixels the closed form cannot take (finite depth looking so far down that it
/// may overflow) are left unchanged and listed in `fallback` (n values at most) for the exact
/// per-pixel path; returns their count.
int fog_row(
    const FogRowParams &p, const float *z, float *row, int channels, int n, std::int32_t *fallback);

}  // namespace posthaste::shading
