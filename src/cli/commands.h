#pragma once
// Each subcommand adds itself to the CLI11 app; its callback throws posthaste::Error on failure
// and stores its exit code in `exit_code` otherwise.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace posthaste {
class Graph;
}

namespace posthaste::cli {

/// Options shared by the commands that evaluate a graph (run, render).
struct RunSettings {
    std::string frames;
    int jobs = 0;
    int threads = 0;
    bool quiet = false;
    bool skip_bad_frames = false;
    bool dry_run = false;
    /// --max-memory: "" = a share of the machine's available memory (see memory_budget_from).
    std::string max_memory;
    /// Skip frames whose outputs all exist and read back whole (resume an interrupted run).
    bool skip_existing = false;
    /// Carry on past failing frames, then fail (exit code of the first failure) at the end.
    bool keep_going = false;
    /// Called after each frame, under a lock: frame, start (seconds since the epoch), seconds
    /// taken, and the error ("" when the frame was written).
    std::function<void(int, double, double, const std::string &)> on_frame;
    /// When set, filled with each node's total seconds ("id (type)" -> s) after the run.
    std::map<std::string, double> *node_seconds = nullptr;
};

/// Apply --max-memory: "0" = no budget, "" = 80 % of MemAvailable, else a size ("8G").
void apply_memory_budget(const std::string &max_memory);

/// Frames of `frames` whose outputs in `graph` all exist and read back whole.
std::vector<int> frames_done(const Graph &graph, const std::vector<int> &frames);

/// Check and evaluate `graph` over the frames (settings.frames, else the graph's default), with
/// progress and a summary. Returns the exit code; throws Error on failure.
int run_graph(Graph &graph, const RunSettings &settings);
void add_render_command(CLI::App &app, int &exit_code);

void add_run_command(CLI::App &app, int &exit_code);
void add_info_command(CLI::App &app, int &exit_code);
void add_nodes_command(CLI::App &app, int &exit_code);
void add_diff_command(CLI::App &app, int &exit_code);
void add_bench_command(CLI::App &app, int &exit_code);
void add_farm_command(CLI::App &app, int &exit_code);
void add_test_command(CLI::App &app, int &exit_code);

/// True when stderr is a terminal (progress bars) and NO_COLOR-style plain output is not forced.
bool stderr_is_terminal();

}  // namespace posthaste::cli
