#pragma once
// Depth of field, part 1: the thin-lens circle of confusion per pixel and the tile max/min CoC
// reduction with neighbourhood dilation that bounds the gather radius (Jimenez 2014, "Next
// Generation Post Processing in Call of Duty: Advanced Warfare", tile max/min CoC).
//
// Signed CoC: negative in front of the focus plane (near field), positive behind it (far field).
// Stored as a RADIUS in pixels (half the diameter), clamped to max_coc / 2.

#include <cstdint>
#include <vector>

#include "core/image.h"

namespace posthaste::shading {

/// Thin-lens parameters, in the units of the EXR header.
struct DofLens {
    float fstop = 5.6f;       ///< f-number N; aperture diameter A = f / N.
    float focus_m = 10.0f;    ///< Focus distance s, metres.
    float focal_mm = 35.0f;   ///< Focal length f, mm.
    float sensor_mm = 36.0f;  ///< Sensor width, mm (maps to the image width).
};

/// Signed CoC diameter in pixels of a point at camera-space depth z (metres) on an image
/// `width_px` wide: c = A f (z - s) / (z (s - f)) * width_px / sensor_width, A = f / N.
/// z = +inf gives the far limit A f / (s - f). z <= 0 or NaN are the caller's to handle; a focus
/// distance at or inside the focal length is moved to 1.001 f (everything then far out of focus).
float coc_diameter_px(const DofLens &lens, float z_m, int width_px);

/// The per-pixel signed CoC radius image and its tile reduction.
struct CocField {
    int width = 0, height = 0;
    std::vector<float> radius;  ///< Signed radius, px, clamped to +-max_radius; row-major.
    int tile = 16;              ///< Tile side, px.
    int tiles_x = 0, tiles_y = 0;
    std::vector<float> tile_max;  ///< Max |radius| in the tile.
    std::vector<float> tile_min;  ///< Min |radius| in the tile.
    std::vector<float> gather;    ///< Dilated: the largest |radius| of any tile that can reach it.
    std::vector<float>
        near_gather;          ///< Dilated like gather, over near-field (negative) radii only.
    float max_radius = 0.0f;  ///< Largest |radius| in the image.
};

/// CoC radii of a depth image (1st channel, metres). NaN, zero or negative depth (not a depth)
/// counts as in focus; +inf as the far limit. max_radius_px >= 0.
/// Parallel over tiles; the result does not depend on the thread count. Leaves the tile vectors
/// empty: call reduce_tiles next.
CocField compute_coc(const Image &depth, const DofLens &lens, float max_radius_px);

/// Fill tile_max / tile_min and the dilated gather radii: gather(t) = max over tiles t' whose
/// max radius reaches t (|radius| >= the distance from t' to the nearest pixel of t); near_gather
/// the same over the near field's radii (-radius where radius < 0).
void reduce_tiles(CocField &field);

}  // namespace posthaste::shading
