#pragma once
// The lens node's resampling of RGBA rows, written once over Highway (lens_kernels.cpp; one
// pixel's four channels per 128-bit vector) and dispatched to the CPU's best target at run time.

#include <cstdint>

namespace posthaste::filter {

/// For x < n: out[4x..4x+3] = the RGBA image `img` (w x h) at (sx[x], sy[x]) (pixel centres at
/// +0.5), bilinear (taps 2) or Catmull-Rom (taps 4), where the footprint lies inside the image;
/// elsewhere (or at a NaN position) edge[x] is set to 1 and out is left for the caller.
void lens_resample_rgba_row(const float *img,
                            int w,
                            int h,
                            const float *sx,
                            const float *sy,
                            int n,
                            int taps,
                            float *out,
                            std::uint8_t *edge);

}  // namespace posthaste::filter
