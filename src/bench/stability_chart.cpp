#include "bench/stability_chart.h"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "bench/chart.h"
#include "core/error.h"
#include "core/json_error.h"

namespace posthaste::bench {
namespace {

struct Case {
    std::string row;  ///< "node / params"
    std::string frame;
    std::string status;
    std::string tooltip;
};

std::vector<Case> parse_cases(const std::string &text, const std::string &origin)
{
    const nlohmann::json j = parse_json_document(text, origin);
    if (!j.is_object() || !j.contains("cases") || !j["cases"].is_array()) {
        throw_usage(origin, ": expected a stability record {\"cases\": [...]}");
    }
    std::vector<Case> cases;
    for (std::size_t i = 0; i < j["cases"].size(); ++i) {
        const nlohmann::json &c = j["cases"][i];
        if (!c.is_object()) {
            throw_usage(origin, ":/cases: expected objects");
        }
        // A field of another type is named with the file, not left to json's type_error.
        auto text = [&](const char *key, const char *missing) {
            if (!c.contains(key)) {
                return std::string(missing);
            }
            if (!c[key].is_string()) {
                throw_usage(
                    origin, ":/cases/", i, "/", key, ": expected a string, got ", c[key].dump());
            }
            return c[key].get<std::string>();
        };
        Case k;
        k.row = text("node", "?") + " / " + text("params", "?");
        k.frame = text("frame", "?");
        k.status = text("status", "?");
        std::ostringstream t;
        t << k.row << " on " << k.frame << ": " << k.status;
        if (c.contains("max_abs")) {
            t << "; max |v| " << c["max_abs"].dump();
        }
        if (c.contains("spread")) {
            t << "; spread " << c["spread"].dump();
        }
        if (c.contains("ms")) {
            t << "; " << c["ms"].dump() << " ms";
        }
        const std::string message = text("message", "");
        if (!message.empty()) {
            t << "; " << message;
        }
        k.tooltip = t.str();
        cases.push_back(std::move(k));
    }
    return cases;
}

const char *status_color(const std::string &status)
{
    return status == "ok"              ? "#2ca02c"
           : status == "rejected"      ? "#9ecae1"
           : status == "known_failure" ? "#ffbb78"
           : status == "unstable"      ? "#d62728"
                                       : "#7f0000";
}

template <typename T>
void add_unique(std::vector<T> &list, const T &v)
{
    if (std::find(list.begin(), list.end(), v) == list.end()) {
        list.push_back(v);
    }
}

}  // namespace

std::string stability_svg(const std::string &json_text, const std::string &origin)
{
    const std::vector<Case> cases = parse_cases(json_text, origin);
    std::vector<std::string> rows, cols;
    for (const Case &c : cases) {
        add_unique(rows, c.row);
        add_unique(cols, c.frame);
    }
    const int cell = 22, left = 260, top = 120, legend = 40;
    const int width = left + cell * int(cols.size()) + 20;
    const int height = top + cell * int(rows.size()) + legend;
    std::ostringstream s;
    s << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << width << "\" height=\"" << height
      << "\" font-family=\"sans-serif\" font-size=\"11\">\n"
      << "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n";
    for (std::size_t c = 0; c < cols.size(); ++c) {
        s << "<text transform=\"translate(" << left + cell * int(c) + cell / 2 + 4 << "," << top - 6
          << ") rotate(-60)\">" << xml_escape(cols[c]) << "</text>\n";
    }
    for (std::size_t r = 0; r < rows.size(); ++r) {
        s << "<text x=\"" << left - 6 << "\" y=\"" << top + cell * int(r) + cell / 2 + 4
          << "\" text-anchor=\"end\">" << xml_escape(rows[r]) << "</text>\n";
    }
    for (const Case &k : cases) {
        const auto r = std::find(rows.begin(), rows.end(), k.row) - rows.begin();
        const auto c = std::find(cols.begin(), cols.end(), k.frame) - cols.begin();
        s << "<rect class=\"" << xml_escape(k.status) << "\" x=\"" << left + cell * int(c)
          << "\" y=\"" << top + cell * int(r) << "\" width=\"" << cell - 2 << "\" height=\""
          << cell - 2 << "\" fill=\"" << status_color(k.status) << "\"><title>"
          << xml_escape(k.tooltip) << "</title></rect>\n";
    }
    int x = 10;
    const int y = top + cell * int(rows.size()) + 20;
    for (const char *status : {"ok", "rejected", "known_failure", "unstable", "crashed"}) {
        s << "<rect x=\"" << x << "\" y=\"" << y - 10 << "\" width=\"12\" height=\"12\" fill=\""
          << status_color(status) << "\"/><text x=\"" << x + 16 << "\" y=\"" << y << "\">" << status
          << "</text>\n";
        x += 110;
    }
    s << "</svg>\n";
    return s.str();
}

std::string stability_html(const std::string &json_text, const std::string &origin)
{
    const std::vector<Case> cases = parse_cases(json_text, origin);
    std::ostringstream os;
    os << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>posthaste stability: "
       << xml_escape(origin) << "</title><style>body{font-family:sans-serif;margin:2em}"
       << "td,th{border:1px solid #ccc;padding:4px 8px}table{border-collapse:collapse}</style>"
       << "</head><body>\n<h1>Stability: " << xml_escape(origin) << "</h1>\n"
       << stability_svg(json_text, origin);
    std::map<std::string, int> counts;
    for (const Case &k : cases) {
        ++counts[k.status];
    }
    os << "<p>" << cases.size() << " case(s):";
    for (const auto &[status, n] : counts) {
        os << " " << n << " " << xml_escape(status) << ";";
    }
    os << "</p>\n<table><tr><th>case</th><th>details</th></tr>\n";
    for (const Case &k : cases) {
        if (k.status != "ok") {
            os << "<tr><td>" << xml_escape(k.row + " on " + k.frame) << "</td><td>"
               << xml_escape(k.tooltip) << "</td></tr>\n";
        }
    }
    os << "</table>\n</body></html>\n";
    return os.str();
}

}  // namespace posthaste::bench
