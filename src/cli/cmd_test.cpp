// posthaste test SUITE: a regression suite is a folder of graphs, each with an optional
// NAME.test.json beside it (frames, --set values, idiff thresholds) and its reference outputs in
// SUITE/references/NAME/. Each graph runs with its write nodes redirected into --out; every
// output frame is diffed against its reference; the HTML report and JUnit XML cover the whole
// suite; the exit code is idiff's for the worst verdict. --update writes the references.

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli/commands.h"
#include "core/error.h"
#include "core/json_error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "metrics/diff.h"
#include "metrics/report.h"
#include "nodes/registry.h"

namespace posthaste::cli {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

struct TestOptions {
    std::string suite;
    std::string out;
    std::string report_dir;
    std::string junit;
    std::vector<std::string> only;
    bool update = false;
    int threads = 0;
    bool quiet = false;
};

/// NAME.test.json: what a suite entry runs and how closely it must match.
struct TestSpec {
    std::string frames;
    std::vector<std::string> sets;
    metrics::DiffOptions diff;
};

TestSpec read_test_spec(const fs::path &path)
{
    TestSpec spec;
    // Defaults: OpenImageIO's testsuite tolerances.
    metrics::Thresholds &t = spec.diff.thresholds;
    t.fail = 0.004f;
    t.fail_percent = 0.02f;
    t.hard_fail = 0.012f;
    t.warn = 0.004f;
    t.warn_percent = 0.02f;
    if (!fs::exists(path)) {
        return spec;
    }
    std::ifstream in(path);
    std::stringstream text;
    text << in.rdbuf();
    const std::string where = path.string();
    const json doc = parse_json_document(text.str(), where);
    if (!doc.is_object()) {
        throw_usage(where, ": expected an object {\"frames\", \"set\", \"thresholds\", \"flip\"}");
    }
    for (auto it = doc.begin(); it != doc.end(); ++it) {
        const std::string &key = it.key();
        const json &v = it.value();
        const std::string at = where + ":/" + key;
        if (key == "frames") {
            if (!v.is_string()) {
                throw_usage(at, ": expected a frame list string like \"1-2\"");
            }
            spec.frames = v.get<std::string>();
            parse_frame_list(spec.frames, at);
        } else if (key == "set") {
            if (!v.is_array()) {
                throw_usage(at, ": expected an array of \"node.param=value\" strings");
            }
            for (const json &s : v) {
                if (!s.is_string()) {
                    throw_usage(at, ": expected an array of \"node.param=value\" strings");
                }
                spec.sets.push_back(s.get<std::string>());
            }
        } else if (key == "thresholds") {
            if (!v.is_object()) {
                throw_usage(at, ": expected an object of idiff thresholds");
            }
            for (auto t_it = v.begin(); t_it != v.end(); ++t_it) {
                const std::string tat = at + "/" + t_it.key();
                if (!t_it.value().is_number() || t_it.value().get<double>() < 0.0) {
                    throw_usage(tat, ": expected a number >= 0");
                }
                const float x = t_it.value().get<float>();
                const std::string &n = t_it.key();
                if (n == "fail") {
                    t.fail = x;
                } else if (n == "failrelative") {
                    t.fail_relative = x;
                } else if (n == "failpercent") {
                    t.fail_percent = x;
                } else if (n == "hardfail") {
                    t.hard_fail = x;
                } else if (n == "allowfailures") {
                    t.allow_failures = int(x);
                } else if (n == "warn") {
                    t.warn = x;
                } else if (n == "warnrelative") {
                    t.warn_relative = x;
                } else if (n == "warnpercent") {
                    t.warn_percent = x;
                } else if (n == "hardwarn") {
                    t.hard_warn = x;
                } else {
                    throw_usage(tat,
                                ": unknown threshold \"",
                                n,
                                "\" (fail, failrelative, failpercent, hardfail, allowfailures, "
                                "warn, warnrelative, warnpercent, hardwarn)");
                }
            }
        } else if (key == "flip") {
            const std::string f = v.is_string() ? v.get<std::string>() : "";
            if (f != "hdr" && f != "ldr" && f != "off") {
                throw_usage(at, ": expected \"hdr\", \"ldr\" or \"off\"");
            }
            spec.diff.flip = f == "off"   ? metrics::FlipMode::Off
                             : f == "ldr" ? metrics::FlipMode::Ldr
                                          : metrics::FlipMode::Hdr;
        } else if (key != "description" && key != "comment") {
            throw_usage(
                at, ": unknown key \"", key, "\" (frames, set, thresholds, flip, description)");
        }
    }
    return spec;
}

struct Output {
    std::string node;
    std::string pattern;  ///< Where the run writes it (under --out).
    std::string name;     ///< File pattern name, shared by output and reference.
};

/// Run one suite entry; append its entries. Returns the references written (with update).
int run_entry(const TestOptions &o,
              const fs::path &graph_path,
              std::vector<metrics::ReportEntry> &entries)
{
    const std::string name = graph_path.stem().string();
    const fs::path spec_path = graph_path.parent_path() / (name + ".test.json");
    const fs::path references = fs::path(o.suite) / "references" / name;
    const fs::path out_dir = fs::path(o.out) / name;
    int written = 0;
    auto fail_entry =
        [&](int frame, const std::string &a, const std::string &b, const std::string &message) {
            entries.push_back(metrics::file_error_entry(name, frame, a, b, message));
            std::fprintf(
                stderr, "%s: FILE ERROR: %s\n", name.c_str(), printable_line(message).c_str());
        };
    TestSpec spec;
    std::vector<Output> outputs;
    std::vector<int> frames;
    const auto t0 = std::chrono::steady_clock::now();
    try {
        spec = read_test_spec(spec_path);
        // Load once to find the write nodes, then again with them writing under --out.
        const Graph probe = Graph::load(graph_path.string(), nodes::catalog(), spec.sets);
        std::vector<std::string> sets = spec.sets;
        for (const GraphNode &gn : probe.nodes()) {
            if (gn.identity.type != "write") {
                continue;
            }
            Output out;
            out.node = gn.identity.id;
            out.name = fs::path(gn.params.values().at("path").text).filename().string();
            out.pattern = (out_dir / out.name).string();
            sets.push_back(out.node + ".path=" + out.pattern);
            outputs.push_back(out);
        }
        if (outputs.empty()) {
            throw_usage(graph_path.string(), ": no write node: nothing to compare");
        }
        Graph graph = Graph::load(graph_path.string(), nodes::catalog(), sets);
        frames = spec.frames.empty() ? graph.default_frames()
                                     : parse_frame_list(spec.frames, spec_path.string());
        graph.check(frames);
        for (int f : frames) {
            graph.evaluate(f);
        }
    } catch (const Error &e) {
        fail_entry(frames.empty() ? 0 : frames.front(), graph_path.string(), "", e.what());
        return 0;
    }
    const double run_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ReadOptions read_options;
    read_options.linearize = false;
    spec.diff.images = !o.report_dir.empty();
    const std::size_t compared = std::size_t(frames.size() * outputs.size());
    for (const Output &out : outputs) {
        const std::string test = outputs.size() > 1 ? name + ": " + out.name : name;
        for (int f : frames) {
            const std::string result = expand_frame_pattern(out.pattern, f);
            const std::string reference = expand_frame_pattern((references / out.name).string(), f);
            if (o.update) {
                std::error_code ec;
                fs::create_directories(references, ec);
                fs::copy_file(result, reference, fs::copy_options::overwrite_existing, ec);
                if (ec) {
                    throw_runtime(reference, ": cannot write the reference: ", ec.message());
                }
                ++written;
                continue;
            }
            if (!fs::exists(reference)) {
                fail_entry(f,
                           reference,
                           result,
                           "reference missing: " + reference +
                               " (posthaste test --update writes it after review)");
                continue;
            }
            const auto c0 = std::chrono::steady_clock::now();
            Frame fa, fb;
            try {
                fa = metrics::read_for_comparison(reference, {}, f, read_options);
                fb = metrics::read_for_comparison(result, {}, f, read_options);
            } catch (const Error &e) {
                fail_entry(f, reference, result, e.what());
                continue;
            }
            const metrics::DiffReport report = metrics::diff_frames(fa, fb, spec.diff);
            metrics::ReportEntry e = metrics::report_entry(test, report, reference, result);
            if (!o.report_dir.empty()) {
                e.images = metrics::report_images(fa, fb, report);
            }
            e.seconds =
                run_seconds / double(std::max<std::size_t>(1, compared)) +
                std::chrono::duration<double>(std::chrono::steady_clock::now() - c0).count();
            if (!o.quiet) {
                std::printf("%s: %s\n", test.c_str(), metrics::summary_line(report).c_str());
            }
            entries.push_back(std::move(e));
        }
    }
    return written;
}

int run(const TestOptions &o)
{
    set_thread_count(o.threads);
    std::error_code ec;
    if (!fs::is_directory(o.suite, ec)) {
        throw_usage(o.suite, ": not a suite folder (graphs, NAME.test.json, references/NAME/)");
    }
    std::vector<fs::path> graphs;
    for (const auto &entry : fs::directory_iterator(o.suite)) {
        const std::string file = entry.path().filename().string();
        // A spec whose graph was renamed or removed held thresholds nothing used any more.
        if (file.ends_with(".test.json") &&
            !fs::is_regular_file(
                entry.path().parent_path() / (file.substr(0, file.size() - 10) + ".json"), ec)) {
            throw_usage(entry.path().string(),
                        ": no graph ",
                        file.substr(0, file.size() - 10),
                        ".json beside it for these thresholds");
        }
        if (entry.is_regular_file() && entry.path().extension() == ".json" &&
            !file.ends_with(".test.json")) {
            if (o.only.empty() ||
                std::find(o.only.begin(), o.only.end(), entry.path().stem().string()) !=
                    o.only.end()) {
                graphs.push_back(entry.path());
            }
        }
    }
    std::sort(graphs.begin(), graphs.end());
    // A name --only gives that no graph has is named (it was passed over, and the run passed).
    for (const std::string &name : o.only) {
        if (std::none_of(graphs.begin(), graphs.end(), [&](const fs::path &g) {
                return g.stem().string() == name;
            })) {
            throw_usage(o.suite, ": --only names \"", name, "\", which is no graph of the suite");
        }
    }
    if (graphs.empty()) {
        throw_usage(o.suite, ": no graphs (*.json) in the suite");
    }
    if (o.update && (!o.report_dir.empty() || !o.junit.empty())) {
        throw_usage("--update writes references, not a report: --report and --junit compare");
    }
    std::vector<metrics::ReportEntry> entries;
    int written = 0;
    for (const fs::path &g : graphs) {
        written += run_entry(o, g, entries);
    }
    if (o.update) {
        std::printf("%d reference file(s) written under %s\n",
                    written,
                    (fs::path(o.suite) / "references").string().c_str());
        return entries.empty() ? 0 : metrics::exit_code(metrics::Verdict::FileError);
    }
    metrics::Verdict worst = metrics::Verdict::Pass;
    int counts[5] = {};
    for (const metrics::ReportEntry &e : entries) {
        worst = metrics::worse(worst, e.verdict);
        ++counts[int(e.verdict)];
    }
    const std::string suite_name = fs::path(o.suite).lexically_normal().filename().string();
    if (!o.report_dir.empty()) {
        const std::string page = (fs::path(o.report_dir) / "index.html").string();
        write_text_file(page, metrics::html_report("posthaste test " + o.suite, entries));
        if (!o.quiet) {
            std::printf("report: %s\n", page.c_str());
        }
    }
    if (!o.junit.empty()) {
        write_text_file(o.junit, metrics::junit_xml(suite_name, entries));
    }
    if (!o.quiet) {
        std::printf(
            "%zu graph(s), %zu comparison(s): %d pass, %d warning, %d failure, %d size "
            "mismatch, %d file error; %s\n",
            graphs.size(),
            entries.size(),
            counts[0],
            counts[1],
            counts[2],
            counts[3],
            counts[4],
            metrics::verdict_name(worst));
    }
    return metrics::exit_code(worst);
}

}  // namespace

void add_test_command(CLI::App &app, int &exit_code)
{
    auto o = std::make_shared<TestOptions>();
    CLI::App *cmd = app.add_subcommand(
        "test",
        "Run a regression suite: each graph in SUITE, its outputs diffed against "
        "SUITE/references/NAME/ (idiff exit codes)");
    cmd->add_option(
           "suite", o->suite, "Suite folder: NAME.json graphs, NAME.test.json, references/")
        ->required();
    cmd->add_option("--out,-o", o->out, "Where the graphs write their outputs")
        ->capture_default_str();
    cmd->add_option("--report", o->report_dir, "Write an HTML report to DIR/index.html")
        ->check(not_empty());
    cmd->add_option("--junit", o->junit, "Write JUnit XML here")->check(not_empty());
    cmd->add_option("--only", o->only, "Run only these graphs (names without .json)");
    cmd->add_flag("--update",
                  o->update,
                  "Write the outputs as the new references (after reviewing a change)");
    cmd->add_option("--threads,-t", o->threads, "Worker threads (default: all cores)")
        ->check(in_range(0, 1024));
    cmd->add_flag("--quiet,-q", o->quiet, "Print nothing but errors");
    o->out = "out/test";
    cmd->callback([o, &exit_code] { exit_code = run(*o); });
}

}  // namespace posthaste::cli
