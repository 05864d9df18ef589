#pragma once
// The pinhole camera of a frame solved from its world-space position and camera depth passes,
// for renderers that write no camera matrices (Blender, and most files a studio receives).
//
// For a pinhole camera, depth = a.P + a0 and u * depth = b.P + b0, v * depth = c.P + c0 hold
// exactly for every surface point P seen at NDC (u, v): depth is camera-space z, an affine
// function of world position, and the projection's numerators are affine too. A least-squares
// fit of those three rows over the frame's surface pixels gives worldToNDC; the rows, made
// orthonormal, give worldToCamera. Pixels where a filtered render mixed two surfaces (edges) or
// the sky and a surface do not fit a single point and are dropped as outliers, round by round.
// The world may be left- or right-handed: worldToCamera then has determinant +1 or -1.

#include <cstddef>
#include <optional>
#include <string>

#include "core/camera.h"
#include "core/image.h"

namespace posthaste {

/// The largest RMS reprojection error (pixels) a solve accepts by default; read's
/// `camera_residual` parameter declares it as its default.
inline constexpr double kDefaultMaxResidualPx = 0.05;

struct CameraSolveOptions {
    /// Largest RMS reprojection error (pixels) accepted over the pixels kept.
    double max_residual_px = kDefaultMaxResidualPx;
    /// The near clip for NDC z; absent: the nearest depth in the frame.
    std::optional<float> near_clip;
    /// Fit on every `stride`-th pixel in x and y (0: chosen so that at most about 100,000 pixels
    /// are looked at).
    int stride = 0;
};

struct CameraSolve {
    glm::mat4 world_to_camera{1.0f};
    glm::mat4 world_to_ndc{1.0f};
    float near_clip = 0.0f;
    float focal_over_sensor_width = 0.0f;  ///< focal length / sensor width (the x scale).
    float focal_over_sensor_height = 0.0f;
    double residual_px = 0.0;         ///< RMS reprojection error over the pixels kept.
    std::size_t pixels_valid = 0;     ///< Surface pixels looked at (finite depth and position).
    std::size_t pixels_kept = 0;      ///< Of those, the ones the final fit used.
    bool right_handed_world = false;  ///< worldToCamera has determinant -1.
    /// "solved from position + depth, residual 3e-05 px over 98.1 % of 245760 pixels".
    std::string describe() const;
};

/// Solve the camera of a frame whose `position` (world space, 3+ channels) and `depth` (camera
/// z, 1 channel) passes cover the absolute rectangle `data`, NDC spanning `display`. Throws a
/// runtime Error beginning with `who` when the passes cannot give a camera: too few surface
/// pixels, positions on one plane or line, depth not in the position's units, or a residual
/// over the limit (orthographic, distorted or inconsistent passes). Deterministic: the same
/// passes give the same bits.
CameraSolve solve_camera(const Image &position,
                         const Image &depth,
                         const Rect &display,
                         const Rect &data,
                         const std::string &who,
                         const CameraSolveOptions &options = {});

/// Fill a Camera's matrices (and the lens values it lacks) from a solve. The focal length comes
/// from `focal_length_mm` when given, else from the camera's own, else a 36 mm sensor (Blender's
/// default) is assumed; the sensor then follows from the solved field of view.
void apply_camera_solve(const CameraSolve &solve,
                        std::optional<float> focal_length_mm,
                        Camera &camera);

}  // namespace posthaste
