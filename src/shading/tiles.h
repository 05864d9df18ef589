#pragma once
// Tile reductions of a per-pixel 2D vector field, for gather filters whose reach follows the
// field (motion blur: McGuire et al. 2012 "A reconstruction filter for plausible motion blur",
// TileMax / NeighborMax; defocus can reuse them with a circle-of-confusion field). A tile image
// has one pixel per tile (ceil(W / tile) x ceil(H / tile)), 2 channels: the longest vector.

#include <cstdint>
#include <functional>
#include <vector>

#include "core/image.h"

namespace posthaste::shading {

/// The longest vector of each tile x tile block of `field` (channels `first` and `first` + 1;
/// other channels are ignored). Vectors that are not finite count as zero. Ties keep the first
/// in scan order, so the result does not depend on the thread count.
Image tile_max(const Image &field, int tile, int first = 0);

/// For each tile, the longest vector among the tiles within `radius` tiles (a (2 radius + 1)^2
/// window, clamped at the borders): everything that can reach into the tile when no vector is
/// longer than radius * tile pixels. Ties keep the first in scan order.
Image neighbour_max(const Image &tiles, int radius);

/// neighbour_max counting only the tiles whose own longest vector can reach: a tile at Chebyshev
/// distance d (in tiles, d <= radius) counts when d <= ceil(|v| / tile) + margin. A vector of
/// length |v| crosses at most ceil(|v| / tile) tile borders, so this is still everything that
/// can reach into the tile (margin: tiles more, e.g. for a jittered lookup), without the longer
/// vectors further away that cannot. Ties keep the first in scan order.
Image neighbour_max_reach(const Image &tiles, int tile, int margin, int radius);

/// neighbour_bounds over the same tiles as neighbour_max_reach (`tiles`: their tile max).
Image neighbour_bounds_reach(
    const Image &bounds, const Image &tiles, int tile, int margin, int radius);

/// tile_max and tile_bounds (either may be null) in one pass over `field`.
void tile_max_bounds(const Image &field, int tile, int first, Image *max, Image *bounds);

/// neighbour_max_reach of `tiles` into `nmax` and neighbour_bounds_reach of `bounds` into
/// `nbounds` (either may be null; `bounds` only with `nbounds`) in one pass over the windows.
void neighbour_reach(const Image &tiles,
                     const Image *bounds,
                     int tile,
                     int margin,
                     int radius,
                     Image *nmax,
                     Image *nbounds);

/// The bounding box of each tile's vectors (channels `first`, `first` + 1 of `field`): 4
/// channels, min x, min y, max x, max y. Non-finite vectors count as zero.
Image tile_bounds(const Image &field, int tile, int first = 0);

/// For each tile, the union of the boxes of the tiles within `radius` tiles: how far apart the
/// vectors that can reach into the tile are (a tile whose box is small moves coherently).
Image neighbour_bounds(const Image &bounds, int radius);

/// Per tile of a width x height frame: whether any of the four planes (row-major, width per
/// row) holds a non-zero value in it (NaN counts). tiles_x x tiles_y, row-major.
std::vector<std::uint8_t> occupied_tiles(const float *const planes[4],
                                         int width,
                                         int height,
                                         int tile);

/// Per tile: whether an occupied tile lies within `reach(tile index)` tiles of it (Chebyshev
/// distance): where a gather of that reach can read anything but zeros.
std::vector<std::uint8_t> tiles_in_reach(const std::vector<std::uint8_t> &occupied,
                                         int tiles_x,
                                         int tiles_y,
                                         const std::function<int(std::size_t)> &reach);

}  // namespace posthaste::shading
