#pragma once
// GTAO's per-row kernel (shading/ao/gtao.h), written once over Highway's lane types
// (gtao_kernels.cpp): one pixel a lane, its depth samples gathered. Compiled for each x86 target
// Highway supports and dispatched at run time.

#include <cstdint>

namespace posthaste::shading {

/// Row buffers of the kernel hold n values rounded up to whole vectors: n + kGtaoPad.
inline constexpr int kGtaoPad = 16;

struct GtaoKernelParams {
    const float *depth = nullptr;  ///< full-resolution depth, w x h, camera z (+inf sky)
    int w = 0, h = 0;
    /// depth_ray(u, v) = origin + u du + v dv (world vector to the depth-1 point of NDC u, v);
    /// cam: the camera position.
    float cam[3] = {}, origin[3] = {}, du[3] = {}, dv[3] = {};
    float radius = 1.0f, max_radius_px = 256.0f;
    float px_world_1 = 1.0f;  ///< world units per pixel at depth 1
    int slices = 2, steps = 4, stride = 1;
    /// 0: a sample hides everything below its horizon (GTAO); > 0: only the sectors between
    /// it and it pushed this far in camera depth (a visibility bitmask, Therrien et al. 2023).
    float thickness = 0.0f;
    /// Maps over every (1 << map_shift)-th pixel in x and y (map_w x map_h), a sample reading
    /// the cell its pixel rounds to. Where non-null: thickness_map, each pixel's own surface
    /// depth (a sample hides the sectors of min(its own, thickness)); reach_map, how far back
    /// each pixel's surface reaches (a crossing of the radius between two samples counts only
    /// where the nearer one's reaches back to the farther one's depth).
    const float *thickness_map = nullptr, *reach_map = nullptr;
    int map_shift = 0, map_w = 0, map_h = 0;
    const float *dir_x = nullptr, *dir_y = nullptr;  ///< slice directions [16 * slices]
};

/// The AO estimate (gtao.h) of n pixels of output row oy: output pixel i is the full-resolution
/// pixel (stride i, stride oy). z: its depth; nx, ny, nz: its normal (a zero or non-finite one
/// faces the camera); rot: its rotation index (0..15) times slices, into dir_x/dir_y; jitter: its
/// step offset
/// in [0, 1). All hold n + kGtaoPad values (the padding's z must be +inf); out n + kGtaoPad.
void gtao_row(const GtaoKernelParams &p,
              int oy,
              const float *z,
              const float *nx,
              const float *ny,
              const float *nz,
              const std::int32_t *rot,
              const float *jitter,
              int n,
              float *out);

/// One output row of gtao_upsample: the two reduced rows either side (depth z0, z1 from
/// gtao_depth, AO a0, a1), the row's full-resolution depth z, per column the left and right
/// reduced pixels (i0, i1) and the right one's bilinear weight fx, and the lower row's weight fy.
struct GtaoUpsampleRow {
    const float *z0, *z1, *a0, *a1, *z;
    const std::int32_t *i0, *i1;
    const float *fx;
    float fy;
};

/// The w upsampled AO values of a row into out (gtao_upsample_kernels.cpp).
void gtao_upsample_row(const GtaoUpsampleRow &r, int w, float *out);

}  // namespace posthaste::shading
