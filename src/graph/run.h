#pragma once
// Running a graph over frames: several frames at once (jobs), tiles in parallel inside each node
// (threads), failures collected per frame, progress and a summary on a terminal. Shared by the
// CLI's run, render and farm tasks and by the Python module.

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace posthaste {

class Graph;

/// Options of a run (the CLI's run and render, a farm chunk, Python's Graph.run).
struct RunSettings {
    std::string frames;
    /// Frames in flight: 0 the default (default_jobs), -1 auto (run_graph), else the count.
    int jobs = 0;
    int threads = 0;
    /// No progress and no summary on stdout/stderr.
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
    /// Asked before each frame is started; true stops the run there (frames in flight finish).
    /// May be called from any of the run's threads, never two at once.
    std::function<bool()> should_stop;
    /// When set, filled with each node's total seconds ("id (type)" -> s) after the run.
    std::map<std::string, double> *node_seconds = nullptr;
    /// When set, the frames evaluated without error, in the order they finished.
    std::vector<int> *frames_written = nullptr;
};

/// Apply --max-memory: "0" = no budget, "" = 80 % of MemAvailable, else a size ("8G").
void apply_memory_budget(const std::string &max_memory);

/// Frames of `frames` whose outputs in `graph` all exist and read back whole.
std::vector<int> frames_done(const Graph &graph, const std::vector<int> &frames);

/// The default frames in flight for `threads` worker threads: threads / 2, from 1 to 4 (each
/// frame gets two threads or more).
int default_jobs(int threads);

/// Check and evaluate `graph` over the frames (settings.frames, else the graph's default), with
/// progress and a summary unless quiet. Returns the exit code; throws Error on failure.
int run_graph(Graph &graph, const RunSettings &settings);

/// True when stderr is a terminal (progress bars).
bool stderr_is_terminal();

}  // namespace posthaste
