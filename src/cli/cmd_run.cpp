// posthaste run GRAPH: evaluate a graph over frames (graph/run.h does the work).

#include <optional>
#include <string>

#include "cli/commands.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "graph/graph.h"
#include "nodes/registry.h"

namespace posthaste::cli {
namespace {

struct RunOptions : RunSettings {
    std::string graph;
    std::vector<std::string> sets;
    std::string jobs_text;
};

/// --jobs: a count in [0, 256] (0: the default), or auto (-1, graph/run.cpp).
int parse_jobs(const std::string &text)
{
    if (text.empty()) {
        return 0;
    }
    if (text == "auto") {
        return -1;
    }
    const std::optional<int> jobs = parse_int(text);
    if (!jobs || *jobs < 0 || *jobs > 256) {
        throw_usage("--jobs: expected a number in [0, 256] or auto, got \"", text, "\"");
    }
    return *jobs;
}

}  // namespace

void add_run_command(CLI::App &app, int &exit_code)
{
    auto opts = std::make_shared<RunOptions>();
    CLI::App *cmd = app.add_subcommand("run", "Evaluate a graph over a range of frames");
    cmd->add_option("graph", opts->graph, "Graph file (JSON)")->required();
    cmd->add_option("--frames,-f",
                    opts->frames,
                    "Frames: 1-48, 1-48x2, 1,5,10-20 (default: the graph's, else those on disk)")
        ->check(not_empty());
    cmd->add_option("--set,-s", opts->sets, "Override a parameter: node.param=value")
        ->allow_extra_args(false);
    cmd->add_option(
           "--jobs,-j",
           opts->jobs_text,
           "Frames evaluated at once (default: threads / 2, 1 to 4); auto: the first frame "
           "alone, then one per thread, at most what 3/4 of --max-memory holds of the "
           "first frame's pass images")
        ->check(not_empty());
    cmd->add_option("--threads,-t", opts->threads, "Worker threads (default: all cores)")
        ->check(in_range(0, 1024));
    cmd->add_flag("--quiet,-q", opts->quiet, "No progress and no summary");
    cmd->add_flag("--skip-bad-frames",
                  opts->skip_bad_frames,
                  "Carry on past frames whose input is missing or unreadable, with a warning "
                  "(an output that cannot be written still fails the run)");
    cmd->add_flag("--dry-run", opts->dry_run, "Validate the graph and its inputs, compute nothing");
    cmd->add_option("--max-memory",
                    opts->max_memory,
                    "Budget for pass images, all frames in flight (8G, 512M; 0: none; default 80 "
                    "% of available memory); frames it refuses run again with half as many at "
                    "once")
        ->check(not_empty());
    cmd->add_flag("--skip-existing",
                  opts->skip_existing,
                  "Skip frames whose outputs all exist and read back whole (resume a run)");
    cmd->add_flag("--keep-going",
                  opts->keep_going,
                  "Carry on past failing frames, then exit non-zero naming the first");
    cmd->callback([opts, &exit_code] {
        opts->jobs = parse_jobs(opts->jobs_text);
        set_thread_count(opts->threads);
        Graph graph = Graph::load(opts->graph, nodes::catalog(), opts->sets);
        exit_code = run_graph(graph, *opts);
    });
}

}  // namespace posthaste::cli
