#pragma once
// The motion blur's per-pixel records (internal to src/shading/motion_blur*.cpp): the field
// planes the gather reads, the sky's log depth, the front and reach weights, and the pack that
// writes them (motion_blur_pack.cpp).

#include <algorithm>
#include <cstddef>
#include <limits>
#include <vector>

#include "core/image.h"
#include "core/memory.h"
#include "shading/motion_blur/motion_blur.h"

namespace posthaste::shading::motion_blur_detail {

/// Everything a sample reads, in one 32-byte record (two per cache line): color (up to four
/// channels, zero-padded); the blur half-extent scaled to a coverage density, v / (2 |v|^2), so
/// that |dot(wv, d)| = (how far the motion runs along d) / (2 |v|) with no division per
/// sample (zero below half a pixel of motion); log depth (kSkyLogZ for sky); |v|.
/// Log depth of sky: far beyond any finite depth, finite so that sky - sky = 0.
constexpr float kSkyLogZ = 1e30f;
constexpr float kInf = std::numeric_limits<float>::infinity();

/// Weight of "Y is in front of X": 1 in front, 0 behind, 0.5 at equal depth, a linear ramp in
/// log depth (relative depth difference) of width soft_z between. Sky is behind everything
/// finite and level with sky.
inline float front(float lzy, float lzx, float inv_soft)
{
    return std::min(std::max(0.5f + (lzx - lzy) * inv_soft, 0.0f), 1.0f);  // minss/maxss, no branch
}

/// 1 while the distance t is within the reach `len`, fading to 0 over the next pixel.
inline float reach(float t, float len)
{
    return std::min(std::max(len + 0.5f - t, 0.0f), 1.0f);
}

/// Uninitialized storage for n trivial records from the scratch pool (core/memory.h; pack
/// writes every record before it is read).
template <class T>
using Scratch = ScratchArray<T>;
template <class T>
Scratch<T> scratch(std::size_t n)
{
    return scratch_array<T>(n);
}

/// The per-pixel records of a frame, one plane per field (structure of arrays): the eight
/// pixels of a group sample eight adjacent pixels of one row (see Gather), which is one 32-byte
/// load per field, and a sample reads only the fields it uses. Colour: four planes, zero-padded
/// past the image's channels (floats, so the output stays a convex combination of input
/// values). Log depth: kSkyLogZ for sky. The blur half-extent scaled to a coverage density,
/// v / (2 |v|^2), so that |dot(w, d)| = (how far the motion runs along d) / (2 |v|) with no
/// division per sample (zero below half a pixel of motion); and |v|.
enum Field { kRed, kGreen, kBlue, kAlpha, kLogZ, kWx, kWy, kLen, kFields };

/// The planes (allocated uninitialized; pack writes every record) and the clamped half-extent
/// vectors (2 channels, for the tile max).
struct Packed {
    Scratch<float> block;
    std::size_t stride = 0;  ///< floats from one plane to the next (a multiple of 16)
    /// The clamped half-extent vectors (2 channels) for tiles.h's reductions, where the pack
    /// does not fold them itself (scalar path, tiles not a multiple of the lanes); else empty. The
    /// gather recovers a pixel's vector from its planes: v = w 2|v|^2.
    Image velocity;
    /// Per row: every alpha is exactly 1 (RGBA colour). A frame opaque everywhere blurs to
    /// alpha 1, and the gather does not sum its alpha plane.
    std::vector<unsigned char> opaque_rows;
    /// Tile max and tile bounds of the velocities (tiles.h), when the pack reduced them
    /// (vector rows, tiles a multiple of the lanes wide); else empty.
    Image tiles, bounds;

    float *plane(int field) const { return block.get() + std::size_t(field) * stride; }
};

/// The records of a frame (motion_blur_pack.cpp): the planes, the per-row opacity and, on the
/// vector path with tiles a multiple of its lanes wide, the tile max (and with `bounds`, the
/// tile bounds). `vector`: the vector rows (Highway, the CPU's best target).
Packed pack(const Image &color,
            const Image &motion,
            const Image &depth,
            const MotionBlurOptions &o,
            bool vector,
            bool bounds);

}  // namespace posthaste::shading::motion_blur_detail
