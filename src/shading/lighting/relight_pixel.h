#pragma once
// Pieces of the relight method shared by its reference (relight.cpp) and its vector rows
// (relight_kernels.cpp), which fall back to them for the lanes they do not cover. Not for other
// callers: shading/lighting/relight.h is the interface.

#include "shading/lighting/relight.h"

namespace posthaste::shading::relight {

// One shaded pixel's inputs.
struct Prepared {
    bool valid = false;
    glm::vec3 p{0.0f}, n{0.0f, 0.0f, 1.0f}, v{0.0f, 0.0f, 1.0f};
    shading::Surface surf;
    const shading::DirectOptions *opts = nullptr;
};

/// Stage 1 for one pixel: its surface, or pr.valid = false for background and unusable pixels.
void prepare_pixel(const Inputs &sh, int x, int y, Prepared &pr);
/// The lights' sum at one prepared pixel, one light at a time (shading::direct_light).
glm::vec3 light_sum_scalar(const Inputs &sh, const Prepared &pr, int x, int y);
/// The pixel's output color from its lights' sum `c` and its input `in`.
glm::vec3 finish_pixel(const Inputs &sh, const Prepared &pr, glm::vec3 c, const float *in);

/// Every row of `out` through the vector kernel on the best Highway target (sh.kernel_ok
/// options only).
void shade_rows_vector(const Inputs &sh, Image &out);

}  // namespace posthaste::shading::relight
