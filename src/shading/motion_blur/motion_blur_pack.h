#pragma once
// The motion blur's pack, shared by its driver and scalar rows (motion_blur_pack.cpp) and its
// vector rows (motion_blur_pack_kernels.cpp). Internal to src/shading/motion_blur*.cpp.

#include "shading/motion_blur/motion_blur_records.h"

namespace posthaste::shading::motion_blur_detail {

/// Writes the records and velocities of a frame, row by row.
struct Packer {
    const Image &color, &motion, &depth;
    Packed &out;
    int w, nc;
    float scale, max_r;

    /// The record of pixel (x, y); its velocity into (vx_out, vy_out) and the velocity image
    /// (when there is one).
    void pixel(int y, int x, float &vx_out, float &vy_out) const;

    /// Pixels [x0, x1) of row y; returns whether their alpha is exactly 1 (RGBA only).
    /// With vx, vy: the velocities into them (x - x0 indexed).
    bool pixels(int y, int x0, int x1, float *vx = nullptr, float *vy = nullptr) const;
};

/// Lanes of the vector rows on the CPU's target: the pack folds the tile reductions itself
/// where the tile is a multiple of it.
int pack_lanes();

/// Row y through the vector rows; returns whether its alpha is exactly 1 (RGBA only).
bool pack_row_vector(const Packer &p, int y);

/// The rows of tile band ty through the vector rows, folding each row into the band's tile max
/// and bounds (out.tiles; out.bounds when it is allocated) while it is in cache. `tile` is a
/// multiple of pack_lanes().
void pack_band_vector(const Packer &p, int ty, int tile, Packed &out);

}  // namespace posthaste::shading::motion_blur_detail
