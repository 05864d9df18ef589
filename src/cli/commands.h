#pragma once
// Each subcommand adds itself to the CLI11 app; its callback throws posthaste::Error on failure
// and stores its exit code in `exit_code` otherwise.

#include <CLI/CLI.hpp>
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
};

/// Check and evaluate `graph` over the frames (settings.frames, else the graph's default), with
/// progress and a summary. Returns the exit code; throws Error on failure.
int run_graph(Graph &graph, const RunSettings &settings);
void add_render_command(CLI::App &app, int &exit_code);

void add_run_command(CLI::App &app, int &exit_code);
void add_info_command(CLI::App &app, int &exit_code);
void add_nodes_command(CLI::App &app, int &exit_code);
void add_diff_command(CLI::App &app, int &exit_code);
void add_bench_command(CLI::App &app, int &exit_code);

/// True when stderr is a terminal (progress bars) and NO_COLOR-style plain output is not forced.
bool stderr_is_terminal();

}  // namespace posthaste::cli
