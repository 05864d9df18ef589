#pragma once
// Non-finite input values (NaN, Inf) would spread through any node that gathers neighbours. A
// gathering node reads its inputs through finite_view: the image itself when every value is
// finite (no copy, the common case), else a copy with those values replaced.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "core/image.h"

namespace posthaste {

/// The largest magnitude finite_view passes: a gather's sum of a few million such values with
/// weights up to ten stays within float (values near float's largest, 3.4e38, summed to infinity
/// in bloom's FFT, sharpen, lens and transform, and to NaN where two infinities met).
inline constexpr float kMaxGatherValue = 1e30f;

/// One value as finite_view reads it with replacement 0: NaN and +-Inf as 0.
inline float finite_or_zero(float v)
{
    return std::isfinite(v) ? v : 0.0f;
}

/// A direction given as a vector whose float length over- or underflows (finite components, not
/// all zero, such as [1e-30, 1e-30, 0]) divided by its largest component, so that normalising it
/// gives the direction it names; any other vector as it is (ordinary directions keep their bits).
inline glm::vec3 rescaled_direction(glm::vec3 d)
{
    const float big = std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)});
    const float len = glm::length(d);
    if (big > 0.0f && std::isfinite(big) && !(std::isfinite(len) && len > 1e-12f)) {
        d /= big;
    }
    return d;
}

/// `image` when all its values are finite and at most kMaxGatherValue in magnitude (with
/// `allow_positive_inf`, +inf counts as fine: a depth pass's sky), otherwise `storage` filled
/// with a copy in which every other non-finite value is `replacement` and every larger finite
/// value is +-kMaxGatherValue. Parallel; the result does not depend on the thread count.
const Image &finite_view(const Image &image,
                         float replacement,
                         Image &storage,
                         bool allow_positive_inf = false);

}  // namespace posthaste
