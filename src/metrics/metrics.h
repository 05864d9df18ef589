#pragma once
// Numeric image comparison that agrees with OpenImageIO's idiff / ImageBufAlgo::compare (2.4):
// mean, RMS, PSNR, max error and where, pixels over the warn and fail thresholds, and idiff's
// pass / warning / failure verdict as a pure function of those numbers.
//
// Definitions (as in ImageBufAlgo::compare):
//   - error per value f = |a - b|, the subtraction done in float; sums in double.
//   - mean = sum f / (pixels * channels); rms = sqrt(sum f^2 / (pixels * channels)).
//   - psnr = 20 log10(peak / rms), peak = max(1, largest |a| or |b| seen), +inf when rms == 0.
//   - max error: the first value in scan order (y, then x, then channel) with the largest f.
//   - a pixel counts once as over a threshold when ANY of its channels is (f > thresh and, when
//     a relative threshold is set, f / mean(|a|, |b|) > relative).
//   - NaN matches NaN and Inf matches Inf (either sign); such values add nothing. The first
//     mismatch in finiteness sets max error to +inf at its location and adds nothing else; later
//     mismatches enter the sums (making mean and rms Inf or NaN) and the counts.

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "core/image.h"

namespace posthaste::metrics {

/// Error statistics over a set of channels (all of an image's channels, or one of them).
struct ErrorStats {
    double mean_error = 0.0;
    double rms_error = 0.0;
    double psnr = std::numeric_limits<double>::infinity();
    double max_error = 0.0;
    int max_x = 0;  ///< Pixel of the max error (0, 0 when every value matches).
    int max_y = 0;
    int max_channel = 0;
    double peak = 1.0;             ///< The value PSNR is relative to: max(1, largest |value|).
    std::uint64_t warn_count = 0;  ///< Pixels with a value over the warn threshold.
    std::uint64_t fail_count = 0;  ///< Pixels with a value over the fail threshold.
};

/// Thresholds with idiff's meaning and defaults (-fail, -failrelative, -failpercent, -hardfail,
/// -allowfailures, -warn, -warnrelative, -warnpercent, -hardwarn).
struct Thresholds {
    float fail = 1e-6f;          ///< A value fails when its error is above this...
    float fail_relative = 0.0f;  ///< ...and above this fraction of mean(|a|, |b|).
    float fail_percent = 0.0f;   ///< Percent of pixels allowed to fail.
    float hard_fail = std::numeric_limits<float>::infinity();  ///< Fail when max error is above.
    int allow_failures = 0;  ///< Pass outright when at most this many pixels fail.
    float warn = 1e-6f;
    float warn_relative = 0.0f;
    float warn_percent = 0.0f;
    float hard_warn = std::numeric_limits<float>::infinity();
};

/// Whole-image and per-channel comparison results.
struct CompareStats {
    ErrorStats all;                    ///< Over every channel, as idiff prints it.
    std::vector<ErrorStats> channels;  ///< channels[c]: as if channel c were compared alone.
    std::uint64_t pixel_count = 0;     ///< width * height.

    /// Percent of pixels over the warn threshold (idiff's "N pixels (P%) over").
    double warn_percent() const;
    /// Percent of pixels over the fail threshold.
    double fail_percent() const;
};

/// Compare two images of the same width, height and channel count (throws Error otherwise).
/// Uses thresholds.fail / warn and their relative forms for the counts. The result does not
/// depend on the thread count (per-tile partial sums combined in tile order, in double).
CompareStats compare(const Image &a, const Image &b, const Thresholds &thresholds = {});

/// compare() over the surface pixels only (those whose `depth` is finite: not the sky) and the
/// first `channels` channels of both images (0: all of them). For truths that hold nothing on the
/// sky (Cycles writes AO 0 there). The images and `depth` share a width and height; a frame
/// with no surface pixel is an error.
CompareStats compare_surface(const Image &a,
                             const Image &b,
                             const Image &depth,
                             int channels = 0,
                             const Thresholds &thresholds = {});

/// idiff's outcomes, valued as its exit codes.
enum class Verdict : int {
    Pass = 0,
    Warning = 1,
    Failure = 2,
    SizeMismatch = 3,
    FileError = 4,
};

/// idiff's verdict from the statistics: nothing is reported unless more than allow_failures
/// pixels fail; then Failure when fail_count > fail_percent% of the pixels or max error >
/// hard_fail, else Warning when warn_count > warn_percent% or max error > hard_warn, else Pass.
Verdict verdict(const CompareStats &stats, const Thresholds &thresholds);

/// The process exit code for a verdict (idiff's: 0 ok, 1 warning, 2 failure, 3 size, 4 file).
inline int exit_code(Verdict v)
{
    return static_cast<int>(v);
}

/// "PASS", "WARNING", "FAILURE", "SIZE MISMATCH" or "FILE ERROR" (idiff's words).
const char *verdict_name(Verdict v);

/// The worse of two verdicts (the larger exit code).
inline Verdict worse(Verdict a, Verdict b)
{
    return static_cast<int>(a) >= static_cast<int>(b) ? a : b;
}

/// |a - b| * scale per value, same shape as the inputs, with compare's rules for non-finite
/// values: equal ones (NaN and NaN, inf and inf) 0, any other pair with one infinity.
Image difference_image(const Image &a, const Image &b, float scale = 1.0f);

}  // namespace posthaste::metrics
