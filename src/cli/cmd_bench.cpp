// posthaste bench SPEC.json: time one node over a sweep of settings and measure its error
// against a ground truth (files or another graph); writes results.csv, chart.svg (error against
// time, Pareto front marked), index.html with thumbnails, and results.json (src/bench/bench.h).

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <utility>
#include <vector>

#include "bench/bench.h"
#include "bench/stability_chart.h"
#include "cli/commands.h"
#include "core/error.h"
#include "core/text.h"
#include "graph/graph.h"
#include "io/image_file.h"

namespace posthaste::cli {
namespace {

struct BenchCliOptions {
    std::string spec;
    std::string out;
    std::string stability;
    std::string frames;
    bool frames_given = false;  ///< --frames was given (an empty list is then an error).
    int runs = 0;
    int warmup = -1;
    int threads = -1;
    bool quiet = false;
    std::string max_memory;
};

/// A stability record's charts (tests/stability writes build/stability.json), as (file name,
/// text): made before the bench runs, so that a bad record stops it before any timing.
std::vector<std::pair<std::string, std::string>> chart_stability(const std::string &record)
{
    std::error_code ec;
    if (std::filesystem::is_directory(record, ec)) {
        throw_usage(record, ": is a directory, not a stability record (--stability)");
    }
    std::ifstream in(record, std::ios::binary);
    if (!in) {
        throw_usage(record, ": cannot read the stability record (--stability)");
    }
    std::stringstream text;
    text << in.rdbuf();
    return {{"stability.svg", bench::stability_svg(text.str(), record)},
            {"stability.html", bench::stability_html(text.str(), record)}};
}

int run(const BenchCliOptions &o)
{
    apply_memory_budget(o.max_memory);
    if (o.spec.empty() && o.stability.empty()) {
        throw_usage("bench: give a spec file, or --stability RECORD.json");
    }
    if (o.frames_given && o.frames.empty()) {
        throw_usage("bench: --frames: expected a frame list such as 8 or 1-2, got nothing");
    }
    if (!o.frames.empty()) {
        parse_frame_list(o.frames, "--frames");
    }
    const auto stability = o.stability.empty() ? std::vector<std::pair<std::string, std::string>>{}
                                               : chart_stability(o.stability);
    if (o.spec.empty()) {
        const std::string out = o.out.empty() ? "bench_out/stability" : o.out;
        std::error_code ec;
        std::filesystem::create_directories(out, ec);
        if (ec) {
            throw_runtime(out, ": cannot create the output folder (--out): ", ec.message());
        }
        for (const auto &[name, text] : stability) {
            write_text_file((std::filesystem::path(out) / name).string(), text);
        }
        if (!o.quiet) {
            std::printf("wrote %s/{stability.svg,stability.html}\n", out.c_str());
        }
        return 0;
    }
    bench::BenchSpec spec = bench::load_spec(o.spec);
    if (!o.frames.empty()) {
        spec.frames = o.frames;
    }
    if (o.runs > 0) {
        spec.runs = o.runs;
    }
    if (o.warmup >= 0) {
        spec.warmup = o.warmup;
    }
    if (o.threads >= 0) {
        spec.threads = o.threads;
    }
    const std::string out =
        o.out.empty() ? "bench_out/" + std::filesystem::path(o.spec).stem().string() : o.out;
    // A destination that cannot be a folder fails now, not after the timed runs.
    for (const std::filesystem::path &d :
         {std::filesystem::path(out), std::filesystem::path(out) / "thumbs"}) {
        std::error_code ec;
        if (std::filesystem::exists(d, ec) && !std::filesystem::is_directory(d, ec)) {
            throw_runtime(d.string(), ": is a file, not a folder for the bench output (--out)");
        }
    }
    const bench::BenchResult result = bench::run_bench(spec, [&](const std::string &line) {
        if (!o.quiet) {
            std::fprintf(stderr, "%s\n", line.c_str());
        }
    });
    bench::write_results(result, out, stability);
    if (!o.quiet) {
        std::printf("%-20s %12s %12s %10s %12s %10s %10s %s\n",
                    "setting",
                    "node ms",
                    "graph ms",
                    "ratio",
                    "rmse",
                    "psnr",
                    "flip",
                    "pareto");
        for (const bench::SettingResult &r : result.settings) {
            std::printf("%-20s %12.4f %12.4f %10.3f %12.6g %10.4g %10.4g %s\n",
                        printable_line(r.setting.name).c_str(),
                        r.node.median_ms,
                        r.graph.median_ms,
                        r.speed_ratio,
                        r.rmse,
                        r.psnr,
                        r.flip,
                        r.pareto ? "*" : "");
        }
        std::printf("wrote %s/{results.csv,chart.svg,index.html,results.json,thumbs/%s}\n",
                    printable_line(out).c_str(),
                    stability.empty() ? "" : ",stability.svg,stability.html");
    }
    return 0;
}

}  // namespace

void add_bench_command(CLI::App &app, int &exit_code)
{
    auto o = std::make_shared<BenchCliOptions>();
    CLI::App *cmd = app.add_subcommand(
        "bench", "Time a node over a sweep of settings against a ground truth: CSV, SVG, HTML");
    cmd->add_option("spec", o->spec, "Bench spec (JSON; see docs/DIFF.md)");
    cmd->add_option("--out,-o", o->out, "Output folder (default: bench_out/<spec name>)");
    CLI::Option *frames = cmd->add_option(
        "--frames,-f", o->frames, "Frames to run (default: the spec's), e.g. 8 or 1-2");
    cmd->add_option("--runs,-n", o->runs, "Timed runs per setting (default: the spec's)")
        ->check(in_range(1, 100000));
    cmd->add_option("--warmup", o->warmup, "Warm-up runs per setting (default: the spec's)")
        ->check(in_range(0, 1000));
    cmd->add_option("--threads,-t",
                    o->threads,
                    "Worker threads, fixed for every run (default: the spec's; 0: all cores)")
        ->check(in_range(0, 1024));
    cmd->add_option("--stability",
                    o->stability,
                    "Also chart a stability record (build/stability.json from the tests)");
    cmd->add_flag("--quiet,-q", o->quiet, "No progress and no table");
    cmd->add_option("--max-memory",
                    o->max_memory,
                    "Budget for pass images (8G, 512M; 0: none; default 80 % of available)");
    cmd->callback([o, frames, &exit_code] {
        o->frames_given = frames->count() > 0;
        exit_code = run(*o);
    });
}

}  // namespace posthaste::cli
