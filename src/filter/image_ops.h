#pragma once
// The everyday image operations behind the reformat, transform, crop, blur and sharpen nodes:
// resizing and warping on OpenImageIO's ImageBufAlgo (resize, warp) with the pass images wrapped
// in place (no copy in or out), the Gaussian blur on the project's Highway FIR kernels. Each call
// splits its output into row bands run by the project's one parallel primitive, with OpenImageIO
// told to use one thread per call: --threads bounds the work, and every output pixel is computed
// the same way whatever the thread count.
//
// Coordinates are absolute file coordinates (pixel edges at integers, centres at +0.5), as the
// windows of a Frame.

#include <cstdint>
#include <glm/mat3x3.hpp>
#include <string>

#include "core/image.h"
#include "filter/fir_kernels.h"

namespace posthaste::filter {

/// An affine map of continuous file coordinates: p' = m * (x, y, 1) (glm, column vectors).
using Affine = glm::dmat3;

/// The resize map from a display window to another: the affine map taking `from` onto `to`.
Affine window_map(const Rect &from, const Rect &to);

/// The smallest integer rectangle holding the image of `r` under `m` (rounded outward; corners
/// that land within 1e-6 of an integer are snapped first, so exact scales keep exact windows).
Rect transformed_bounds(const Affine &m, const Rect &r);

/// True when `name` is a reconstruction filter OpenImageIO knows (lanczos3, catmull-rom, ...).
bool is_filter_name(const std::string &name);

/// True when OpenImageIO's filter `name` is separable (false for radial ones and unknown names).
bool is_separable_filter(const std::string &name);

/// The default width (in pixels) of OpenImageIO's filter `name`; 0 for a name it does not know.
double filter_width(const std::string &name);

/// `src` (covering `src_window`, displayed in `src_display`) resized so that `src_display` maps
/// onto `dst_display`, over the output window `dst_window`: ImageBufAlgo::resize with the named
/// filter (its support widened for minification). Outside the source the edge pixels extend.
Image resize_filtered(const Image &src,
                      const Rect &src_window,
                      const Rect &src_display,
                      const Rect &dst_window,
                      const Rect &dst_display,
                      const std::string &filter);

/// `src` (covering `src_window`) warped by `to_output` (input -> output coordinates) over
/// `dst_window`: ImageBufAlgo::warp with the named filter. Outside the source reads 0, or with
/// `extend_edges` the nearest edge pixel (a depth pass: 0 would pull its edges towards the camera).
Image warp_filtered(const Image &src,
                    const Rect &src_window,
                    const Affine &to_output,
                    const Rect &dst_window,
                    const std::string &filter,
                    bool extend_edges = false);

/// For row y of `dst_window`: the input pixel holding each output pixel's centre mapped by
/// `to_input` (output -> input coordinates), as an index into an image covering `src_window`
/// (y * width + x), or -1 outside it. sample_nearest copies these pixels.
void nearest_sources(const Affine &to_input,
                     const Rect &src_window,
                     const Rect &dst_window,
                     int y,
                     std::int32_t *out);

/// Nearest-neighbour resampling through `to_input` (output -> input coordinates): each output
/// pixel centre maps to a point, and the input pixel holding it is copied, values unchanged (ids,
/// depth, normals). Outside `src_window` every channel is `outside`.
Image sample_nearest(const Image &src,
                     const Rect &src_window,
                     const Affine &to_input,
                     const Rect &dst_window,
                     float outside);

/// Separable Gaussian blur (sigma in pixels per axis) by the FIR kernels of fir_kernels.h (one
/// source over Highway): ImageBufAlgo::convolve with the same kernels gave the same values 15-25
/// times slower at 1080p. The image continues beyond its edges as its edge pixels (no darkening
/// there). Only channels [c0, c1) are blurred, the others are copied.
Image gaussian_blur(const Image &src, double sigma_x, double sigma_y, int c0 = 0, int c1 = -1);

}  // namespace posthaste::filter
