#pragma once
// Tonal art maps (Praun, Hoppe, Webb, Finkelstein 2001, "Real-Time Hatching", section 4): a set
// of hatching textures, one per tone, each with a mip chain, built so that every stroke of a
// lighter tone appears in every darker tone, and every stroke of a coarse level appears in every
// finer level of its tone (the nesting property). Strokes keep their width in texels on every
// level, so a renderer that picks the level from the pixel footprint draws strokes of constant
// screen width; their length is a fraction of the tile, so they stay attached to the surface.
//
// Textures tile (wrap) in both directions. Values are ink coverage in [0, 1] (0: paper).
// Level 0 is the finest (size x size); levels 0 .. stroke_levels - 1 hold drawn strokes; the
// levels below them are 2x2 box averages down to 1 x 1, so distant surfaces fade to a flat tone.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace posthaste::shading {

inline constexpr int kTamTones = 6;

/// Parameters of a tonal art map. Equal parameters give the same bits.
struct TamParams {
    int size = 256;           ///< Finest level side, a power of two in 16..1024.
    int stroke_levels = 4;    ///< Levels with drawn strokes (256, 128, 64, 32), 1..log2(size)-2.
    float width = 1.5f;       ///< Stroke width in texels of whichever level it is drawn into.
    float length = 0.3f;      ///< Stroke length, fraction of the tile side (0.02..0.9).
    float jitter = 0.3f;      ///< 0..1: random spread of angle (+-jitter*12 deg), length, bend.
    float angle_deg = 45.0f;  ///< Main stroke direction, degrees counter-clockwise from +u.
    float cross_angle_deg = -45.0f;  ///< Direction of the cross-hatching strokes.
    int cross_tones = 2;             ///< The darkest this many tones add cross strokes (0..6).
    int candidates = 8;              ///< Random candidates per stroke; the best one is kept.
    float darkest = 0.9f;  ///< Mean ink coverage of the darkest tone (tone k: darkest k / 6).
    std::uint32_t seed = 1;
};

/// One stroke: centre in tile units [0, 1)^2, unit direction, length in tile units, perpendicular
/// bend in tile units at the middle; `tone` and `level` say where it was first added.
struct TamStroke {
    float cx = 0, cy = 0, dx = 1, dy = 0, length = 0, bend = 0;
    int tone = 0, level = 0;
};

class Tam {
   public:
    Tam() = default;
    int size() const { return size_; }
    /// All levels, stroke levels first then the filtered ones (down to 1 x 1).
    int levels() const { return levels_; }
    int stroke_levels() const { return stroke_levels_; }
    /// Side of level l.
    int level_size(int l) const { return size_ >> l; }
    /// Coverage texels of tone t (0: lightest), level l, row-major.
    const float *texels(int tone, int level) const
    {
        return data_.data() + std::size_t(tone) * tone_stride_ + level_offset_[std::size_t(level)];
    }
    /// Mean coverage of tone t at level l.
    float mean(int tone, int level) const;
    /// Every stroke in the order added.
    const std::vector<TamStroke> &strokes() const { return strokes_; }
    /// Coverage of tone t at (u, v) in tile units (wrapping), filtered between the two levels
    /// around `lod` (0: finest; clamped to the chain; see ramp_at).
    float sample(int tone, float u, float v, float lod) const
    {
        return ramp_at(tone + 1, 0.0f, u, v, lod);
    }
    /// Ink of the 7-level ramp (paper, then tones 0..5) at darkness d in [0, 1]: with
    /// s = 6 d, k = floor(s), the blend (1 - (s - k)) C(k) + (s - k) C(k + 1), C(0) = 0 (paper),
    /// C(j) = tone j - 1; continuous in d. Trilinear like sample(); NaN d reads as paper.
    float ramp(float darkness, float u, float v, float lod) const
    {
        if (!(darkness > 0.0f)) {
            return 0.0f;
        }
        const float s = std::min(darkness, 1.0f) * float(kTamTones);
        const int k = std::min(int(s), kTamTones - 1);
        return ramp_at(k, s - float(k), u, v, lod);
    }
    /// Floats per texel in packed(): paper 0, tones 0..5, tone 5 again.
    static constexpr std::size_t kPacked = 8;
    /// Texel-major copy of every level for vector kernels: texel i of level l starts at
    /// packed() + (level_offset(l) + i) * kPacked; ramp entry k of it is element k.
    const float *packed() const { return packed_.data(); }
    /// First texel of level l in packed() (and in each tone plane).
    std::size_t level_offset(int level) const { return level_offset_[std::size_t(level)]; }
    /// Milliseconds build_tam took: wall clock, and CPU time of its (single) thread.
    double build_ms() const { return build_ms_; }
    double build_cpu_ms() const { return build_cpu_ms_; }

   private:
    friend Tam build_tam(const TamParams &p);
    /// Sizes and offsets for `p`, texels zero.
    static Tam layout(const TamParams &p);
    /// The strokes and levels (build_tam without the disk cache and the packing).
    static Tam build(const TamParams &p);
    /// packed_ from data_.
    void pack();
    /// Filtered blend of ramp entries k and k + 1 (weight f) of the packed texels.
    float ramp_at(int k, float f, float u, float v, float lod) const
    {
        lod = std::clamp(lod, 0.0f, float(levels_ - 1));  // NaN lod: clamp keeps NaN
        const int l0 = lod >= 0.0f ? int(lod) : levels_ - 1;
        const float fl = lod >= 0.0f ? lod - float(l0) : 0.0f;
        // Fixed point with 16 fraction bits at the finest level, wrapped to the tile; coarser
        // levels shift it right. finite u, v only (the caller's positions are finite).
        u -= std::floor(u);
        v -= std::floor(v);
        const float one = float(size_) * 65536.0f;
        const std::int32_t fu = std::int32_t(u * one), fv = std::int32_t(v * one);
        // Departure from plain trilinear: the blend between levels runs over the middle half of
        // each lod step only ("brilinear"), still continuous in lod, and half the pixels read a
        // single level.
        const float b = std::clamp(2.0f * fl - 0.5f, 0.0f, 1.0f);
        if (b <= 0.0f) {
            return ramp_level(k, f, l0, fu, fv);
        }
        if (b >= 1.0f) {
            return ramp_level(k, f, l0 + 1, fu, fv);
        }
        const float c0 = ramp_level(k, f, l0, fu, fv);
        return c0 + b * (ramp_level(k, f, l0 + 1, fu, fv) - c0);
    }
    /// Bilinear, wrapping, at fixed-point finest-level coordinates (16 fraction bits). Packed
    /// texels hold 8 floats: paper 0, tones 0..5, tone 5 again, so entries k and k + 1 share a
    /// cache line.
    float ramp_level(int k, float f, int level, std::int32_t fu, std::int32_t fv) const
    {
        const int s = size_ >> level, mask = s - 1;
        const std::int32_t x = (fu >> level) - 32768, y = (fv >> level) - 32768;  // - half texel
        const int x0 = (x >> 16) & mask, y0 = (y >> 16) & mask;  // arithmetic shift: floor
        const float fx = float(x & 0xffff) * (1.0f / 65536.0f);
        const float fy = float(y & 0xffff) * (1.0f / 65536.0f);
        const int x1 = (x0 + 1) & mask;
        const float *base =
            packed_.data() + level_offset_[std::size_t(level)] * kPacked + std::size_t(k);
        const float *r0 = base + std::size_t(y0) * std::size_t(s) * kPacked;
        const float *r1 = base + std::size_t((y0 + 1) & mask) * std::size_t(s) * kPacked;
        const std::size_t o0 = std::size_t(x0) * kPacked, o1 = std::size_t(x1) * kPacked;
        const float t00 = r0[o0] + f * (r0[o0 + 1] - r0[o0]);
        const float t10 = r0[o1] + f * (r0[o1 + 1] - r0[o1]);
        const float t01 = r1[o0] + f * (r1[o0 + 1] - r1[o0]);
        const float t11 = r1[o1] + f * (r1[o1 + 1] - r1[o1]);
        const float a = t00 + fx * (t10 - t00);
        const float c = t01 + fx * (t11 - t01);
        return a + fy * (c - a);
    }
    int size_ = 0, stroke_levels_ = 0, levels_ = 0;
    std::size_t tone_stride_ = 0;
    std::vector<std::size_t> level_offset_;
    std::vector<float> data_;    ///< Tone-major planes (building, tests).
    std::vector<float> packed_;  ///< Texel-major, kPacked floats per texel (sampling).
    std::vector<TamStroke> strokes_;
    double build_ms_ = 0, build_cpu_ms_ = 0;
};

/// Throws Error (usage) naming the bad field when params are out of range.
void validate(const TamParams &p);

/// Build the map: tone by tone (lightest first), level by level (coarsest first), add strokes
/// until the level's mean coverage reaches the tone's target; each stroke is the best of
/// `candidates` random strokes by the paper's goodness (new ink over ink drawn, summed over the
/// levels it enters), and is drawn into its level, every finer level, and (by construction)
/// every darker tone. Single-threaded and hash-seeded: deterministic.
Tam build_tam(const TamParams &p);

}  // namespace posthaste::shading
