#pragma once
// Motion blur as a gather filter over one frame's color, depth and screen motion: the
// reconstruction filter of the motion_blur node (nodes/motion_blur.cpp), and the uniform blur
// along each pixel's own velocity that it is compared against. Free functions so benchmarks
// and tests can time and call the stages directly.

#include <cstdint>

#include "core/image.h"

namespace posthaste::shading {

enum class BlurMethod {
    Reconstruct,  ///< Tile-max / neighbour-max reconstruction (McGuire 2012, Guertin 2014).
    Uniform,      ///< Average along the pixel's own motion, no depth (the seeds' method).
};

struct MotionBlurOptions {
    BlurMethod method = BlurMethod::Reconstruct;
    /// Fraction of the frame interval the shutter is open, centred on the frame: a pixel blurs
    /// over +-shutter/2 x motion.
    float shutter = 0.5f;
    int samples = 32;           ///< Most samples per pixel (fewer for short motion).
    float max_radius = 64.0f;   ///< Longest blur half-extent, pixels.
    int tile = 16;              ///< Tile size of the tile-max reduction, pixels.
    float soft_z = 0.05f;       ///< Depth ramp of the front/back test, relative to depth.
    float tile_jitter = 0.25f;  ///< Jitter of the neighbour-max lookup, in tiles (hides seams).
    /// Tiles whose reachable vectors all lie within coherence x the longest of each other take
    /// the uniform path (0: never).
    float coherence = 0.1f;
    /// Eight adjacent pixels of a row share their sample positions (one run of adjacent pixels,
    /// read with one load per field) where the vectors they sample along all lie within this
    /// many pixels of the middle of their bounding box; a sample then moves by at most this
    /// much at the ends of its path (0: every pixel samples on its own).
    float group_tolerance = 0.5f;
    std::uint32_t seed = 0;
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

/// Milliseconds per stage of the last call: wall time, and CPU time of the whole process (all
/// threads; on a shared machine the wall time also counts waiting for a core).
struct MotionBlurStats {
    double pack_ms = 0.0, tile_max_ms = 0.0, neighbour_max_ms = 0.0, gather_ms = 0.0;
    double pack_cpu_ms = 0.0, tile_max_cpu_ms = 0.0, neighbour_max_cpu_ms = 0.0,
           gather_cpu_ms = 0.0;
    int tiles_copied = 0, tiles_coherent = 0, tiles_total = 0;
    /// 8-pixel groups gathered (outside copied tiles), and how many shared a run of samples.
    long groups = 0, groups_shared = 0;
};

/// Blur `color` (1-4 channels) along `motion` (>= 2 channels, pixels from the previous frame to
/// this one, x right, y down) with `depth` (1 channel, camera-space z, +inf for sky; only read by
/// Reconstruct, may be empty for Uniform). Non-finite motion counts as zero, non-finite depth as
/// sky. Zero motion returns `color` bit for bit; the output does not depend on the thread count.
/// Sizes must match (checked by the caller).
Image motion_blur(const Image &color,
                  const Image &motion,
                  const Image &depth,
                  const MotionBlurOptions &options,
                  MotionBlurStats *stats = nullptr);

/// The tile max and tile bounds (shading/tiles.h) of the clamped half-extent vectors
/// (motion x shutter / 2, at most max_radius long), as motion_blur computes them (the vector
/// pack folds them in); for tests.
void motion_blur_tiles(const Image &color,
                       const Image &motion,
                       const Image &depth,
                       const MotionBlurOptions &options,
                       Image &tiles,
                       Image &bounds);

}  // namespace posthaste::shading
