// The bench's reports (bench.h): results.csv, the speed-accuracy chart (chart.h) as SVG, the
// HTML page with thumbnails, and writing them atomically into the output folder.

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench/bench.h"
#include "bench/bench_metrics.h"
#include "bench/chart.h"
#include "core/error.h"
#include "core/text.h"
#include "io/image_file.h"

namespace posthaste::bench {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

std::string number_text(double v)
{
    if (std::isnan(v)) {
        return "nan";
    }
    if (std::isinf(v)) {
        return v > 0 ? "inf" : "-inf";
    }
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.6g", v);
    return buf;
}

std::string csv_field(const std::string &s)
{
    if (s.find_first_of(",\"\n") == std::string::npos) {
        return s;
    }
    std::string out = "\"";
    for (char c : s) {
        out += c == '"' ? std::string("\"\"") : std::string(1, c);
    }
    return out + "\"";
}

json json_number(double v)
{
    return std::isfinite(v) ? json(v) : json(number_text(v));
}

}  // namespace

std::string results_csv(const BenchResult &result)
{
    std::ostringstream os;
    os << "setting,node_median_ms,node_p10_ms,node_p90_ms,node_min_ms,node_max_ms,"
          "graph_median_ms,graph_min_ms,graph_max_ms,speed_ratio,rmse,psnr,flip,pareto,runs,"
          "threads,frames,overrides\n";
    for (const SettingResult &r : result.settings) {
        os << csv_field(r.setting.name);
        for (double v : {r.node.median_ms,
                         r.node.p10_ms,
                         r.node.p90_ms,
                         r.node.min_ms,
                         r.node.max_ms,
                         r.graph.median_ms,
                         r.graph.min_ms,
                         r.graph.max_ms}) {
            os << "," << number_text(v);
        }
        os << "," << (std::isnan(r.speed_ratio) ? "" : number_text(r.speed_ratio));
        os << "," << number_text(r.rmse) << "," << number_text(r.psnr) << ","
           << (std::isnan(r.flip) ? "" : number_text(r.flip));
        os << "," << (r.pareto ? 1 : 0) << "," << r.node.runs_ms.size() << "," << result.threads
           << "," << result.frames.size() << "," << csv_field(join(r.setting.overrides, " "))
           << "\n";
    }
    return os.str();
}

std::string results_svg(const BenchResult &result)
{
    const BenchSpec &spec = result.spec;
    std::vector<ChartPoint> points;
    for (const SettingResult &r : result.settings) {
        points.push_back({r.setting.name,
                          r.node.median_ms,
                          r.node.min_ms,
                          r.node.max_ms,
                          chart_value(r, spec.chart_metric)});
    }
    ChartOptions o;
    o.title = str_cat(spec.node,
                      ": ",
                      spec.chart_metric,
                      " vs time (",
                      result.frames.size(),
                      " frame(s), ",
                      result.threads,
                      " thread(s), median of ",
                      spec.runs,
                      ")");
    o.x_label = str_cat("node \"", spec.node, "\" time per frame (ms; bar: min..max)");
    o.y_label = spec.chart_metric == "psnr"   ? "PSNR (dB, higher is better)"
                : spec.chart_metric == "flip" ? "mean FLIP"
                                              : "RMSE vs truth";
    o.log_y = spec.log_y && spec.chart_metric != "psnr";
    o.higher_y_is_better = spec.chart_metric == "psnr";
    return svg_chart(points, o);
}

std::string results_html(const BenchResult &result)
{
    const BenchSpec &spec = result.spec;
    std::ostringstream os;
    os << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>posthaste bench: "
       << xml_escape(spec.origin) << "</title>\n<style>body{font-family:sans-serif;margin:2em}"
       << "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:4px 8px;"
       << "text-align:right}td:first-child{text-align:left}.pareto{background:#fde}"
       << "img{image-rendering:pixelated;width:160px}</style></head><body>\n";
    os << "<h1>" << xml_escape(spec.origin) << "</h1>\n";
    if (!spec.description.empty()) {
        os << "<p>" << xml_escape(spec.description) << "</p>\n";
    }
    os << "<p>graph <code>" << xml_escape(spec.graph) << "</code>, node <code>"
       << xml_escape(spec.node) << "</code>, pass <code>" << xml_escape(spec.pass)
       << "</code>, truth <code>"
       << xml_escape(spec.truth_pattern.empty()
                         ? spec.truth_graph + " (node " + spec.truth_node + ")"
                         : spec.truth_pattern)
       << "</code>; " << result.frames.size() << " frame(s), " << spec.warmup << " warm-up, "
       << spec.runs << " timed run(s), " << result.threads << " thread(s).</p>\n";
    os << results_svg(result);
    os << "<table>\n<tr><th>setting</th><th>node median ms</th><th>min..max ms</th>"
       << "<th>graph median ms</th><th>speed ratio</th><th>RMSE</th><th>PSNR</th><th>FLIP</th>"
       << "<th>output</th><th>|output - truth| x" << number_text(spec.diff_scale) << "</th></tr>\n";
    for (std::size_t i = 0; i < result.settings.size(); ++i) {
        const SettingResult &r = result.settings[i];
        os << "<tr" << (r.pareto ? " class=\"pareto\"" : "") << "><td>"
           << xml_escape(r.setting.name) << (r.setting.name == spec.baseline ? " (baseline)" : "")
           << "<br><small>" << xml_escape(join(r.setting.overrides, " ")) << "</small></td><td>"
           << number_text(r.node.median_ms) << "</td><td>" << number_text(r.node.min_ms) << ".."
           << number_text(r.node.max_ms) << "</td><td>" << number_text(r.graph.median_ms)
           << "</td><td>" << (std::isnan(r.speed_ratio) ? "" : number_text(r.speed_ratio))
           << "</td><td>" << number_text(r.rmse) << "</td><td>" << number_text(r.psnr)
           << "</td><td>" << (std::isnan(r.flip) ? "" : number_text(r.flip)) << "</td>"
           << "<td><img src=\"thumbs/" << i << ".png\" alt=\"output\"></td>"
           << "<td><img src=\"thumbs/" << i << "_diff.png\" alt=\"difference\"></td></tr>\n";
    }
    os << "</table>\n<p>Pareto-optimal settings (no other setting is both faster and more "
       << "accurate) are highlighted and joined in red on the chart.</p>\n</body></html>\n";
    return os.str();
}

void write_results(const BenchResult &result,
                   const std::string &dir,
                   const std::vector<std::pair<std::string, std::string>> &extra)
{
    // Every text is made first (invalid UTF-8, e.g. from a spec path, becomes U+FFFD, as the
    // pages and JSON declare UTF-8), then every file is staged beside its destination and only
    // then renamed into place: a failure leaves none of the outputs half-written.
    json j = {{"spec", result.spec.origin},
              {"node", result.spec.node},
              {"frames", result.frames},
              {"threads", result.threads},
              {"baseline", result.spec.baseline}};
    json settings = json::array();
    for (const SettingResult &r : result.settings) {
        settings.push_back({{"name", r.setting.name},
                            {"set", r.setting.overrides},
                            {"node_ms", r.node.runs_ms},
                            {"graph_ms", r.graph.runs_ms},
                            {"node_median_ms", json_number(r.node.median_ms)},
                            {"graph_median_ms", json_number(r.graph.median_ms)},
                            {"speed_ratio", json_number(r.speed_ratio)},
                            {"rmse", json_number(r.rmse)},
                            {"psnr", json_number(r.psnr)},
                            {"flip", json_number(r.flip)},
                            {"pareto", r.pareto}});
    }
    j["settings"] = settings;
    std::vector<std::pair<std::string, std::string>> texts = {
        {"results.csv", valid_utf8(results_csv(result))},
        {"chart.svg", valid_utf8(results_svg(result))},
        {"index.html", valid_utf8(results_html(result))},
        {"results.json", j.dump(2, ' ', false, json::error_handler_t::replace) + "\n"}};
    for (const auto &[name, text] : extra) {
        texts.emplace_back(name, valid_utf8(text));
    }

    const fs::path d(dir);
    std::error_code ec;
    fs::create_directories(d / "thumbs", ec);
    if (ec) {
        throw_runtime((d / "thumbs").string(), ": cannot create the output folder: ", ec.message());
    }
    std::vector<std::pair<fs::path, fs::path>> staged;  // (staged, final)
    auto unstage = [&] {
        for (const auto &[tmp, final_path] : staged) {
            fs::remove(tmp, ec);
        }
    };
    try {
        for (const auto &[name, text] : texts) {
            const fs::path final_path = d / name;
            staged.emplace_back(d / ("." + name + ".part"), final_path);
            write_text_file(staged.back().first.string(), text);
        }
        for (std::size_t i = 0; i < result.settings.size(); ++i) {
            const SettingResult &r = result.settings[i];
            for (const auto &[suffix, image] :
                 {std::pair<std::string, const Image *>{"", &r.thumbnail},
                  std::pair<std::string, const Image *>{"_diff", &r.difference}}) {
                const std::string name = std::to_string(i) + suffix + ".png";
                staged.emplace_back(d / "thumbs" / (".part_" + name), d / "thumbs" / name);
                write_preview(*image, staged.back().first.string(), false);
            }
        }
        for (const auto &[tmp, final_path] : staged) {
            if (fs::is_directory(final_path, ec)) {
                throw_runtime(final_path.string(),
                              ": is a directory; cannot write the bench output");
            }
        }
    } catch (...) {
        unstage();
        throw;
    }
    for (const auto &[tmp, final_path] : staged) {
        fs::rename(tmp, final_path, ec);
        if (ec) {
            const std::string why = ec.message();
            unstage();
            throw_runtime(final_path.string(), ": cannot write the bench output: ", why);
        }
    }
}

}  // namespace posthaste::bench
