#pragma once
// Lens distortion (Brown-Conrady: radial k1, k2, k3 and tangential p1, p2, in OpenCV's form with
// y pointing down), its exact inverse by Newton's method, the map from output pixels to source
// positions that a lens node resamples with, and the resampling filters.
//
// Normalised coordinates: (X - cx, Y - cy) / unit, with (cx, cy) the optical centre and `unit`
// half the display width (or the focal length in pixels, as OpenCV's calibrations use).
//   distort(u) = u (1 + k1 r^2 + k2 r^4 + k3 r^6) + (2 p1 x y + p2 (r^2 + 2 x^2),
//                                                   p1 (r^2 + 2 y^2) + 2 p2 x y),  r^2 = |u|^2.

#include <cstdint>
#include <glm/mat2x2.hpp>
#include <glm/vec2.hpp>
#include <optional>
#include <string>
#include <vector>

#include "core/image.h"

namespace posthaste::filter {

struct Distortion {
    double k1 = 0, k2 = 0, k3 = 0, p1 = 0, p2 = 0;

    bool identity() const { return k1 == 0 && k2 == 0 && k3 == 0 && p1 == 0 && p2 == 0; }
    /// Undistorted -> distorted, normalised coordinates.
    glm::dvec2 distort(glm::dvec2 u) const;
    /// d distort / d u.
    glm::dmat2 jacobian(glm::dvec2 u) const;
    /// The u with distort(u) = d, by Newton's method from u = d; nullopt when it does not
    /// converge to 1e-9 (normalised) in 50 steps or meets a singular Jacobian.
    std::optional<glm::dvec2> undistort(glm::dvec2 d) const;
};

/// Where the lens puts things, in file pixel coordinates.
struct LensGeometry {
    Distortion distortion;
    glm::dvec2 centre{0.0};  ///< optical centre, file coordinates (pixel edges at integers)
    double unit = 1.0;       ///< pixels per normalised unit
    bool undistort = false;  ///< false: the output is the input as the lens would image it
};

/// For each output pixel, where it reads the input: continuous coordinates relative to the input
/// data window (pixel centres at +0.5), NaN where no source exists.
struct LensMap {
    Rect window;  ///< the output data window (file coordinates)
    std::vector<float> sx, sy;
    /// The nearest input pixel (y * width + x of the input data window), -1 outside it.
    std::vector<std::int32_t> nearest;
};

/// The output data window (the bounding box of the input data window moved by the lens, at most
/// `limit`), and the map. Throws an Error naming `who` and the pixel where the distortion folds
/// over (its Jacobian's determinant <= 0) within the region it is used on.
LensMap build_lens_map(const LensGeometry &g,
                       const Rect &input_window,
                       const Rect &limit,
                       const std::string &who);

enum class Resample { Nearest, Bilinear, Bicubic };

/// `img`'s channel c at continuous (x, y) (pixel centres at +0.5); outside the image the image
/// is `outside` (Catmull-Rom for bicubic).
float sample(const Image &img, int c, float x, float y, Resample filter, float outside);

/// Channels [c0, c1) of `img` at (x, y) into out[0..c1-c0), as `sample` gives them, with the
/// filter's weights computed once and an unchecked path where the footprint lies inside.
void sample_channels(
    const Image &img, int c0, int c1, float x, float y, Resample filter, float outside, float *out);

/// n pixels of `img` at (xs[i], ys[i]) into out (img.channels() floats each), as sample_channels
/// gives them: RGBA images under bilinear or bicubic through the Highway kernel
/// (lens_kernels.h), the pixels whose footprint crosses the image's edge, other layouts and
/// nearest one by one. The lens node and the transform node resample rows with it.
void resample_row(const Image &img,
                  const float *xs,
                  const float *ys,
                  int n,
                  Resample filter,
                  float outside,
                  float *out);

}  // namespace posthaste::filter
