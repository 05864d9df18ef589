#pragma once
// Depth of field, part 2: the gather. Per output pixel, samples on a jittered spiral (disc or
// n-bladed polygon) inside the tile's dilated gather radius are split into a near field (in
// front of the pixel and in front of the focus plane: spreads with its own CoC and yields a
// coverage alpha) and a background (weights limited by the pixel's own CoC, so a blurred far
// field never bleeds over a sharper foreground), then composited near-over-background.
// In the spirit of Jimenez 2014 (CoD: AW) and Abadie 2018 ("A Life of a Bokeh"); full
// resolution, no bokeh brightness boost (highlights keep their energy, not more).

#include <cstdint>

#include "core/image.h"
#include "shading/dof/dof_coc.h"

namespace posthaste::shading {

enum class DofMethod {
    Gather,  ///< Near/far separated gather (the node's default).
    Simple,  ///< Baseline: uniform disc of each pixel's own CoC, no depth test (scatter-free).
};

/// The grid a crop blurred on its own starts on (the lighting split's share): the CoC tiles
/// (16 px) and the gather's groups of 8 pixels then fall as the whole frame's do, and the crop
/// can draw the frame's jitter (DofSettings::jitter_x0).
constexpr int kDofCropAlign = 16;

struct DofSettings {
    float max_coc_px = 64.0f;  ///< Largest CoC diameter, px.
    int samples = 64;          ///< Most samples per pixel; fewer where the CoC is small.
    float density = 8.0f;      ///< Samples per R^2 (R: gather radius, px): ~2.5 per disc pixel.
    int blades = 0;            ///< 0: disc; >= 3: regular polygon.
    float rotation_deg = 0.0f;
    DofMethod method = DofMethod::Gather;
    /// Gather at half resolution where the tile's gather radius is at least half_min_radius
    /// (full-resolution px), then composite at full resolution; smaller blurs stay full-res.
    bool half_res = false;
    float half_min_radius = 3.0f;
    float half_density = 8.0f;  ///< Samples per R^2 (half-res px) at half resolution.
    std::uint32_t seed = 0;
    /// Where this image's top-left pixel lies in the frame whose jitter it draws (x a multiple of
    /// 8, the gather's groups): the lighting split's share, blurred over a crop, samples each
    /// pixel as the rest's blur of the whole frame does. Their noise then cancels as one
    /// blur's would; drawn apart it added up (dof f48 0.0157 -> 0.018 RMSE).
    int jitter_x0 = 0, jitter_y0 = 0;
    /// Blur colour less this image's first three channels, placed with its top-left pixel at
    /// (subtract_x0, subtract_y0) (inside the frame): the lighting split's rest
    /// (shading/lighting/lighting_split.h) without a copy of the frame. Colour needs three channels.
    const Image *subtract = nullptr;
    int subtract_x0 = 0, subtract_y0 = 0;
    /// Tiles out of reach of every non-zero colour value keep their (zero) input instead of
    /// gathering zeros: the same bits, and a sparse image (the split's share) costs only
    /// where it holds something.
    bool skip_empty = false;
};

/// Milliseconds per pass of the last call: wall time, and process CPU time (all threads).
/// coc: CoC, colour sanitising and the half-resolution downsample; tiles: tile max/min and
/// dilation; gather: the half-resolution near/far gather; composite: the full-resolution pass
/// (copies in-focus tiles, gathers small-CoC tiles, composites the half-resolution layers).
struct DofTimes {
    double coc_ms = 0, tiles_ms = 0, gather_ms = 0, composite_ms = 0;
    double coc_cpu_ms = 0, tiles_cpu_ms = 0, gather_cpu_ms = 0, composite_cpu_ms = 0;
    int tiles_copied = 0, tiles_gathered = 0;  ///< 16 x 16 px tiles.
};

/// Blur `color` (1-4 channels, premultiplied) by the thin-lens CoC of `depth` (metres). Returns
/// false, leaving `out` untouched, when every pixel's CoC radius is under 1/16 px (the simple
/// method: under half a pixel; the caller keeps its input: bit for bit). The gather blurs a CoC
/// under half a pixel, which reaches no neighbour's centre, by the 4-neighbour stencil that adds
/// the disc's variance (r^2 / 4 per axis). Otherwise `out` is a new image of color's shape;
/// non-finite colour values (NaN, +-Inf) are read as 0 so the output stays finite.
/// Same bits for any thread count (jitter hashed from (x / 8, y): eight adjacent pixels share
/// their taps) and, within rounding, for the AVX2 and scalar paths.
bool apply_dof(const Image &color,
               const Image &depth,
               const DofLens &lens,
               const DofSettings &settings,
               Image &out,
               DofTimes *times = nullptr);

}  // namespace posthaste::shading
