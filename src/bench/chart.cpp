#include "bench/chart.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <sstream>

namespace posthaste::bench {
namespace {

bool finite_point(const ChartPoint &p)
{
    return std::isfinite(p.x) && std::isfinite(p.y);
}

/// On the front's terms: finite, or at the best possible error (PSNR +inf: an exact result).
bool ranked_point(const ChartPoint &p, bool higher_y_is_better)
{
    return finite_point(p) ||
           (std::isfinite(p.x) && std::isinf(p.y) && (p.y > 0) == higher_y_is_better);
}

/// Drawn: a finite time and a y that is not NaN (an infinite y goes on the top or bottom edge).
bool drawn_point(const ChartPoint &p)
{
    return std::isfinite(p.x) && !std::isnan(p.y);
}

std::string num(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f", v);
    return buf;
}

std::string tick_label(double v)
{
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.3g", v);
    return buf;
}

/// A 1-2-5 step giving about `count` intervals over [lo, hi].
double nice_step(double lo, double hi, int count)
{
    const double raw = (hi - lo) / count;
    const double mag = std::pow(10.0, std::floor(std::log10(raw)));
    const double f = raw / mag;
    return mag * (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0);
}

struct Axis {
    double lo = 0.0, hi = 1.0;
    bool log = false;
    /// Log scale with values <= 0: the bottom decade is theirs, its tick labelled 0.
    bool zero_row = false;
    std::vector<double> ticks;

    /// Position in [0, 1] along the axis.
    double unit(double v) const
    {
        if (log) {
            v = std::max(v, lo);
            return (std::log10(v) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
        }
        return (v - lo) / (hi - lo);
    }
};

Axis linear_axis(double lo, double hi)
{
    if (!(hi > lo)) {
        const double pad = lo == 0.0 ? 1.0 : std::fabs(lo) * 0.1;
        lo -= pad;
        hi += pad;
    }
    const double step = nice_step(lo, hi, 5);
    Axis a;
    a.lo = std::floor(lo / step) * step;
    a.hi = std::ceil(hi / step) * step;
    for (double t = a.lo; t <= a.hi + step * 0.5; t += step) {
        a.ticks.push_back(std::fabs(t) < step * 1e-9 ? 0.0 : t);
    }
    return a;
}

Axis log_axis(double lo, double hi, bool zero_row)
{
    Axis a;
    a.log = true;
    a.zero_row = zero_row;
    a.lo = std::pow(10.0, std::floor(std::log10(lo)) - (zero_row ? 1.0 : 0.0));
    a.hi = std::pow(10.0, std::ceil(std::log10(hi)));
    if (!(a.hi > a.lo)) {
        a.hi = a.lo * 10.0;
    }
    for (double t = a.lo; t <= a.hi * 1.001; t *= 10.0) {
        a.ticks.push_back(t);
    }
    return a;
}

}  // namespace

std::vector<std::size_t> pareto_front(const std::vector<ChartPoint> &points,
                                      bool higher_y_is_better)
{
    const double sign = higher_y_is_better ? -1.0 : 1.0;
    std::vector<std::size_t> front;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const ChartPoint &p = points[i];
        if (!ranked_point(p, higher_y_is_better)) {
            continue;
        }
        bool dominated = false;
        for (std::size_t j = 0; j < points.size() && !dominated; ++j) {
            const ChartPoint &q = points[j];
            dominated = j != i && ranked_point(q, higher_y_is_better) && q.x <= p.x &&
                        sign * q.y <= sign * p.y && (q.x < p.x || sign * q.y < sign * p.y);
        }
        if (!dominated) {
            front.push_back(i);
        }
    }
    std::sort(front.begin(), front.end(), [&](std::size_t a, std::size_t b) {
        return points[a].x != points[b].x ? points[a].x < points[b].x
                                          : sign * points[a].y < sign * points[b].y;
    });
    return front;
}

std::string svg_chart(const std::vector<ChartPoint> &points, const ChartOptions &o)
{
    const double left = 80, right = 30, top = 40, bottom = 60;
    const double pw = o.width - left - right, ph = o.height - top - bottom;

    double xmin = std::numeric_limits<double>::infinity(), xmax = -xmin;
    double ymin = xmin, ymax = -xmin, ypos_min = xmin;
    bool any_y = false, nonpositive = false, inf_top = false, inf_bottom = false;
    std::vector<std::string> undrawn;
    for (const ChartPoint &p : points) {
        if (!drawn_point(p)) {
            undrawn.push_back(p.label);
            continue;
        }
        const double lo = std::isfinite(p.x_lo) ? std::min(p.x_lo, p.x) : p.x;
        const double hi = std::isfinite(p.x_hi) ? std::max(p.x_hi, p.x) : p.x;
        xmin = std::min(xmin, lo);
        xmax = std::max(xmax, hi);
        if (!std::isfinite(p.y)) {
            inf_top = inf_top || p.y > 0;
            inf_bottom = inf_bottom || p.y < 0;
            continue;
        }
        any_y = true;
        nonpositive = nonpositive || p.y <= 0.0;
        ymin = std::min(ymin, p.y);
        ymax = std::max(ymax, p.y);
        if (p.y > 0.0) {
            ypos_min = std::min(ypos_min, p.y);
        }
    }
    const bool any = std::isfinite(xmin);
    const Axis ax = linear_axis(any ? std::min(0.0, xmin) : 0.0, any ? xmax : 1.0);
    const bool log_y = o.log_y && std::isfinite(ypos_min);
    const Axis ay = log_y ? log_axis(ypos_min, std::max(ymax, ypos_min), nonpositive)
                          : linear_axis(any_y ? std::min(0.0, ymin) : 0.0, any_y ? ymax : 1.0);
    auto px = [&](double x) { return left + pw * ax.unit(x); };
    // An infinite y (PSNR of an exact result) on the edge it points to, in a band of its own
    // so that it stands apart from the largest finite value.
    const double band = 24.0;
    const double y_top = top + (inf_top ? band : 0.0),
                 y_bottom = top + ph - (inf_bottom ? band : 0.0);
    auto py = [&](double y) {
        return std::isinf(y) ? (y > 0 ? top : top + ph)
                             : y_top + (y_bottom - y_top) * (1.0 - ay.unit(y));
    };
    auto y_text = [&](double y) {
        return ay.zero_row && y <= 0.0 ? std::string("0") : tick_label(y);
    };

    std::ostringstream s;
    s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << o.width << "\" height=\""
      << o.height + 16 * int(undrawn.size() ? 1 : 0) << "\" font-family=\"sans-serif\" "
      << "font-size=\"12\">\n";
    s << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    s << "<text x=\"" << num(o.width / 2.0) << "\" y=\"22\" text-anchor=\"middle\" "
      << "font-size=\"15\">" << xml_escape(o.title) << "</text>\n";
    // Grid and ticks.
    for (double t : ax.ticks) {
        const std::string x = num(px(t));
        s << "<line x1=\"" << x << "\" y1=\"" << num(top) << "\" x2=\"" << x << "\" y2=\""
          << num(top + ph) << "\" stroke=\"#ddd\"/>\n";
        s << "<text x=\"" << x << "\" y=\"" << num(top + ph + 16) << "\" text-anchor=\"middle\">"
          << tick_label(t) << "</text>\n";
    }
    for (double t : ay.ticks) {
        const std::string y = num(py(t));
        s << "<line x1=\"" << num(left) << "\" y1=\"" << y << "\" x2=\"" << num(left + pw)
          << "\" y2=\"" << y << "\" stroke=\"#ddd\"/>\n";
        s << "<text x=\"" << num(left - 6) << "\" y=\"" << y
          << "\" text-anchor=\"end\" dominant-baseline=\"middle\">"
          << (ay.zero_row && t == ay.ticks.front() ? "0" : tick_label(t)) << "</text>\n";
    }
    for (const double edge : {inf_top ? top : -1.0, inf_bottom ? top + ph : -1.0}) {
        if (edge >= 0.0) {
            s << "<text x=\"" << num(left - 6) << "\" y=\"" << num(edge)
              << "\" text-anchor=\"end\" dominant-baseline=\"middle\">"
              << (edge == top ? "inf" : "-inf") << "</text>\n";
        }
    }
    s << "<rect x=\"" << num(left) << "\" y=\"" << num(top) << "\" width=\"" << num(pw)
      << "\" height=\"" << num(ph) << "\" fill=\"none\" stroke=\"black\"/>\n";
    s << "<text x=\"" << num(left + pw / 2) << "\" y=\"" << num(o.height - 14)
      << "\" text-anchor=\"middle\">" << xml_escape(o.x_label) << "</text>\n";
    s << "<text transform=\"translate(18," << num(top + ph / 2) << ") rotate(-90)\" "
      << "text-anchor=\"middle\">" << xml_escape(o.y_label) << (log_y ? " (log scale)" : "")
      << "</text>\n";

    // The Pareto front, joined in time order.
    const std::vector<std::size_t> front = pareto_front(points, o.higher_y_is_better);
    std::vector<bool> on_front(points.size(), false);
    if (!front.empty()) {
        s << "<polyline class=\"pareto\" fill=\"none\" stroke=\"#d62728\" stroke-width=\"1.5\" "
          << "points=\"";
        for (std::size_t k = 0; k < front.size(); ++k) {
            on_front[front[k]] = true;
            s << (k ? " " : "") << num(px(points[front[k]].x)) << ","
              << num(py(points[front[k]].y));
        }
        s << "\"/>\n";
    }
    for (std::size_t i = 0; i < points.size(); ++i) {
        const ChartPoint &p = points[i];
        if (!drawn_point(p)) {
            continue;
        }
        const std::string x = num(px(p.x)), y = num(py(p.y));
        if (std::isfinite(p.x_lo) && std::isfinite(p.x_hi) && p.x_hi > p.x_lo) {
            s << "<line x1=\"" << num(px(p.x_lo)) << "\" y1=\"" << y << "\" x2=\""
              << num(px(p.x_hi)) << "\" y2=\"" << y << "\" stroke=\"#888\"/>\n";
        }
        s << "<circle class=\"" << (on_front[i] ? "point pareto" : "point") << "\" cx=\"" << x
          << "\" cy=\"" << y << "\" r=\"4.5\" "
          << (on_front[i] ? "fill=\"#d62728\" stroke=\"#d62728\""
                          : "fill=\"white\" stroke=\"#1f77b4\" stroke-width=\"1.5\"")
          << "><title>" << xml_escape(p.label) << ": " << tick_label(p.x) << " ms, " << y_text(p.y)
          << "</title></circle>\n";
        // Off the scale (inf) or below a log scale (0): said beside the label.
        const bool edge = !std::isfinite(p.y) || (ay.zero_row && p.y <= 0.0);
        s << "<text x=\"" << num(px(p.x) + 7) << "\" y=\""
          << num(py(p.y) + (py(p.y) <= top ? 14 : -7)) << "\">" << xml_escape(p.label)
          << (edge ? " (" + y_text(p.y) + ")" : "") << "</text>\n";
    }
    if (!undrawn.empty()) {
        std::string names;
        for (const std::string &n : undrawn) {
            names += (names.empty() ? "" : ", ") + n;
        }
        s << "<text x=\"" << num(left) << "\" y=\"" << o.height + 6
          << "\">not drawn (non-finite): " << xml_escape(names) << "</text>\n";
    }
    s << "</svg>\n";
    return s.str();
}

}  // namespace posthaste::bench
