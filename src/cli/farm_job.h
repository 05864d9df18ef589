#pragma once
// The farm job directory, shared by `farm submit`/`resubmit`/`task` (cmd_farm.cpp) and
// `farm status`/`check` (farm_job.cpp). docs/FARM.md has the layout.

#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "graph/graph.h"

namespace posthaste::cli::farm {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// Run a command; its stdout, and whether it exited 0.
bool capture(const std::string &command, std::string &out);
/// Whether `program` is an executable on PATH.
bool on_path(const std::string &program);
/// A job file (job.json, a chunk's state); a one-line error when unreadable or malformed.
json read_json(const fs::path &path);
/// Load the job's graph from its working directory (graph paths are relative to it).
Graph load_job_graph(const json &job, const fs::path &dir);

struct FrameState {
    std::string state = "missing";  ///< done, failed, running, queued, missing
    std::string error;
    double seconds = -1.0;
    int submission = -1, chunk = -1;
};

/// Each frame's state: done (its outputs read back whole), failed, running, queued or missing,
/// from the job directory and squeue.
std::map<int, FrameState> frame_states(const json &job, const fs::path &dir, const Graph &graph);

/// `farm status DIR [--json]`.
int status_command(const std::string &dir_text, bool as_json);
/// `farm check DIR`: report.json and report.html; non-zero when a frame is not done.
int check_command(const std::string &dir_text);

}  // namespace posthaste::cli::farm
