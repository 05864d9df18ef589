#pragma once
// diff_frames: the comparison behind `posthaste diff`. Compares the passes two frames share (or
// a chosen list) with idiff's statistics and verdict per pass, optionally runs FLIP on the color
// pass, and returns difference and FLIP images plus a JSON report and a one-line summary. No
// file I/O: the CLI reads the frames and writes what it wants of the report.
//
// Frame a is the reference (FLIP's reference image), b the test. Verdict rules, worst wins:
//   - frames of different width or height: SizeMismatch (3), nothing compared;
//   - a requested pass (DiffOptions::passes) missing from either frame: FileError (4);
//   - a pass whose channel counts differ: SizeMismatch (3) for that pass;
//   - a pass present in only one frame (when comparing all passes), or with the same number of
//     channels under different names (compared by position): at least Warning (1);
//   - otherwise each pass's idiff verdict over its channels (metrics::verdict).
// FLIP is reported, never part of the verdict.

#include <optional>
#include <string>
#include <vector>

#include "core/frame.h"
#include "core/image.h"
#include "metrics/flip.h"
#include "metrics/metrics.h"

namespace posthaste::metrics {

enum class FlipMode {
    Off,
    Hdr,  ///< Scene-linear input (the canonical color pass): HDR-FLIP.
    Ldr,  ///< Display-encoded sRGB input in [0, 1]: LDR-FLIP.
};

struct DiffOptions {
    Thresholds thresholds;
    /// Passes to compare; empty: every pass present in both frames.
    std::vector<std::string> passes;
    FlipMode flip = FlipMode::Hdr;
    /// The pass FLIP runs on (its first three channels, as RGB).
    std::string flip_pass = "color";
    float pixels_per_degree = kDefaultPixelsPerDegree;
    /// Make the difference and FLIP images (skip them for statistics only).
    bool images = true;
    /// Difference images hold |a - b| * difference_scale (idiff -abs -scale).
    float difference_scale = 1.0f;
};

struct PassDiff {
    std::string name;
    std::vector<std::string> channels;  ///< Channel names of frame a's pass.
    bool compared = false;
    CompareStats stats;  ///< Valid when compared.
    Verdict verdict = Verdict::Pass;
    std::string note;  ///< Why not compared, or what else is off; may be empty.
    Image difference;  ///< Empty unless compared and DiffOptions::images.
};

struct FlipDiff {
    std::string pass;
    bool hdr = true;
    float pixels_per_degree = kDefaultPixelsPerDegree;
    FlipResult result;  ///< result.error_map: 1 channel in [0, 1] (empty unless images).
    Image heatmap;      ///< error_map through flip_color_map, linear RGB (empty unless images).
};

struct DiffReport {
    int frame = 0;  ///< Frame a's number.
    int width = 0, height = 0;
    Thresholds thresholds;
    std::vector<PassDiff> passes;  ///< In name order.
    std::vector<std::string> only_in_a;
    std::vector<std::string> only_in_b;
    std::vector<std::string> messages;  ///< Every problem, one printable line each.
    std::optional<FlipDiff> flip;
    Verdict verdict = Verdict::Pass;

    int exit_code() const { return metrics::exit_code(verdict); }
};

/// Compare frame b (test) against frame a (reference). Throws Error only for invalid options
/// (a negative difference_scale or pixels_per_degree <= 0); data problems go into the report.
DiffReport diff_frames(const Frame &a, const Frame &b, const DiffOptions &options = {});

/// The report as a JSON object (snake_case keys; non-finite numbers as "inf", "-inf", "nan").
std::string to_json(const DiffReport &report);

/// One line for a terminal: frame, verdict, and per pass mean / rms / psnr / max (@ x, y,
/// channel) / failing pixels, then FLIP and problems.
std::string summary_line(const DiffReport &report);

}  // namespace posthaste::metrics
