#pragma once
// Non-finite input values (NaN, Inf) would spread through any node that gathers neighbours. A
// gathering node reads its inputs through finite_view: the image itself when every value is
// finite (no copy, the common case), else a copy with those values replaced.

#include <cmath>

#include "core/image.h"

namespace posthaste {

/// One value as finite_view reads it with replacement 0: NaN and +-Inf as 0.
inline float finite_or_zero(float v)
{
    return std::isfinite(v) ? v : 0.0f;
}

/// `image` when all its values are finite (with `allow_positive_inf`, +inf counts as finite:
/// a depth pass's sky), otherwise `storage` filled with a copy in which every other value is
/// `replacement`. Parallel; the result does not depend on the thread count.
const Image &finite_view(const Image &image,
                         float replacement,
                         Image &storage,
                         bool allow_positive_inf = false);

}  // namespace posthaste
