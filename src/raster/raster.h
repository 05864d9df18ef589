#pragma once
// The tile rasterizer core: triangles in homogeneous "raster space" are clipped (near plane and
// a guard band), snapped to 8-bit sub-pixel fixed point, binned into 64x64 tiles and walked per
// tile in parallel (one thread owns a tile; llvmpipe / MOC). Edges are exact integer edge
// functions with the top-left fill rule, so triangles sharing an edge cover each pixel centre
// exactly once. Depth test on a key interpolated linearly in screen space (greater is nearer).
// Output: per pixel the key and the id of the nearest triangle. Bins keep submission order, so
// the result is the same bits for any thread count.
//
// Raster space: a vertex (X, Y, Q, W) lies at pixel (X / W, Y / W) (pixel centres at +0.5) with
// depth key Q / W. Perspective cameras use W = camera z and Q = 1 (key = 1 / z); orthographic
// ones W = 1 and Q = distance toward the viewer.

#include <cstdint>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <vector>

#include "core/image.h"

namespace posthaste::raster {

inline constexpr int kSubpixelBits = 8;
inline constexpr int kRasterTile = 64;
/// Id written where no triangle covers the pixel.
inline constexpr std::uint32_t kNoTriangle = 0xffffffffu;

/// Triangles of one object: vertices already in raster space; the triangle i gets id
/// id_base + i.
struct DrawBatch {
    const glm::vec4 *vertices = nullptr;
    const glm::uvec3 *triangles = nullptr;
    std::size_t triangle_count = 0;
    std::uint32_t id_base = 0;
};

struct RasterParams {
    int width = 0, height = 0;
    bool cull_backfaces = true;  ///< Cull triangles that are clockwise on screen (y down).
    float near_w = 1e-3f;        ///< Clip where W < near_w.
};

/// Target buffers, width x height, row-major. `ids` may be null (depth only).
struct RasterTarget {
    float *keys = nullptr;
    std::uint32_t *ids = nullptr;
};

struct RasterCounts {
    std::size_t submitted = 0;  ///< Triangles handed in.
    std::size_t binned = 0;     ///< Triangles after culling and clipping (one per piece).
};

/// Clear keys to -inf and ids to kNoTriangle, then rasterize every batch in order. The id of a
/// pixel is the triangle with the greatest key (the first one submitted wins ties).
RasterCounts rasterize(const std::vector<DrawBatch> &batches,
                       const RasterParams &params,
                       RasterTarget target);

/// Rasterize into buffers already holding keys and ids (no clear): for layering extra geometry.
RasterCounts rasterize_over(const std::vector<DrawBatch> &batches,
                            const RasterParams &params,
                            RasterTarget target);

}  // namespace posthaste::raster
