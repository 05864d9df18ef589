#pragma once
// Speed-versus-error charts for `posthaste bench`: the Pareto front of a set of (time, error)
// points, both minimised, and an SVG scatter chart with labelled points, min/max time bars and
// the front marked and connected. No I/O: the caller writes the text where it wants.

#include <cstddef>
#include <string>
#include <vector>

#include "core/text.h"

namespace posthaste::bench {

/// One measured setting: x is time (its median), x_lo / x_hi its spread, y its error.
struct ChartPoint {
    std::string label;
    double x = 0.0;
    double x_lo = 0.0;
    double x_hi = 0.0;
    double y = 0.0;
};

/// Indices of the points no other point dominates (another is at most as slow and at most as
/// wrong, and strictly better in one), sorted by x then by error. Error is y, or -y when
/// `higher_y_is_better` (PSNR). A y at the best possible infinity (PSNR +inf: exact) takes part
/// and dominates as any value would; other points with a non-finite x or y are never on the
/// front and dominate nothing; identical points are all on it.
std::vector<std::size_t> pareto_front(const std::vector<ChartPoint> &points,
                                      bool higher_y_is_better = false);

struct ChartOptions {
    std::string title;
    std::string x_label = "time per frame (ms)";
    std::string y_label = "error";
    /// Log scale on y (points with y <= 0 then get the bottom decade, its tick labelled 0).
    bool log_y = false;
    /// y is a quality (PSNR) rather than an error: the front maximises it.
    bool higher_y_is_better = false;
    int width = 720;
    int height = 480;
};

/// A self-contained SVG document: axes with ticks, every point labelled, the Pareto front drawn
/// as filled red points joined by a line, the rest hollow. An infinite y is drawn on the top or
/// bottom edge, "(inf)" after its label; points with a non-finite x or a NaN y are listed under
/// the chart instead of drawn.
std::string svg_chart(const std::vector<ChartPoint> &points, const ChartOptions &options);

}  // namespace posthaste::bench
