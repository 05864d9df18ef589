#pragma once
// Regression reports a person and a CI system can read: a self-contained HTML page (thumbnails
// of reference, result, |difference| and the FLIP map through the OCIO display, per-pass metrics,
// failures and the worst cases first, a summary on top) and JUnit XML (one test case per frame
// and pass, the failure message carrying the metrics and thresholds), in the manner of Blender's
// render-test reports. Built from metrics::diff_frames results; used by `diff --report/--junit`
// and by the suite runner (`posthaste test`).

#include <set>
#include <string>
#include <vector>

#include "core/frame.h"
#include "io/image_file.h"
#include "metrics/diff.h"

namespace posthaste::metrics {

/// PNG files (bytes) of one comparison, any of them empty when it does not apply.
struct ReportImages {
    std::string reference;
    std::string result;
    std::string difference;  ///< |a - b| of the shown pass, normalised by its largest value
    float difference_scale = 1.0f;
    std::string flip;        ///< FLIP heat map
    std::string shown_pass;  ///< The pass the thumbnails show.
};

/// One compared frame (of one test in a suite).
struct ReportEntry {
    std::string test;  ///< The graph's name in a suite; "diff" for `posthaste diff`.
    int frame = 0;
    std::string a, b;  ///< Reference and result paths.
    Verdict verdict = Verdict::Pass;
    /// Per pass: name, verdict and a metrics line (mean, rms, psnr, max, failing pixels).
    struct Pass {
        std::string name;
        Verdict verdict = Verdict::Pass;
        std::string metrics;
    };
    std::vector<Pass> passes;
    std::vector<std::string> messages;  ///< Problems (missing files, mismatches, ...).
    std::string thresholds;             ///< "fail 0.004, failpercent 0.02, ..." for messages.
    double flip_mean = -1.0;            ///< < 0: none.
    double worst_rms = 0.0;             ///< Largest rms over passes (the ordering key).
    double seconds = 0.0;
    ReportImages images;
};

/// Read a frame for comparison. The reader fills channels a file lacks with constants (color
/// without alpha gets A = 1); those trailing constants are dropped again, so that stored
/// channels alone are compared, as idiff does (RGB against RGBA is then a channel mismatch).
/// `wanted` empty: every pass.
Frame read_for_comparison(const std::string &path,
                          const std::set<std::string> &wanted,
                          int frame_number,
                          const ReadOptions &options);

/// The entry of one diff_frames result (metrics and verdicts; no images).
ReportEntry report_entry(const std::string &test,
                         const DiffReport &report,
                         const std::string &a,
                         const std::string &b);

/// An entry for a frame that could not be compared (a file missing or unreadable).
ReportEntry file_error_entry(const std::string &test,
                             int frame,
                             const std::string &a,
                             const std::string &b,
                             const std::string &message);

/// Thumbnails (at most `max_width` pixels wide) of frames a and b and of the report's images
/// (diff_frames must have run with DiffOptions::images). The color pass goes through the OCIO
/// display sRGB / Standard; another pass is shown normalised by the largest |value| of a.
ReportImages report_images(const Frame &a,
                           const Frame &b,
                           const DiffReport &report,
                           int max_width = 240);

/// The HTML page: summary, then entries worst first (verdict, then rms).
std::string html_report(const std::string &title, std::vector<ReportEntry> entries);

/// JUnit XML: a <testsuite> per test, a <testcase> per frame and pass (per frame when a frame
/// could not be compared); failures and size mismatches as <failure>, file errors as <error>.
std::string junit_xml(const std::string &name, const std::vector<ReportEntry> &entries);

}  // namespace posthaste::metrics
