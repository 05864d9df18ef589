#pragma once
// Camera-only motion: the screen motion a static world would have, from depth and the camera
// matrices of this frame and the previous one (docs/CONVENTIONS.md: worldToCamera, worldToNDC,
// prevWorldToNDC). Same convention as the `motion` pass: pixels from the previous frame to this
// one, x right, y down.

#include <string>

#include "core/camera.h"
#include "core/image.h"

namespace posthaste::shading {

/// Motion (2 channels) for every pixel of `depth` (camera-space z). Pixels with z = +inf (sky)
/// reproject their view direction (camera rotation only); non-finite or non-positive depth, or a
/// point behind the previous camera, gives zero motion. Throws Error naming `who` and the missing
/// header attribute when a matrix is absent.
Image camera_motion(const Image &depth, const Camera &camera, const std::string &who);

}  // namespace posthaste::shading
