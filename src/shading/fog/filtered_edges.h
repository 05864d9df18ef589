#pragma once
// Fog over a colour pass filtered at depth edges.
//
// A production renderer filters its colour: an edge pixel's colour is the weighted mean of
// samples of the surfaces on either side, while its depth is one of them (Cycles writes the
// depth of one sample, unfiltered). The true fogged pixel is the same mean of each sample's own
// composite, T_i L_i + I_i; fogging the mean by the pixel's one depth gives T_p c_p + I_p, wrong
// by sum_i w_i (T_i - T_p) L_i + (I_i - I_p). The correction estimates that sum with the
// neighbours' centres standing in for the samples: each neighbour q's composite (T_q, I_q from
// its own depth) applied to its colour c_q, a Gaussian weight w_q over the 3x3 neighbourhood,
//   out_p = T_p c_p + I_p + sum_q w_q ((T_q - T_p) c_q + (I_q - I_p)) / sum_q w_q.
// Where the neighbours' depths give the pixel's own T and I the sum is exactly 0: only edges
// change, and nothing is blurred. Pixels whose 3x3 depths lie on one plane (inverse depths
// affine within 1 % along each line through the pixel; a line with an end outside the frame
// or without depth is not looked at) are left as they are: there the sum is
// of the second order (the rays' lengths differ, not their surfaces), and the cost stays with
// the edges. The result is clamped to [0, max T * max c + max I]
// over the neighbourhood (a high-contrast edge could otherwise overshoot: radiance is never
// negative).

#include "core/image.h"

namespace posthaste::shading {

/// Adds the correction above to `out` (the fog applied per pixel, T c + I, RGB in channels
/// 0-2; further channels are left alone). `transmittance` and `inscatter` hold each pixel's
/// T and I (the model applied to colours 1 and 0), `color` the unfogged colour, `depth` the
/// depth pass: depths NaN or at most 0 (pixels the model leaves alone: the node reads NaN and
/// -inf as 0) neither change nor count as neighbours. `sigma` is the Gaussian's standard deviation
/// in pixels (> 0). Every image has the size of `out`; the result is the same for any thread count.
void correct_filtered_edges(const Image &color,
                            const Image &transmittance,
                            const Image &inscatter,
                            const Image &depth,
                            float sigma,
                            Image &out);

}  // namespace posthaste::shading
