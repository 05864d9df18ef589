#pragma once
// Ground-truth-based ambient occlusion (Jimenez et al. 2016, "Practical Realtime Strategies for
// Accurate Indirect Occlusion"): per pixel, a few slices through the view vector; in each, the
// highest horizon on either side within a world radius, found by marching the depth pass, and
// the cosine-weighted visible arc between them integrated in closed form, weighted by the length
// of the normal's projection onto the slice. With the radius as a hard cut-off this estimates
// the same quantity as raster::render_ao_truth: the cosine-weighted fraction of the hemisphere
// with no surface within the radius, as far as the depth pass shows the surfaces (what lies
// behind a visible surface counts as solid: the depth buffer's one-layer approximation).

#include <cstdint>

#include "core/image.h"
#include "shading/camera_rays.h"

namespace posthaste::shading {

struct GtaoParams {
    float radius = 1.0f;           ///< World units: occluders farther from the point do not count.
    int slices = 2;                ///< Slice directions per pixel (rotated per pixel).
    int steps = 4;                 ///< Depth samples on each side of a slice.
    float max_radius_px = 256.0f;  ///< Cap on the search's screen radius.
    /// 1: every pixel; 2: every other pixel in x and y (a quarter of the work), brought back
    /// to full resolution by gtao_upsample.
    int stride = 1;
    std::uint32_t seed = 0;  ///< Shifts the 4x4 pattern of slice rotations and step jitter.
    /// 0: GTAO's horizons (a sample hides every direction below it); > 0: a visibility bitmask
    /// of 32 sectors per slice, each sample hiding only the sectors between itself and itself
    /// pushed this far in camera depth (scene units).
    float thickness = 0.0f;
    /// Maps of one channel over every map_stride-th pixel of the depth pass in x and y
    /// (ceil(size / map_stride); shading/lighting/occluder_thickness.h), where non-null; a
    /// sample reads the map pixel nearest to it.
    /// thickness_map: with thickness > 0, how deep each sample's surface is: it hides by
    /// min(its own, thickness).
    const Image *thickness_map = nullptr;
    /// reach_map: how far back each pixel's surface reaches. Where a sample lies just beyond
    /// the radius, the straight surface between it and the last sample inside is a horizon
    /// candidate (see gtao.cpp); with a reach map, only where the nearer of the two reaches back
    /// to the farther one's depth: a jump in depth with empty space behind the nearer surface
    /// is a silhouette, not a surface.
    const Image *reach_map = nullptr;
    int map_stride = 1;  ///< 1, 2, 4 or 8
};

/// AO (1 channel, 0 occluded .. 1 open, the estimate itself: a few slices can scatter a little
/// outside [0, 1], clamped by the caller after any denoising; ceil(size / stride)) of a depth
/// pass (camera z, +inf sky)
/// with world-space normals of the same size, seen through `rays` (NDC [0,1]^2 spanning these
/// images). Sky and non-finite depth give 1; a zero or non-finite normal uses the view vector. Rows
/// in parallel, same bits for any thread count.
Image gtao(const Image &depth, const Image &normal, const CameraRays &rays, const GtaoParams &p);

/// The depth of gtao's output pixels (full-resolution pixel stride (x, y)), NaN where there is
/// no surface: the weights of the denoise and the upsample are then 0. Made once, used by both.
Image gtao_depth(const Image &depth, int stride);

/// A depth-aware blur of `ao` (5x5 box, neighbours weighted by max(0, 1 - |dz| / (0.1 z)) of the
/// depth difference, `ao_depth` from gtao_depth): the 4x4 pattern of slice rotations averaged,
/// depth edges kept.
Image gtao_denoise(const Image &ao, const Image &ao_depth);

/// The reduced AO of gtao with `stride` > 1 brought to the depth pass's resolution: the four
/// nearest computed pixels, bilinear weights times the depth similarity of the denoise; the
/// closest in depth where none is on the same surface.
Image gtao_upsample(const Image &ao, const Image &ao_depth, const Image &depth, int stride);

}  // namespace posthaste::shading
