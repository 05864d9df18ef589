#pragma once
// src/io/mip_levels.h: the levels of a MIP- or rip-mapped part made again from a touched pass.

#include <utility>
#include <vector>

namespace posthaste::io_detail {

/// The source pixels, with their weights, each pixel of the next level averages along an axis of
/// n pixels (nn: the next level's size along it; along false: the axis is kept).
std::vector<std::vector<std::pair<int, float>>> level_taps(int n,
                                                           bool along,
                                                           bool round_up,
                                                           int &nn);

/// The next level along x, y or both of a W x H x nch image: each pixel the weighted mean of
/// the pixels above it (level_taps). nw, nh: the new size.
std::vector<float> halve(const std::vector<float> &src,
                         int w,
                         int h,
                         int nch,
                         bool along_x,
                         bool along_y,
                         bool round_up,
                         int &nw,
                         int &nh);

}  // namespace posthaste::io_detail
