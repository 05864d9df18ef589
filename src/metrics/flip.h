#pragma once
// FLIP: a perceptual difference between a reference and a test image, per pixel in [0, 1].
// LDR-FLIP after Andersson et al., "FLIP: A Difference Evaluator for Alternating Images",
// HPG 2020: a color pipeline (YyCxCz, contrast sensitivity filters sized by pixels per degree,
// clamp to the RGB cube, L*a*b* with the Hunt adjustment, HyAB distance, remap to [0, 1]) and a
// feature pipeline (edge and point detectors on the achromatic channel), combined as
// color^(1 - feature). HDR-FLIP after Andersson et al., "Visualizing Errors in Rendered High
// Dynamic Range Images" (EG 2021) and Ray Tracing Gems II ch. 19 (2021): exposures from the
// reference's max and median luminance, ACES-fit tone mapping per exposure, LDR-FLIP on each,
// per-pixel max.

#include <glm/vec3.hpp>
#include <optional>
#include <vector>

#include "core/image.h"
#include "core/srgb.h"

namespace posthaste::metrics {

/// The papers' default viewing condition: a 0.7 m wide 3840-pixel monitor seen from 0.7 m,
/// 0.7 * 3840 / 0.7 * pi / 180 = 67.02 pixels per degree.
inline constexpr float kDefaultPixelsPerDegree = 67.0206f;
/// The most pixels per degree FLIP takes: its filters' radii grow with it (a 4K display at arm's
/// length is about 100; 1e9 ran a filter of a billion taps, 1e30 overflowed its radius).
inline constexpr float kMaxPixelsPerDegree = 1000.0f;

struct FlipOptions {
    float pixels_per_degree = kDefaultPixelsPerDegree;
    /// HDR only: exposure range in stops; computed from the reference when not given.
    std::optional<float> start_exposure;
    std::optional<float> stop_exposure;
    /// HDR only: number of exposures; max(2, ceil(stop - start)) when <= 0.
    int num_exposures = 0;
};

struct FlipResult {
    Image error_map;    ///< 1 channel, per-pixel FLIP in [0, 1].
    double mean = 0.0;  ///< Mean of error_map (summed per row in double, rows in order).
    float max = 0.0f;
    int max_x = 0, max_y = 0;  ///< First pixel in scan order holding the max.
    // HDR only (zero for LDR):
    float start_exposure = 0.0f;
    float stop_exposure = 0.0f;
    int num_exposures = 0;
};

/// LDR-FLIP of two images whose first three channels are sRGB-encoded RGB in [0, 1] (values are
/// clamped to [0, 1], NaN reads as 0). Throws Error unless both have the same size and >= 3
/// channels.
FlipResult flip_ldr(const Image &reference, const Image &test, const FlipOptions &options = {});

/// HDR-FLIP of two images whose first three channels are scene-linear Rec.709 RGB (values are
/// clamped to [0, 65536], NaN reads as 0). Throws Error as flip_ldr.
FlipResult flip_hdr(const Image &reference, const Image &test, const FlipOptions &options = {});

/// A magma-like perceptual color map, dark purple-black at 0 to pale yellow at 1, as
/// sRGB-encoded RGB. t is clamped to [0, 1]; NaN maps to 1 (the worst error).
glm::vec3 flip_color_map(float t);

/// An RGB image of error_map (channel 0) through flip_color_map; `linear` decodes the sRGB
/// values to linear (for EXR output, which is scene-linear), else they stay display-encoded.
Image flip_heatmap(const Image &error_map, bool linear = true);

/// The stages, exposed for tests. Colors are (R, G, B), (X, Y, Z), (Yy, Cx, Cz) or (L*, a*, b*).
namespace flip {

inline constexpr float kQc = 0.7f;           ///< Exponent on the HyAB distance.
inline constexpr float kPc = 0.4f;           ///< Fraction of the max distance mapped to kPt...
inline constexpr float kPt = 0.95f;          ///< ...onto this error.
inline constexpr float kQf = 0.5f;           ///< Exponent on the feature difference.
inline constexpr float kW = 0.082f;          ///< Edge detector peak-to-trough width in degrees.
inline constexpr float kToneTarget = 0.85f;  ///< Tone-mapped value defining the exposures.

using posthaste::linear_to_srgb;  // core/srgb.h
using posthaste::srgb_to_linear;
glm::vec3 linear_rgb_to_xyz(glm::vec3 rgb);
glm::vec3 xyz_to_linear_rgb(glm::vec3 xyz);
glm::vec3 xyz_to_ycxcz(glm::vec3 xyz);
glm::vec3 ycxcz_to_xyz(glm::vec3 ycxcz);
glm::vec3 xyz_to_lab(glm::vec3 xyz);
/// a* and b* scaled by 0.01 L*.
glm::vec3 hunt_adjust(glm::vec3 lab);
/// |dL| + sqrt(da^2 + db^2).
float hyab(glm::vec3 a, glm::vec3 b);
/// HyAB^kQc between Hunt-adjusted green and blue: the largest color distance.
float max_color_distance();
/// Map HyAB^kQc to [0, 1]: linear to kPt at kPc * max, then linear to 1 at max.
float remap_color_difference(float power_hyab, float cmax);

/// A 2D contrast sensitivity filter, a sum of up to two separable Gaussian terms:
/// kernel(x, y) = sum_t weight[t] * g[t][x] * g[t][y], with the 2D sum equal to 1.
struct CsfKernel {
    int radius = 0;
    std::vector<float> weight;
    std::vector<std::vector<float>> g;  ///< Each 2 * radius + 1 taps.
    /// The 2D kernel's value at offset (dx, dy) in [-radius, radius]^2.
    float at(int dx, int dy) const;
};
/// channel 0: achromatic, 1: red-green, 2: blue-yellow. Radius ceil(3 sqrt(b_max / (2 pi^2))
/// ppd), shared by the three channels (b_max: the widest Gaussian of all three).
CsfKernel csf_kernel(int channel, float ppd);

/// 1D factors of the feature detectors, radius ceil(3 sd), sd = 0.5 kW ppd: the Gaussian g
/// (sum 1), its first derivative d1 and second derivative d2 (each with positive taps summing
/// to 1 and negative taps to -1). Edge x = d1(x) g(y); point x = d2(x) g(y).
struct FeatureKernels {
    int radius = 0;
    std::vector<float> g, d1, d2;
};
FeatureKernels feature_kernels(float ppd);

/// ACES filmic fit (Narkowicz) with the 0.6 pre-exposure folded in, clamped to [0, 1].
float tone_map_aces(float x);
/// The input x with tone_map_aces(x) == kToneTarget.
float tone_target_input();

}  // namespace flip

}  // namespace posthaste::metrics
