#pragma once
// The farm job directory, shared by `farm submit`/`resubmit`/`task` (cmd_farm.cpp) and
// `farm status`/`check` (farm_job.cpp). docs/FARM.md has the layout.

#include <cstdint>
#include <filesystem>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "graph/graph.h"

namespace posthaste::cli::farm {

namespace fs = std::filesystem;
using json = nlohmann::json;

/// Run a command; its stdout, and whether it exited 0.
bool capture(const std::string &command, std::string &out);
/// As capture: the command's exit status (-1 when it could not be run or was killed).
int capture_status(const std::string &command, std::string &out);
/// `s` in single quotes for a shell (a quote inside closes, escapes and reopens).
std::string shell_quote(const std::string &s);
/// `s` as one value of an #SBATCH line: in double quotes, with " and \ escaped by a backslash
/// (sbatch reads those lines itself: a space would end the value, a # start a comment).
/// Refuses a Slurm option's value with characters outside Slurm's syntax for partitions, memory
/// and times (letters, digits, "_-.:,+"): a line break would start a shell line in the batch
/// script (and end its #SBATCH directives there); one line naming the option.
void require_sbatch_value(const std::string &option, const std::string &value);
std::string sbatch_quote(const std::string &s);
/// A path as text inside an #SBATCH --output pattern: each "%" doubled (Slurm reads "%a",
/// "%j", ... in it; "50%all" would name a file per array task and job).
std::string slurm_filename(const std::string &path);
/// An Error naming how to get Slurm's `program` unless it is on PATH.
void require_slurm(const std::string &program);
/// `sbatch --parsable ARGS`: the job id, or an Error with what sbatch said; `refused` is set
/// when sbatch exited non-zero (nothing was queued).
std::string sbatch(const std::string &args, bool *refused = nullptr);
/// Whether `program` is an executable on PATH.
bool on_path(const std::string &program);
/// A job file (job.json, a chunk's state); a one-line error when unreadable or malformed.
json read_json(const fs::path &path);
/// DIR/job.json, its shape checked (farm_dir.cpp): every key the commands read, with its type,
/// chunk frames among "frames", job ids of digits only (they go into squeue's command line).
/// One line naming the file and the key otherwise.
json read_job(const fs::path &dir);
/// Load the job's graph from its working directory (graph paths are relative to it).
Graph load_job_graph(const json &job, const fs::path &dir);
/// The graph file with the --set values written into its node params, typed as `run` types
/// them (farm_dir.cpp).
std::string apply_sets(const std::string &graph_path,
                       const Graph &graph,
                       const std::vector<std::string> &sets);
/// Chunks of `chunk` frames: contiguous, or `interleaved` (chunk k of n takes frames k, k + n,
/// ...; farm_dir.cpp says when).
std::vector<std::vector<int>> make_chunks(const std::vector<int> &frames,
                                          int chunk,
                                          bool interleaved);
/// `submit --force`: refuses to replace `dir` unless it is a job directory (holds job.json) or
/// empty, and not the current folder, nor a folder holding the graph or an output (one line
/// naming it, exit 2).
void require_replaceable(const fs::path &dir,
                         const std::string &graph_path,
                         const std::vector<std::string> &outputs);

/// What a task records of an output it wrote (after the atomic rename): its size and a 64-bit
/// hash of its bytes (core/hash.h hash_bytes, hex).
struct OutputRecord {
    std::string path;
    std::uint64_t bytes = 0;
    std::string hash;
};
/// The record of the file at `path` as it is now; false when it cannot be read.
bool record_output(const std::string &path, OutputRecord &out);
/// Records as a task's log line holds them, and back (entries that do not parse are dropped).
json records_json(const std::vector<OutputRecord> &records);
std::vector<OutputRecord> records_from(const json &line);

struct FrameState {
    std::string state = "missing";  ///< done, failed, running, queued, missing
    std::string error;
    double seconds = -1.0;
    int submission = -1, chunk = -1;
    std::vector<OutputRecord> written;  ///< from the task's "done" line, when it has them
};

/// Each frame's state: done, failed, running, queued or missing, from the job directory and
/// squeue. Done means every output of the frame is there and whole: byte for byte what the task
/// recorded having written (its size and hash), or, for a frame without records (a job
/// directory of an older version), every pixel of every part and level read back.
/// Only frames whose latest log line says done are read back: leftover files of frames no task
/// ran are not this job's. A failing squeue is an error, or with `tolerant` a warning.
std::map<int, FrameState> frame_states(const json &job,
                                       const fs::path &dir,
                                       const Graph &graph,
                                       bool tolerant = false);

/// `farm status DIR [--json]`.
int status_command(const std::string &dir_text, bool as_json);
/// `farm check DIR`: report.json and report.html; non-zero when a frame is not done.
int check_command(const std::string &dir_text);

}  // namespace posthaste::cli::farm
