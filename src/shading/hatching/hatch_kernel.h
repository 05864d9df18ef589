#pragma once
// The hatching kernel's per-frame context, set up by hatch.cpp for the tile kernel
// (hatch_kernels.cpp). Internal to src/shading/hatch*.

#include <vector>

#include "core/image.h"
#include "shading/hatching/hatch.h"

namespace posthaste::shading::hatch_detail {

/// Outline pen: coverage clamp(r + 1 - dist, 0, 1) of an edge pixel at offset (dx, dy).
struct LineTap {
    int dx, dy;
    float coverage;
};

/// Everything the per-tile kernels need, computed once per frame.
struct KernelCtx {
    const Image *color, *depth, *normal, *position;
    Image *out;
    const Tam *tam;
    const ToneCurve *curve;
    const LineTap *taps;
    int tap_count;
    int line_reach;
    bool screen_space, tone_from_light, partial_mix, needs_samples;
    float depth_threshold, cos_thr, inv_scale, lod_offset, flat_lod, finest;
    float ambient, exposure, mix;
    glm::vec3 light, paper, ink_minus_paper, outline_color;
    bool triplanar;
    float triplanar_sharpness, zero_pow;  ///< zero_pow = std::pow(0, triplanar_sharpness)
    const Image *id;                      ///< With ids only.
    const std::vector<int> *ids;          ///< Hatch only these ids; null: everywhere.
};

/// One tile of hatch() (mix > 0; the caller copies otherwise), the lanes of the best target the
/// CPU has (simd.h); HatchingSimd compares the targets.
void hatch_tile(const KernelCtx &k, const Rect &t);

}  // namespace posthaste::shading::hatch_detail
