#include "bench/bench.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bench/bench_metrics.h"
#include "bench/chart.h"
#include "core/error.h"
#include "core/json_error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "core/timing.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "nodes/registry.h"

namespace posthaste::bench {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

// --- Spec ----------------------------------------------------------------------------------

void check_keys(const json &obj, const std::vector<std::string> &allowed, const std::string &where)
{
    for (auto it = obj.begin(); it != obj.end(); ++it) {
        if (std::find(allowed.begin(), allowed.end(), it.key()) == allowed.end()) {
            throw_usage(
                where,
                where.back() == ':' ? "/" : "",
                ": unknown key ",
                quoted(it.key()),
                did_you_mean(it.key(), allowed),
                " (expected: ",
                [&] {
                    std::string s;
                    for (const std::string &a : allowed) {
                        s += (s.empty() ? "" : ", ") + a;
                    }
                    return s;
                }(),
                ")");
        }
    }
}

std::string get_string(const json &obj, const std::string &key, const std::string &where)
{
    const json &v = obj.at(key);
    if (!v.is_string()) {
        throw_usage(where, "/", key, ": expected a string, got ", v.dump());
    }
    return v.get<std::string>();
}

std::vector<std::string> get_strings(const json &v, const std::string &where)
{
    if (!v.is_array()) {
        throw_usage(where, ": expected a list of strings, got ", v.dump());
    }
    std::vector<std::string> out;
    for (std::size_t i = 0; i < v.size(); ++i) {
        if (!v[i].is_string()) {
            throw_usage(where, "/", i, ": expected a string, got ", v[i].dump());
        }
        out.push_back(v[i].get<std::string>());
    }
    return out;
}

int get_int(const json &obj, const std::string &key, int lo, int hi, const std::string &where)
{
    // Compared as the JSON holds them (unsigned above LLONG_MAX), never truncated to int first.
    const json &v = obj.at(key);
    bool in_range = false;
    if (v.is_number_unsigned()) {
        const unsigned long long u = v.get<unsigned long long>();
        in_range =
            hi >= 0 && u <= (unsigned long long)(hi) && (lo <= 0 || u >= (unsigned long long)(lo));
    } else if (v.is_number_integer()) {
        in_range = v.get<long long>() >= lo && v.get<long long>() <= hi;
    }
    if (!in_range) {
        throw_usage(where, "/", key, ": expected an integer in ", lo, "..", hi, ", got ", v.dump());
    }
    return int(v.get<long long>());
}

std::string resolve(const std::string &path, const std::string &base_dir)
{
    if (path.empty() || fs::path(path).is_absolute() || base_dir.empty()) {
        return path;
    }
    return (fs::path(base_dir) / path).lexically_normal().string();
}

// --- Running -------------------------------------------------------------------------------

/// Channel `channel` of `image` alone (-1: the image itself).
ImagePtr select_channel(const ImagePtr &image, int channel, const std::string &where)
{
    if (channel < 0) {
        return image;
    }
    if (channel >= image->channels()) {
        throw_runtime(
            where, ": the truth has ", image->channels(), " channels, no channel ", channel);
    }
    auto out = std::make_shared<Image>(image->width(), image->height(), 1);
    for (std::size_t i = 0; i < out->pixel_count(); ++i) {
        out->data()[i] = image->data()[i * std::size_t(image->channels()) + std::size_t(channel)];
    }
    return out;
}

struct Prepared {
    std::unique_ptr<Graph> graph;
    int node = -1;
};

Prepared prepare(const std::string &path,
                 const std::string &node,
                 const std::vector<std::string> &overrides,
                 const std::string &origin)
{
    Prepared p;
    try {
        p.graph = std::make_unique<Graph>(Graph::load(path, nodes::catalog(), overrides));
    } catch (const Error &e) {
        throw Error(e.code(), origin + ": " + e.what());
    }
    p.graph->set_capture(node);
    p.node = p.graph->find(node);
    return p;
}

}  // namespace

BenchSpec parse_spec(const std::string &text,
                     const std::string &origin,
                     const std::string &base_dir)
{
    const json j = parse_json_document(text, origin);
    if (!j.is_object()) {
        throw_usage(origin, ": expected a JSON object");
    }
    const std::string w = origin + ":";
    check_keys(j,
               {"description",
                "graph",
                "node",
                "frames",
                "pass",
                "truth",
                "settings",
                "baseline",
                "metrics",
                "chart",
                "warmup",
                "runs",
                "threads",
                "diff_scale",
                "exclude"},
               w);
    BenchSpec s;
    s.origin = origin;
    for (const char *key : {"graph", "node", "truth"}) {
        if (!j.contains(key)) {
            throw_usage(w, " missing key ", quoted(key));
        }
    }
    s.graph = resolve(get_string(j, "graph", w), base_dir);
    s.node = get_string(j, "node", w);
    if (j.contains("description")) {
        s.description = get_string(j, "description", w);
    }
    if (j.contains("frames")) {
        s.frames = j["frames"].is_number() ? std::to_string(get_int(j,
                                                                    "frames",
                                                                    std::numeric_limits<int>::min(),
                                                                    std::numeric_limits<int>::max(),
                                                                    w))
                                           : get_string(j, "frames", w);
        parse_frame_list(s.frames, w + "/frames");
    }
    if (j.contains("pass")) {
        s.pass = get_string(j, "pass", w);
    }

    const json &truth = j["truth"];
    const std::string tw = w + "/truth";
    if (!truth.is_object()) {
        throw_usage(tw,
                    ": expected an object {\"pattern\": ...} or {\"graph\": ..., \"node\": ...}");
    }
    check_keys(truth, {"pattern", "graph", "node", "set", "pass", "channel"}, tw);
    if (truth.contains("pass")) {
        s.truth_pass = get_string(truth, "pass", tw);
    }
    if (truth.contains("channel")) {
        s.truth_channel = get_int(truth, "channel", 0, 63, tw);
    }
    if (j.contains("exclude")) {
        if (get_string(j, "exclude", w) != "sky") {
            throw_usage(w, "/exclude: expected \"sky\" (pixels of infinite depth)");
        }
        s.exclude_sky = true;
    }
    if (truth.contains("pattern") == truth.contains("graph")) {
        throw_usage(tw, ": give exactly one of \"pattern\" (files) or \"graph\" (a truth graph)");
    }
    if (truth.contains("pattern")) {
        if (truth.contains("node") || truth.contains("set")) {
            throw_usage(tw, ": \"node\" and \"set\" only go with \"graph\"");
        }
        s.truth_pattern = resolve(get_string(truth, "pattern", tw), base_dir);
    } else {
        s.truth_graph = resolve(get_string(truth, "graph", tw), base_dir);
        if (!truth.contains("node")) {
            throw_usage(tw, ": missing key \"node\" (the truth graph's node to capture)");
        }
        s.truth_node = get_string(truth, "node", tw);
        if (truth.contains("set")) {
            s.truth_overrides = get_strings(truth["set"], tw + "/set");
        }
    }

    if (j.contains("settings")) {
        const json &list = j["settings"];
        if (!list.is_array() || list.empty()) {
            throw_usage(w, "/settings: expected a non-empty list of {\"name\", \"set\"}");
        }
        for (std::size_t i = 0; i < list.size(); ++i) {
            const std::string sw = str_cat(w, "/settings/", i);
            if (!list[i].is_object()) {
                throw_usage(sw, ": expected an object {\"name\": ..., \"set\": [...]}");
            }
            check_keys(list[i], {"name", "set"}, sw);
            if (!list[i].contains("name")) {
                throw_usage(sw, ": missing key \"name\"");
            }
            BenchSetting setting;
            setting.name = get_string(list[i], "name", sw);
            if (setting.name.empty()) {
                throw_usage(sw, "/name: must not be empty");
            }
            for (const BenchSetting &other : s.settings) {
                if (other.name == setting.name) {
                    throw_usage(sw, "/name: duplicate setting ", quoted(setting.name));
                }
            }
            if (list[i].contains("set")) {
                setting.overrides = get_strings(list[i]["set"], sw + "/set");
            }
            s.settings.push_back(std::move(setting));
        }
    } else {
        s.settings.push_back({"default", {}});
    }
    std::vector<std::string> names;
    for (const BenchSetting &b : s.settings) {
        names.push_back(b.name);
    }
    if (j.contains("baseline")) {
        s.baseline = get_string(j, "baseline", w);
        if (std::find(names.begin(), names.end(), s.baseline) == names.end()) {
            throw_usage(w,
                        "/baseline: no setting ",
                        quoted(s.baseline),
                        did_you_mean(s.baseline, names),
                        " (have: ",
                        join(names, ", "),
                        ")");
        }
    }
    if (j.contains("metrics")) {
        for (const std::string &m : get_strings(j["metrics"], w + "/metrics")) {
            if (m == "flip") {
                s.flip = true;
            } else if (m != "rmse" && m != "psnr") {
                throw_usage(w,
                            "/metrics: unknown metric ",
                            quoted(m),
                            did_you_mean(m, {"rmse", "psnr", "flip"}),
                            " (expected rmse, psnr, flip)");
            }
        }
    }
    if (j.contains("chart")) {
        const json &c = j["chart"];
        const std::string cw = w + "/chart";
        if (!c.is_object()) {
            throw_usage(cw, ": expected an object {\"metric\": ..., \"log_y\": ...}");
        }
        check_keys(c, {"metric", "log_y"}, cw);
        if (c.contains("metric")) {
            s.chart_metric = get_string(c, "metric", cw);
            if (s.chart_metric != "rmse" && s.chart_metric != "psnr" && s.chart_metric != "flip") {
                throw_usage(
                    cw, "/metric: expected rmse, psnr or flip, got ", quoted(s.chart_metric));
            }
            s.flip = s.flip || s.chart_metric == "flip";
        }
        if (c.contains("log_y")) {
            if (!c["log_y"].is_boolean()) {
                throw_usage(cw, "/log_y: expected true or false, got ", c["log_y"].dump());
            }
            s.log_y = c["log_y"].get<bool>();
        }
    }
    if (j.contains("warmup")) {
        s.warmup = get_int(j, "warmup", 0, 1000, w);
    }
    if (j.contains("runs")) {
        s.runs = get_int(j, "runs", 1, 100000, w);
    }
    if (j.contains("threads")) {
        s.threads = get_int(j, "threads", 0, 1024, w);
    }
    if (j.contains("diff_scale")) {
        // Bounded so that it stays finite as a float (1e39 became inf: "xinf" on the page).
        if (!j["diff_scale"].is_number() || !(j["diff_scale"].get<double>() >= 0.0) ||
            !(j["diff_scale"].get<double>() <= 1e6)) {
            throw_usage(
                w, "/diff_scale: expected a number in 0..1e6, got ", j["diff_scale"].dump());
        }
        s.diff_scale = j["diff_scale"].get<float>();
    }
    if (s.flip && s.truth_channel >= 0) {
        throw_usage(w, "/metrics: flip needs RGB, but /truth/channel compares one channel");
    }
    return s;
}

BenchSpec load_spec(const std::string &path)
{
    std::error_code ec;
    if (fs::is_directory(path, ec)) {
        throw_usage(path, ": is a directory, not a bench spec file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw_usage(path, ": cannot read the bench spec");
    }
    std::stringstream ss;
    ss << in.rdbuf();
    return parse_spec(ss.str(), path, fs::path(path).parent_path().string());
}

Timing summarize(std::vector<double> runs_ms)
{
    Timing t;
    t.runs_ms = runs_ms;
    if (runs_ms.empty()) {
        t.median_ms = t.min_ms = t.max_ms = t.p10_ms = t.p90_ms = kNaN;
        return t;
    }
    std::sort(runs_ms.begin(), runs_ms.end());
    const std::size_t n = runs_ms.size();
    t.min_ms = runs_ms.front();
    t.max_ms = runs_ms.back();
    t.median_ms = n % 2 ? runs_ms[n / 2] : 0.5 * (runs_ms[n / 2 - 1] + runs_ms[n / 2]);
    auto rank = [&](double q) {
        const std::size_t r = std::size_t(std::ceil(q * double(n)));
        return runs_ms[std::clamp<std::size_t>(r, 1, n) - 1];
    };
    t.p10_ms = rank(0.10);
    t.p90_ms = rank(0.90);
    return t;
}

double chart_value(const SettingResult &r, const std::string &metric)
{
    return metric == "psnr" ? r.psnr : metric == "flip" ? r.flip : r.rmse;
}

BenchResult run_bench(const BenchSpec &spec, const std::function<void(const std::string &)> &log)
{
    auto say = [&](const std::string &line) {
        if (log) {
            log(line);
        }
    };
    set_thread_count(spec.threads);
    BenchResult result;
    result.spec = spec;
    result.threads = thread_count();

    // Load and check everything before any timing.
    std::vector<Prepared> graphs;
    for (const BenchSetting &s : spec.settings) {
        graphs.push_back(prepare(spec.graph,
                                 spec.node,
                                 s.overrides,
                                 str_cat(spec.origin, ": setting ", quoted(s.name))));
    }
    result.frames = spec.frames.empty() ? graphs.front().graph->default_frames()
                                        : parse_frame_list(spec.frames, spec.origin + ":/frames");
    for (Prepared &p : graphs) {
        p.graph->check(result.frames);
    }

    say(str_cat("truth: ",
                spec.truth_pattern.empty() ? spec.truth_graph : spec.truth_pattern,
                " (",
                result.frames.size(),
                " frame(s))"));
    std::vector<ImagePtr> truth;
    const std::string truth_pass = spec.truth_pass.empty() ? spec.pass : spec.truth_pass;
    if (!spec.truth_pattern.empty()) {
        const std::set<std::string> wanted{truth_pass};
        for (int f : result.frames) {
            const std::string path = expand_frame_pattern(spec.truth_pattern, f);
            Frame fr;
            try {
                fr = read_frame(path, &wanted, f);
            } catch (const Error &) {
                // A pass the file lacks is the spec's mistake (exit 2); a bad file, the reader's.
                const Frame all = read_frame(path, nullptr, f);
                if (all.has(truth_pass)) {
                    throw;
                }
                const std::string why = path + " has no pass " + quoted(truth_pass);
                throw_usage(spec.origin, ":/truth/pass: ", why, " (have: ", listed(all), ")");
            }
            truth.push_back(select_channel(
                display_part(fr, fr.pass(truth_pass).image), spec.truth_channel, path));
        }
    } else {
        Prepared t = prepare(
            spec.truth_graph, spec.truth_node, spec.truth_overrides, spec.origin + ": truth");
        t.graph->check(result.frames);
        for (int f : result.frames) {
            const Frame fr = t.graph->evaluate(f);
            if (!fr.has(truth_pass)) {
                // As for truth files: a pass the truth lacks is the spec's mistake (exit 2).
                throw_usage(
                    spec.origin,
                    spec.truth_pass.empty() ? ":/pass: truth node " : ":/truth/pass: truth node ",
                    quoted(spec.truth_node),
                    " gives no pass ",
                    quoted(truth_pass),
                    " (have: ",
                    listed(fr),
                    ") in frame ",
                    f);
            }
            truth.push_back(select_channel(
                display_part(fr, fr.pass(truth_pass).image), spec.truth_channel, spec.truth_graph));
        }
    }

    // One untimed evaluation of every setting before any timing: it checks what the spec asks
    // of the output (a setting may lose the pass), gives the errors and thumbnails, and is every
    // setting's first, cold, evaluation alike, so no setting is timed cold.
    const std::size_t count = spec.settings.size();
    for (std::size_t s = 0; s < count; ++s) {
        result.settings.push_back(
            measure_setting(spec, spec.settings[s], *graphs[s].graph, result.frames, truth));
    }
    say(str_cat("errors of ", count, " setting(s) measured"));
    std::vector<std::vector<double>> node_ms(count), graph_ms(count);
    const double frames = double(result.frames.size());
    for (int run = 0; run < spec.warmup + spec.runs; ++run) {
        for (std::size_t s = 0; s < count; ++s) {
            const Graph &g = *graphs[s].graph;
            NodeTimes times = g.make_times();
            const auto t0 = std::chrono::steady_clock::now();
            for (int f : result.frames) {
                g.evaluate(f, &times);
            }
            const double wall = ms_since(t0);
            if (run >= spec.warmup) {
                graph_ms[s].push_back(wall / frames);
                node_ms[s].push_back(double(*times.nanoseconds[std::size_t(graphs[s].node)]) *
                                     1e-6 / frames);
            }
        }
        if (run + 1 == spec.warmup || run + 1 == spec.warmup + spec.runs) {
            say(run < spec.warmup
                    ? str_cat(spec.warmup, " warm-up run(s) done")
                    : str_cat(spec.runs, " timed run(s) of ", count, " setting(s) done"));
        }
    }
    for (std::size_t s = 0; s < count; ++s) {
        result.settings[s].node = summarize(node_ms[s]);
        result.settings[s].graph = summarize(graph_ms[s]);
    }

    const auto base =
        std::find_if(result.settings.begin(), result.settings.end(), [&](const SettingResult &r) {
            return r.setting.name == spec.baseline;
        });
    std::vector<ChartPoint> points;
    for (SettingResult &r : result.settings) {
        if (base != result.settings.end()) {
            r.speed_ratio = base->node.median_ms / r.node.median_ms;
        }
        points.push_back({r.setting.name,
                          r.node.median_ms,
                          r.node.min_ms,
                          r.node.max_ms,
                          chart_value(r, spec.chart_metric)});
    }
    for (std::size_t i : pareto_front(points, spec.chart_metric == "psnr")) {
        result.settings[i].pareto = true;
    }
    return result;
}

}  // namespace posthaste::bench
