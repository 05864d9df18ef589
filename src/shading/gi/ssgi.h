#pragma once
// Screen-space diffuse global illumination: one bounce of light from the surfaces the depth pass
// shows. Per pixel, a few slices through the view vector as GTAO's (Jimenez et al. 2016); along
// each side of a slice the depth pass is marched outward, and every sample that rises above the
// horizon found so far lights the arc between the old horizon and itself with its own lit colour
// (a surface facing away lights nothing but still hides what lies behind it). Each arc counts by
// its cosine-weighted measure in closed form, so the result estimates the cosine-weighted mean
// radiance arriving from surfaces: irradiance / pi, what render's truth "gi" gathers by rays.
// What the frame does not show (off screen, behind a visible surface) adds nothing; neither does
// the sky, whose light the beauty already holds.

#include <cstdint>

#include "core/image.h"
#include "shading/camera_rays.h"

namespace posthaste::shading {

struct SsgiParams {
    float radius = 4.0f;           ///< World units: surfaces farther from the point do not count.
    int slices = 1;                ///< Slice directions per pixel (rotated per pixel, 4x4 pattern).
    int steps = 8;                 ///< Depth samples on each side of a slice.
    float max_radius_px = 512.0f;  ///< Cap on the search's screen radius (full-resolution px).
    /// 1, 2 or 4: every stride-th pixel in x and y; bring the result back with
    /// gtao_denoise and gtao_upsample (shading/ao/gtao.h), as the ao node does.
    int stride = 4;
    std::uint32_t seed = 0;  ///< Shifts the pattern of slice rotations and step jitter.
    /// Re-shading of the lit samples for the receiver's view, as ssr re-shades its hits: the
    /// sun's irradiance (colour times illuminance). A sample's colour is its radiance toward the
    /// camera; toward the receiver its sun highlight and its sky reflection differ (a polished
    /// floor mirrors the bright horizon to what stands on it, and the camera sees it darker).
    /// Zero: samples keep the colour the camera saw.
    glm::vec3 sun_irradiance{0.0f};
    glm::vec3 sun_direction{0.4f, 0.75f, 0.3f};  ///< Unit; chooses the sky.
    float sky_scale = 1.0f;                      ///< The renderer's sky-light scale.
    /// With the re-shading: the sun's light that glossy planes of the frame (the largest two
    /// families of parallel glossy surfaces) reflect, traced per computed pixel in the sun's
    /// mirror direction about each plane instead of left to the slices, whose few samples
    /// rarely meet a narrow highlight. The slices then take those planes' sun response
    /// without its specular lobe, so no light is counted twice.
    bool reflected_sun = true;
};

/// The surfaces' material for the re-shading (SsgiParams::sun_irradiance non-zero), the depth
/// pass's size: albedo (RGB, finite), material (roughness, metallic; a non-finite value reads
/// as 1) and, optionally, the sun's visibility (the shadow pass, a non-finite value read as 0;
/// without one, 1 wherever a surface faces the sun). Only the computed pixels are read.
struct SsgiSurfaces {
    const Image *albedo = nullptr;
    const Image *material = nullptr;
    const Image *shadow = nullptr;
};

/// What the screen does not show, from a latitude-longitude probe taken near the camera
/// (render's `projection: latlong`, shading/ssr/environment.h's layout): in a direction the
/// march leaves open, the probe's radiance where its distance is finite (a surface), nothing
/// where it sees the sky (the beauty holds the sky's light already). No parallax: the probe is
/// taken as seen from every pixel.
struct SsgiEnvironment {
    const Image *radiance = nullptr;  ///< RGB(A), finite.
    const Image *distance = nullptr;  ///< One channel, +inf (or NaN) for the sky.
};

/// The light arriving at each computed pixel (RGB, ceil(size / stride)): the cosine-weighted mean
/// radiance from the surfaces a depth pass (camera z, +inf sky) shows, with world-space
/// `normal`s and lit `radiance` (RGB or RGBA scene-linear, the beauty without indirect light) of
/// the same size, seen through `rays` (NDC [0,1]^2 spanning these images). A receiver's diffuse
/// bounce is its diffuse albedo times this. Sky and non-finite depth give 0; a normal's
/// non-finite components read as 0, and a zero normal faces the camera; non-finite radiance
/// reads as 0. Rows in parallel, same bits for any thread count.
Image ssgi(const Image &depth,
           const Image &normal,
           const Image &radiance,
           const CameraRays &rays,
           const SsgiParams &p,
           const SsgiEnvironment *environment = nullptr,
           const SsgiSurfaces *surfaces = nullptr);

/// ssgi's reduced result brought to the depth pass's resolution (RGB): with `denoise`, first a
/// 5x5 blur of the rotation pattern at the reduced resolution; then each pixel blends its four
/// nearest computed pixels, bilinear weights. Every weight is times a depth tent (the ao
/// node's, shading/ao/gtao.h) and max(0, n.n')^8 of the normals, so light does not leak
/// across depth edges or onto a face at an angle (a voxel's top from its side); where no tap
/// is on the pixel's surface, the closest in depth. 0 on the sky.
///
/// With `apply`, the result is the light a diffuse bounce adds instead of the light arriving:
/// times intensity, the albedo (its channel 0 for a one-channel albedo) and, with a material
/// pass, 1 - metallic (its channel 1, clamped to [0, 1]; non-finite reads as 0). Negative light
/// (none is made) would read as 0. Non-finite depth reads as the sky, a normal's or the
/// albedo's non-finite components as 0 (what a scan replacing them gives, bit for bit).
struct SsgiApply {
    const Image *albedo = nullptr;    ///< The depth pass's size.
    const Image *material = nullptr;  ///< Optional: roughness, metallic, ...
    float intensity = 1.0f;
    /// Optional: `color` plus the result (its first three channels; the others as they are)
    /// into `sum` (color's size and channels), row by row while the result's row is in cache.
    const Image *color = nullptr;
    Image *sum = nullptr;
};

/// One row of SsgiApply's sum: dst = src + the light's RGB, nc channels a pixel.
void ssgi_add_row(const float *src, const float *light, int w, int nc, float *dst);
Image ssgi_resolve(const Image &light,
                   const Image &depth,
                   const Image &normal,
                   int stride,
                   bool denoise,
                   const SsgiApply *apply = nullptr);

}  // namespace posthaste::shading
