#pragma once
// Pen-and-ink hatching of a frame with a tonal art map (shading/hatching/tam.h; Praun et al. 2001):
// per-pixel tone, blended across 7 levels (white paper plus the TAM's 6 tones) with continuous
// weights; strokes anchored to surfaces through world position and normal (face-plane or
// triplanar projection), the TAM level from the pixel footprint of the TAM coordinates; outlines
// from depth and normal discontinuities. The screen-space mode (the naive method: TAM indexed by
// pixel coordinates) exists as a baseline for temporal coherence.
//
// Inputs follow docs/CONVENTIONS.md: color RGBA premultiplied scene-linear, depth camera-space z
// (+inf on sky), world normal and position (0 on sky), optional integer id.

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/vec3.hpp>
#include <vector>

#include "core/image.h"
#include "shading/hatching/tam.h"

namespace posthaste::shading {

struct HatchSettings {
    bool screen_space = false;  ///< Naive baseline: TAM at 1 texel per pixel of the screen.
    bool triplanar = false;     ///< Blend three planes by |N|; false: dominant axis of N only.
    float triplanar_sharpness = 4.0f;  ///< Exponent on the plane weights.
    float scale = 2.0f;                ///< World metres per TAM tile (surface mode).
    bool tone_from_light = false;      ///< Tone from n.l (light_dir, ambient) instead of luminance.
    glm::vec3 light_dir{0.4f, 1.0f, 0.3f};  ///< World direction towards the light (normalised).
    float ambient = 0.15f;                  ///< Tone floor with tone_from_light.
    float exposure = 1.0f;               ///< Multiplies luminance (or n.l) before the tone curve.
    float gamma = 2.2f;                  ///< tone = clamp(exposure * L)^(1 / gamma).
    float outline_width = 1.5f;          ///< Pixels; 0 turns outlines off.
    float depth_threshold = 0.02f;       ///< Depth edge: plane distance > this x depth.
    float normal_threshold_deg = 50.0f;  ///< Crease edge: normals differ by more than this.
    glm::vec3 paper{0.95f, 0.93f, 0.86f};
    glm::vec3 ink{0.04f, 0.04f, 0.06f};
    glm::vec3 outline{0.02f, 0.02f, 0.03f};
    std::vector<int> ids;  ///< Hatch only these material ids (empty: everywhere).
    float mix = 1.0f;      ///< 0: input color, 1: full drawing.
};

struct HatchInputs {
    const Image *color = nullptr;     ///< 4 channels (3 accepted: alpha 1).
    const Image *depth = nullptr;     ///< 1 channel.
    const Image *normal = nullptr;    ///< 3 channels.
    const Image *position = nullptr;  ///< 3 channels.
    const Image *id = nullptr;        ///< 1 channel; needed only when settings.ids is not empty.
};

/// The hatched color (same size and channel count as inputs.color). Every output value is
/// finite for any input, including NaN/Inf normals, positions and colors. Same bits for any
/// thread count. Sizes must match (asserted; callers check and report).
Image hatch(const HatchInputs &in, const HatchSettings &s, const Tam &tam);

/// The tone curve t(L) = clamp(L, 0, 1)^(1 / gamma), tabulated over sqrt(L) in 256 linear
/// segments: increasing, continuous, within 3e-4 of the exact curve for gamma 2.2, and no
/// pow() per pixel.
class ToneCurve {
   public:
    explicit ToneCurve(float gamma);
    /// Tone of a linear value; NaN reads as 1 (paper).
    float operator()(float linear) const
    {
        if (std::isnan(linear)) {
            return 1.0f;
        }
        const float q = std::sqrt(std::clamp(linear, 0.0f, 1.0f)) * float(kSegments);
        const int i = std::min(int(q), kSegments - 1);
        const float f = q - float(i);
        return table_[std::size_t(i)] + f * (table_[std::size_t(i) + 1] - table_[std::size_t(i)]);
    }
    /// Tone of an RGBA (or RGB) pixel: Rec.709 luminance, un-premultiplied, times exposure.
    float tone(const float *rgba, int channels, float exposure) const
    {
        const float alpha = channels >= 4 ? rgba[3] : 1.0f;
        float lum = 0.2126f * rgba[0] + 0.7152f * rgba[1] + 0.0722f * rgba[2];
        if (alpha > 1e-6f && alpha < 1.0f) {
            lum /= alpha;  // tone of the surface, not of its coverage
        }
        return (*this)(lum * exposure);
    }

    static constexpr int kSegments = 256;
    /// The kSegments + 1 tabulated tones at sqrt(L) = i / kSegments (for vector kernels).
    const float *table() const { return table_.data(); }

   private:
    std::array<float, kSegments + 1> table_{};
};

/// Tone in [0, 1] (1: paper white) of a color, as hatch() computes it in luminance mode.
float hatch_tone(const float *rgba, int channels, const HatchSettings &s);

}  // namespace posthaste::shading
