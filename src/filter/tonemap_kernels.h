#pragma once
// Tone curves over rows of RGBA pixels, written once over Highway (tonemap_kernels.cpp) and
// dispatched to the CPU's best target at run time. The formulas are in nodes/tonemap.cpp's
// header comment and docs/GRAPHS.md.

namespace posthaste::filter {

enum class ToneCurve { Reinhard = 0, Hable = 1, Aces = 2, Agx = 3 };

/// n RGBA pixels from src to dst (may be the same): unpremultiplied (alpha > 1e-6), the curve
/// per channel or on the Rec.709 luminance (RGB scaled by mapped / luminance), premultiplied
/// back; alpha copied; a pixel with a non-finite R, G or B is copied unchanged.
void tonemap_rgba_row(
    const float *src, float *dst, int n, ToneCurve curve, bool luminance, float white);

}  // namespace posthaste::filter
