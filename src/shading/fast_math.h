#pragma once
// Inline replacements for the libm calls on per-pixel paths (fog, sky, aerial perspective): no
// call overhead, and accurate to a few float ulps, which the tests in tests/unit check.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>

namespace posthaste::shading {

/// exp(x) with relative error < 3e-7 for x in [-87, 88]; 0 below, +inf above; NaN gives NaN.
/// Cody-Waite reduction x = n ln2 + r, |r| <= ln2 / 2, then a degree-6 Taylor polynomial.
inline float fast_exp(float x)
{
    if (!(x >= -87.0f)) {
        return x != x ? x : 0.0f;
    }
    if (x > 88.0f) {
        return INFINITY;
    }
    const float t = x * 1.44269504089f;
    const int n = int(t + (t >= 0.0f ? 0.5f : -0.5f));
    const float r = (x - float(n) * 0.693145751953125f) - float(n) * 1.428606765330187e-06f;
    float p = 1.0f / 720.0f;
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    return p * std::bit_cast<float>(std::uint32_t(n + 127) << 23);
}

/// acos(x) for x in [-1, 1] to about 2e-8 rad (Abramowitz and Stegun 4.4.46); out-of-range inputs
/// clamp to [-1, 1] and NaN reads as 1 (returns 0).
inline float fast_acos(float x)
{
    const float ax = std::min(1.0f, std::fabs(x));  // NaN -> 1
    float p = -0.0012624911f;
    p = p * ax + 0.0066700901f;
    p = p * ax - 0.0170881256f;
    p = p * ax + 0.0308918810f;
    p = p * ax - 0.0501743046f;
    p = p * ax + 0.0889789874f;
    p = p * ax - 0.2145988016f;
    p = p * ax + 1.5707963050f;
    const float r = std::sqrt(1.0f - ax) * p;
    return x < 0.0f ? 3.14159265358979f - r : r;
}

/// atan2(y, x) to about 1e-7 rad: the arctangent of the smaller over the larger magnitude, in
/// [0, 1], by Abramowitz and Stegun 4.4.49 (error 2e-8), then moved to its octant. 0 at the
/// origin.
inline float fast_atan2(float y, float x)
{
    const float ax = std::fabs(x), ay = std::fabs(y);
    const float hi = std::max(ax, ay), lo = std::min(ax, ay);
    if (!(hi > 0.0f)) {
        return 0.0f;
    }
    const float a = lo / hi, s = a * a;
    float p = 0.0028662257f;
    p = p * s - 0.0161657367f;
    p = p * s + 0.0429096138f;
    p = p * s - 0.0752896400f;
    p = p * s + 0.1065626393f;
    p = p * s - 0.1420889944f;
    p = p * s + 0.1999355085f;
    p = p * s - 0.3333314528f;
    float r = (p * s + 1.0f) * a;
    if (ay > ax) {
        r = 1.57079632679f - r;
    }
    if (x < 0.0f) {
        r = 3.14159265359f - r;
    }
    return y < 0.0f ? -r : r;
}

}  // namespace posthaste::shading
