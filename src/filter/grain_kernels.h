#pragma once
// Grain's per-row kernels, written once over Highway's lane types (src/filter/grain_kernels.cpp)
// and compiled for each x86 target Highway supports (SSE4, AVX2, AVX-512), the best one chosen
// at run time. A tail shorter than a vector goes through the same arithmetic one lane at a time.

#include <cstdint>

namespace posthaste::filter {

/// Row buffers for the kernels below hold n values rounded up to whole vectors: n + kRowPad.
inline constexpr int kRowPad = 16;

/// Unit-variance white noise for pixels x0 .. x0 + n - 1 of one row: the sum of the four bytes
/// of pcg_hash(x ^ row_key), centred, times `unit`. `out` holds n + kRowPad floats.
void grain_noise_row(std::uint32_t row_key, int x0, int n, float unit, float *out);

/// One row of n RGBA pixels from `src` to `dst` (which may be the same): each of R, G, B becomes (v
/// + offset) 2^(g_c wgt) - offset where wgt = amount (1 - response + response 4 u (1 - u)), u = L /
/// (L + 0.18) from the pixel's Rec.709 luminance L (clamped at 0; u = 1 when L is not finite);
/// non-finite values are kept. g_c is field_r/g/b[x] (the same array three times for mono grain).
void grain_apply_rgba_row(const float *src,
                          float *dst,
                          const float *field_r,
                          const float *field_g,
                          const float *field_b,
                          int n,
                          float amount,
                          float response,
                          float offset);

}  // namespace posthaste::filter
