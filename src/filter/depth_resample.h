#pragma once
// A depth pass through a reconstruction filter (transform, reformat or lens with "depth" among
// their `filtered` passes). Two things a filter does to colour are wrong for depth: a tap on the
// sky (+inf) makes the sum infinite or NaN (inf * 0, inf - inf under a negative lobe), and the
// negative lobes of Catmull-Rom or Lanczos overshoot a depth edge, down to depths nearer than
// anything in the scene or below zero. So a depth is filtered with its sky marked as NaN (every
// sum that touched the sky, or the outside, comes out NaN), then guarded pixel by pixel: where the
// sum is NaN or the nearest input pixel is sky, the nearest input pixel (the sky is the sky
// exactly where the nearest sample is, and its edge stays sharp); elsewhere the sum clamped to the
// range of the finite depths around the nearest input pixel.

#include "core/image.h"

namespace posthaste::filter {

/// `depth` (one or more channels) with +inf as NaN: the input a filter reads.
Image sky_as_nan(const Image &depth);

/// The smallest and largest finite value of channel 0 of `depth` within the (2 radius + 1)^2
/// pixels around each pixel, as a two-channel image (lo, hi); (+inf, -inf) where none is finite.
/// Parallel; exact (min and max only).
Image depth_range(const Image &depth, int radius);

/// One row of a filtered depth made safe (see the file's comment): `row` (n pixels, `nc`
/// channels each) holds the filter's result from sky_as_nan(depth); (xs[i], ys[i]) is where output
/// pixel i reads the input, in `depth`'s pixel coordinates (centres at +0.5). A point outside the
/// input gives +inf, as the nearest sample does; `range` is depth_range(depth, r) for an r that
/// covers the filter's support (channel 0 is clamped to it; any further channel only takes the
/// nearest pixel where its sum is NaN).
void guard_depth_row(
    const Image &depth, const Image &range, const float *xs, const float *ys, int n, float *row);

}  // namespace posthaste::filter
