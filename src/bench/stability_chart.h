#pragma once
// Charts of the stability suite's record (tests/stability, stability.json): a grid with one row
// per node and parameter set and one column per hostile frame, each cell colored by its status
// (ok, rejected, known failure, unstable, crashed) with the details in a tooltip.

#include <string>

namespace posthaste::bench {

/// The grid as an SVG document, from the text of stability.json. Throws a usage Error naming
/// `origin` when the JSON is not a stability record.
std::string stability_svg(const std::string &json_text, const std::string &origin);

/// An HTML page: the grid, then a table of every case that is not "ok".
std::string stability_html(const std::string &json_text, const std::string &origin);

}  // namespace posthaste::bench
