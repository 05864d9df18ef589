#pragma once
// Screen-space ray-traced ambient occlusion, the slow reference beside GTAO (gtao.h): per pixel,
// stratified cosine-weighted rays from the depth pass's surface point, each marched through the
// depth pass as a height field of finite thickness. A ray point that lies behind the visible
// surface at its screen position, by less than `thickness`, is inside an occluder; a ray that
// leaves the screen or the radius is open. It estimates the quantity raster::render_ao_truth
// computes, as far as one depth layer of given thickness shows the scene: what any method that
// reads only the depth pass can know.

#include <cstdint>

#include "core/image.h"
#include "shading/camera_rays.h"

namespace posthaste::shading {

struct AoTraceParams {
    float radius = 1.0f;  ///< World units: occluders farther from the point do not count.
    int rays = 64;        ///< Rays per pixel, rounded to a square (a grid of strata).
    int steps = 24;       ///< Depth samples along each ray (denser near its start).
    /// Camera-depth units a visible surface is taken to extend behind itself.
    float thickness = 1.0f;
    /// Where non-null, each pixel's own thickness (shading/lighting/occluder_thickness.h, the
    /// depth pass's size), used where it is less than `thickness`.
    const Image *occluder = nullptr;
    int stride = 1;  ///< As GtaoParams::stride: 2 traces every other pixel in x and y.
    std::uint32_t seed = 0;
};

/// AO (1 channel, 0 occluded .. 1 open; ceil(size / stride)) of a depth pass (camera z, +inf sky)
/// with world normals of the same size, seen through `rays` (NDC [0,1]^2 spanning the images).
/// Sky and non-finite depth give 1; a zero or non-finite normal faces the camera. The surface
/// between pixel centres is each pixel's plane (its depth and normal), so a flat face does not
/// occlude itself. Per-pixel hashed jitter: the same bits for any thread count.
Image ao_trace(const Image &depth,
               const Image &normal,
               const CameraRays &rays,
               const AoTraceParams &p);

}  // namespace posthaste::shading
