#pragma once
// ssgi's upsample of one row (ssgi_resolve.cpp) over Highway's lane types
// (ssgi_resolve_kernels.cpp).

#include <cstdint>

namespace posthaste::shading {

/// One output row of the upsample: the two reduced rows it lies between (depth, NaN for no
/// surface; unit normals and light, three floats a pixel), its vertical weight, and per output
/// pixel the full-resolution depth, normal (three planes), the left and right reduced columns
/// and the horizontal weight.
struct SsgiUpsampleRow {
    const float *z0, *z1;  ///< Reduced depth of rows j0, j1.
    const float *n0, *n1;  ///< Reduced unit normals (x, y, z a pixel; 0 where unknown).
    const float *v0, *v1;  ///< Reduced light (r, g, b a pixel).
    float fy;
    const float *z;  ///< Full-resolution depth of the row.
    /// Full-resolution normal of the row: three floats a pixel (n3), or, where the normal pass
    /// has another channel count, three planes.
    const float *n3 = nullptr;
    const float *nx = nullptr, *ny = nullptr, *nz = nullptr;
    int ow = 0;                   ///< The reduced rows' length (columns).
    /// Reduced columns left and right of each pixel, non-decreasing along the row.
    const std::int32_t *i0, *i1;
    const float *fx;              ///< Horizontal weight of each pixel.
    /// Optional (albedo null: none): each pixel times intensity, (1 - metallic) where a
    /// material row is given (its channel 1, mc channels a pixel), and its albedo (na channels:
    /// channel min(c, na - 1)), its negative light clamped to 0.
    const float *albedo = nullptr;
    int na = 3;
    const float *material = nullptr;
    int mc = 0;
    float intensity = 1.0f;
};

/// One row of the denoise at the reduced resolution: the reduced depth (NaN for no surface),
/// unit normals (three floats a pixel, 0 where unknown) and light (three floats a pixel) of the
/// whole image, ow x oh, and the row y to write into out (three floats a pixel).
struct SsgiDenoiseRow {
    const float *z, *n, *light;
    int ow, oh, y;
    float *out;
};

/// Denoises the pixels [x_begin, end) of the row, end the last whole vector of lanes before
/// x_end, with a 5 x 5 window that lies inside the row (x_begin >= 2, x_end <= ow - 2): the bits
/// of the scalar loop in ssgi_resolve.cpp, on every target. Returns end; the caller does the
/// rest.
int ssgi_denoise_row(const SsgiDenoiseRow &r, int x_begin, int x_end);

/// The w upsampled pixels of a row into out (three floats a pixel): depth- and normal-aware
/// bilinear weights over the four taps, the tap nearest in depth where none weighs, 0 on the
/// sky. The bits of the scalar loop it replaced, on every target (no FMA contraction).
void ssgi_upsample_row(const SsgiUpsampleRow &r, int w, float *out);

}  // namespace posthaste::shading
