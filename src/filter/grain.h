#pragma once
// Film grain: a deterministic noise field (hashed from the pixel's file coordinates, the frame
// and a seed) with a Gaussian correlation of `size` pixels and unit variance, applied as a
// multiplicative exposure noise in a log-like space (log2 of value + offset), weighted toward the
// midtones as film grain is most visible there.

#include <cstddef>
#include <cstdint>
#include <vector>

#include "core/image.h"
#include "core/memory.h"

namespace posthaste::filter {

struct GrainParams {
    double intensity = 0.15;      ///< standard deviation of the log2 exposure noise, stops
    double size = 0.8;            ///< Gaussian correlation radius (sigma) of the grain, pixels
    bool color = false;           ///< an independent field per channel (else one for all three)
    double response = 0.6;        ///< 0: the same grain at every level; 1: midtones only
    double offset = 1.0 / 256.0;  ///< the log space's offset: black gets grain of this order
    std::uint32_t seed = 0;
};

/// One or three planes of grain, rows `stride` floats apart, planes `plane` floats apart.
struct GrainField {
    ScratchArray<float> data;  ///< uninitialised pool memory: every value read is written
    std::size_t stride = 0, plane = 0;
    float at(int c, int x, int y) const
    {
        return data[std::size_t(c) * plane + std::size_t(y) * stride + std::size_t(x)];
    }
};

/// The unit-variance grain field for an image of w x h pixels whose pixel (0, 0) lies at file
/// coordinates (x0, y0), one plane per field (1 or 3). Deterministic: depends only on
/// coordinates, frame, seed and plane, not on the thread count or the window.
GrainField grain_field(int w, int h, int x0, int y0, int frame, const GrainParams &p);

/// `in` with grain on its first three channels: v' = (v + offset) 2^(intensity g w(L)) - offset,
/// g the field, L the pixel's Rec.709 luminance, w(L) = 1 - response + response 4 u (1 - u) with
/// u = L / (L + 0.18). Other channels are copied; non-finite values stay in their pixel.
Image apply_grain(const Image &in, int x0, int y0, int frame, const GrainParams &p);

}  // namespace posthaste::filter
