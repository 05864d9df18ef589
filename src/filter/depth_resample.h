#pragma once
// A depth pass through a reconstruction filter (transform, reformat or lens with "depth" or
// "specular_depth" among their `filtered` passes). Two things a filter does to colour are wrong
// for depth: a tap on the sky (+inf) makes the sum infinite or NaN (inf * 0, inf - inf under a
// negative lobe), and the negative lobes of Catmull-Rom or Lanczos overshoot a depth edge, down
// to depths nearer than anything in the scene or below zero. So a depth is filtered split in two
// (sky_split): its values with the sky as 0, and a sky indicator, 1 on the sky. Then each output
// pixel is guarded: where the indicator's sum is not 0 (a tap of non-zero weight on the sky, or
// outside the input) or the nearest input pixel is sky, it takes the nearest input pixel (the sky
// is the sky exactly where nearest sampling puts it, and its edge stays sharp); elsewhere the
// filtered depth clamped to the range of the finite depths around the nearest input pixel.

#include <cstdint>

#include "core/image.h"

namespace posthaste::filter {

/// The image a filter reads for `depth` (nc channels): 2 nc channels, depth with +inf as 0, then
/// per channel 1 where it is +inf and 0 elsewhere.
Image sky_split(const Image &depth);

/// Per channel c, the smallest and largest finite value of `depth` within the (2 radius + 1)^2
/// pixels around each pixel: 2 nc channels (lo_0, hi_0, lo_1, hi_1, ...); (+inf, -inf) where
/// none is finite. Exact (min and max only), in time independent of the radius.
Image depth_range(const Image &depth, int radius);

/// One row of n output pixels of a filtered depth, made safe (see above): `filtered` holds the
/// filter's result on sky_split(depth), 2 nc floats a pixel; nearest[i] is the index of output
/// pixel i's nearest input pixel in `depth` (y * width + x; -1 outside the input: the sky), as
/// the node's nearest sampling picks it; `range` is depth_range(depth, r) for an r that covers
/// the filter's support. Writes nc floats a pixel into `row`.
void guard_depth_row(const Image &depth,
                     const Image &range,
                     const std::int32_t *nearest,
                     int n,
                     const float *filtered,
                     float *row);

}  // namespace posthaste::filter
