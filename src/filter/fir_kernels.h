#pragma once
// One-dimensional FIR filters over Highway's lane types (fir_kernels.cpp), compiled for each x86
// target Highway supports and dispatched at run time: the separable convolutions of the blur,
// sharpen and grain. Taps are summed in order, the first as a product and the others as fused
// multiply-adds, so every target gives the same sum order (rounding may differ by target).

#include <vector>

namespace posthaste::filter {

/// The sampled Gaussian of standard deviation `sigma` taps, truncated at radius
/// max(1, ceil(truncate sigma)) and normalised to sum 1 (2r + 1 taps); sigma <= 0 gives the one
/// tap 1. The blur truncates at 4 sigma, the grain field at 3.
std::vector<float> gaussian_kernel(double sigma, double truncate = 4.0);

/// Buffers read or written by these kernels hold their n values rounded up to whole vectors:
/// n + kFirPad floats.
inline constexpr int kFirPad = 16;

/// out[x] = sum_i k[i] src[x + i stride] for x < n, i < taps. `src` holds
/// n + (taps - 1) stride + kFirPad floats, `out` n + kFirPad. With stride = the channel count,
/// an interleaved row is filtered along x, each channel on its own.
void fir_row(const float *src, const float *k, int taps, int stride, int n, float *out);

/// out[x] = sum_i k[i] rows[i][x] for x < n: a column filter over `taps` rows, each holding
/// n + kFirPad floats, as `out`.
void fir_columns(const float *const *rows, const float *k, int taps, int n, float *out);

}  // namespace posthaste::filter
