#pragma once
// `posthaste bench`: time one node of a graph over a sweep of settings and measure its error
// against a ground truth, then write a CSV, an SVG chart of error against time with the Pareto
// front, and an HTML page with thumbnails.
//
// Spec file (JSON; unknown keys are errors; paths are relative to the spec file):
//   { "graph": "merge.json",          the graph to time
//     "node": "merge",                the node whose output is measured (and timed)
//     "frames": "1-2",                optional; default: the graph's default frames
//     "pass": "color",                optional; the pass compared with the truth
//     "truth": {"pattern": "truth.####.exr"}                      files on disk, or
//              {"graph": "truth.json", "node": "out", "set": [...]}  another graph's output;
//              either with "pass": "ViewLayer.AO" (the truth's pass, default the same) and
//              "channel": 0 (one channel of it: Cycles writes its AO pass as grey RGB)
//     "exclude": "sky",               optional; leave out pixels whose depth (in the measured
//                                     node's output) is infinite: a renderer's AO pass is 0 there
//     "settings": [ {"name": "fast", "set": ["merge.mix=0.5"]}, ... ],   optional sweep
//     "baseline": "fast",             optional; speed ratios are against this setting
//     "metrics": ["rmse", "psnr", "flip"],   optional; default rmse and psnr
//     "chart": {"metric": "rmse", "log_y": true},  optional
//     "warmup": 1, "runs": 5, "threads": 0,  optional (threads 0: all cores)
//     "diff_scale": 16,               optional; thumbnails of |output - truth| are scaled so
//     "description": "..." }          optional; shown on the HTML page

#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "core/image.h"

namespace posthaste::bench {

struct BenchSetting {
    std::string name;
    std::vector<std::string> overrides;  ///< "node.param=value", as `run --set`.
};

struct BenchSpec {
    std::string origin;  ///< The spec file, for messages.
    std::string description;
    std::string graph;  ///< Resolved path.
    std::string node;
    std::string frames;  ///< Empty: the graph's default frames.
    std::string pass = "color";
    std::string truth_pass;     ///< The truth's pass; empty: the same as `pass`.
    int truth_channel = -1;     ///< One channel of the truth's pass (-1: all of them).
    bool exclude_sky = false;   ///< Leave pixels of infinite depth out of the error.
    std::string truth_pattern;  ///< Resolved; empty when the truth is a graph.
    std::string truth_graph;    ///< Resolved; empty when the truth is files.
    std::string truth_node;
    std::vector<std::string> truth_overrides;
    std::vector<BenchSetting> settings;  ///< At least one ("default" when the spec has none).
    std::string baseline;                ///< A setting name, or empty.
    bool flip = false;                   ///< Also report mean HDR-FLIP.
    std::string chart_metric = "rmse";   ///< rmse, psnr or flip.
    bool log_y = true;
    int warmup = 1;
    int runs = 5;
    int threads = 0;
    float diff_scale = 16.0f;
};

/// Read and validate a spec file. Throws a usage Error naming the file and JSON path.
BenchSpec load_spec(const std::string &path);
/// As load_spec, from text; relative paths resolve against `base_dir`.
BenchSpec parse_spec(const std::string &text,
                     const std::string &origin,
                     const std::string &base_dir);

/// Median, min, max, and 10th / 90th percentiles (nearest rank) of a set of times.
struct Timing {
    std::vector<double> runs_ms;
    double median_ms = 0.0, min_ms = 0.0, max_ms = 0.0, p10_ms = 0.0, p90_ms = 0.0;
};
/// Summarise per-run times (the median of an even count is the mean of the middle two).
Timing summarize(std::vector<double> runs_ms);

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct SettingResult {
    BenchSetting setting;
    Timing node;                ///< The measured node's time per frame, per run.
    Timing graph;               ///< Whole-graph time per frame, per run.
    double rmse = kNaN;         ///< Mean over frames of the RMS error over the pass's channels.
    double psnr = kNaN;         ///< Mean over frames of the PSNR (peak max(1, |value|), as idiff).
    double flip = kNaN;         ///< Mean over frames of mean HDR-FLIP on RGB; NaN when not asked.
    double speed_ratio = kNaN;  ///< Baseline median node time / this one (> 1: faster).
    bool pareto = false;        ///< On the front of (node median time, chart metric).
    Image thumbnail;            ///< First frame's pass, display-encoded RGB, small.
    Image difference;           ///< |output - truth| * diff_scale, display-encoded, small.
};

struct BenchResult {
    BenchSpec spec;
    std::vector<int> frames;
    int threads = 0;  ///< The thread count in force.
    std::vector<SettingResult> settings;
};

/// Run the sweep: every setting's graph is loaded and checked first, the truth computed once,
/// then every setting evaluated once, untimed, over every frame (its errors and the checks of
/// its output, alike for all before any timing), then warm-up and timed runs go round-robin
/// over the settings (so drift affects them alike), each run evaluating every frame in order.
/// `log` receives progress lines (may be empty).
BenchResult run_bench(const BenchSpec &spec,
                      const std::function<void(const std::string &)> &log = {});

/// The value of the chart metric for a setting.
double chart_value(const SettingResult &r, const std::string &metric);

/// CSV: one header line, one line per setting (setting, node and graph median/p10/p90/min/max
/// ms, speed_ratio, rmse, psnr, flip, pareto, overrides). Non-finite numbers as nan / inf.
std::string results_csv(const BenchResult &result);
/// The SVG chart of the chart metric against node median time.
std::string results_svg(const BenchResult &result);
/// The HTML page: the chart inline, a table, and per setting `thumbs/<i>.png` and
/// `thumbs/<i>_diff.png`.
std::string results_html(const BenchResult &result);

/// Write results.csv, chart.svg, index.html, results.json and thumbs/ under `dir` (created),
/// with `extra` (file name, text) beside them: all staged first, then renamed into place, so a
/// failure leaves none of them half-written. Text is made valid UTF-8 (U+FFFD for bad bytes).
void write_results(const BenchResult &result,
                   const std::string &dir,
                   const std::vector<std::pair<std::string, std::string>> &extra = {});

}  // namespace posthaste::bench
