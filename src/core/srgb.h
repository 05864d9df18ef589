#pragma once
// The sRGB transfer curve (IEC 61966-2-1), the one copy for every floor: the reader decodes
// sRGB-encoded 8-bit files with it, FLIP and the benchmarks' previews encode and decode with it.
// Display transforms for output go through OpenColorIO (io/color.h), not through this.

#include <cmath>

namespace posthaste {

/// sRGB-encoded value to linear (values below 0 follow the linear segment).
inline float srgb_to_linear(float c)
{
    return c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f);
}

/// Linear value to sRGB-encoded (values below 0 follow the linear segment).
inline float linear_to_srgb(float c)
{
    return c <= 0.0031308f ? c * 12.92f : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
}

}  // namespace posthaste
