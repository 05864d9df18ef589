// posthaste farm: run a frame sequence on a Slurm cluster. `submit` validates the graph as `run`
// does, writes a job directory (the graph with --set applied, the frame list, the chunk table,
// the batch scripts) and submits one job array (a task per chunk) plus a check job that depends
// on it. Each task runs its chunk's frames, logs one line per frame and prints Open Job
// Description progress lines. `status` tells per frame done (outputs read back whole) / failed /
// running / queued / missing from the disk and squeue; `resubmit` submits what is not done;
// `check` (the check job) writes report.json and report.html. docs/FARM.md has the rules.

#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "cli/commands.h"
#include "cli/farm_job.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "nodes/registry.h"

namespace posthaste::cli {
namespace {

using farm::apply_sets;
using farm::capture;
using farm::check_command;
using farm::frame_states;
using farm::FrameState;
using farm::json;
using farm::load_job_graph;
using farm::make_chunks;
using farm::on_path;
using farm::read_job;
using farm::require_slurm;
using farm::sbatch;
using farm::sbatch_quote;
using farm::shell_quote;
using farm::slurm_filename;
using farm::status_command;
namespace fs = std::filesystem;

struct SlurmOptions {
    int max_running = 0;
    std::string partition;
    int cpus_per_task = 0;
    std::string mem;
    std::string time;
};

struct SubmitOptions {
    std::string graph;
    std::string frames;
    std::string chunk = "8";  ///< frames per task, or "auto" (one wave over the partition)
    std::string job_dir;
    std::vector<std::string> sets;
    SlurmOptions slurm;
    bool dry_run = false;
    bool force = false;
};

std::string self_binary()
{
    std::error_code ec;
    const fs::path p = fs::read_symlink("/proc/self/exe", ec);
    return ec ? std::string("posthaste") : p.string();
}

std::string join_frames(const std::vector<int> &frames)
{
    std::string s;
    for (int f : frames) {
        s += s.empty() ? "" : ",";
        s += std::to_string(f);
    }
    return s;
}

/// Tasks the partition runs at once: its usable CPUs (sinfo's total less those down or
/// drained) over the CPUs a task asks for, at most --max-running. Throws naming sinfo when it
/// cannot tell.
int partition_slots(const SlurmOptions &s)
{
    require_slurm("sinfo");
    std::string out;
    const std::string command =
        "sinfo -h -o '%C %P'" + (s.partition.empty() ? "" : " -p " + shell_quote(s.partition));
    if (!capture(command, out)) {
        std::replace(out.begin(), out.end(), '\n', ' ');
        throw_runtime("farm submit: --chunk auto: sinfo failed: ", out);
    }
    // Lines "allocated/idle/other/total PARTITION", the default partition's name ending in '*'.
    long usable = -1;
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);) {
        long a = 0, i = 0, other = 0, total = 0;
        char name[256] = {0};
        if (std::sscanf(line.c_str(), "%ld/%ld/%ld/%ld %255s", &a, &i, &other, &total, name) != 5) {
            continue;
        }
        const std::string n = name;
        const bool is_default = !n.empty() && n.back() == '*';
        if (usable < 0 || (s.partition.empty() ? is_default : n == s.partition)) {
            usable = std::max(0L, total - other);
        }
        if (s.partition.empty() ? is_default : n == s.partition) {
            break;
        }
    }
    if (usable <= 0) {
        throw_runtime("farm submit: --chunk auto: sinfo reports no usable CPUs",
                      s.partition.empty() ? "" : " in partition " + s.partition,
                      " (give --chunk N)");
    }
    long slots = usable / std::max(1, s.cpus_per_task);
    if (s.max_running > 0) {
        slots = std::min(slots, long(s.max_running));
    }
    return int(std::clamp(slots, 1L, 1000000L));
}

/// --chunk: a count, or "auto": the frames spread over one wave of the partition's slots, so
/// that each task pays a process's start-up once (chunk = ceil(frames / slots)).
int chunk_size(const std::string &text, const SlurmOptions &s, std::size_t frames, bool *automatic)
{
    *automatic = text == "auto";
    if (*automatic) {
        const int slots = partition_slots(s);
        return int(
            std::max<std::size_t>(1, (frames + std::size_t(slots) - 1) / std::size_t(slots)));
    }
    const std::optional<int> chunk = parse_int(text);
    if (!chunk || *chunk < 1) {
        throw_usage("farm submit: --chunk must be a whole number of at least 1 or auto, got \"",
                    text,
                    "\"");
    }
    return *chunk;
}

std::string batch_script(const json &job, const fs::path &dir, int submission, int chunks)
{
    const json &s = job["slurm"];
    std::ostringstream o;
    o << "#!/bin/bash\n"
      << "#SBATCH --job-name=" << sbatch_quote("posthaste-" + dir.filename().string()) << "\n"
      << "#SBATCH --array=0-" << chunks - 1;
    if (s.value("max_running", 0) > 0) {
        o << "%" << s["max_running"].get<int>();
    }
    o << "\n#SBATCH --output="
      << sbatch_quote(slurm_filename((dir / "logs").string()) + "/slurm-s" +
                      std::to_string(submission) + "-%a.out")
      << "\n";
    if (!s.value("partition", "").empty()) {
        o << "#SBATCH --partition=" << s["partition"].get<std::string>() << "\n";
    }
    if (s.value("cpus_per_task", 0) > 0) {
        o << "#SBATCH --cpus-per-task=" << s["cpus_per_task"].get<int>() << "\n";
    }
    if (!s.value("mem", "").empty()) {
        o << "#SBATCH --mem=" << s["mem"].get<std::string>() << "\n";
    }
    if (!s.value("time", "").empty()) {
        o << "#SBATCH --time=" << s["time"].get<std::string>() << "\n";
    }
    o << "# One task per chunk; the task index selects the chunk (job.json's submissions).\n"
      << "cd " << shell_quote(job["cwd"]) << " || exit 1\n"
      << "exec " << shell_quote(job["binary"]) << " farm task " << shell_quote(dir.string())
      << " --submission " << submission
      << " --chunk \"$SLURM_ARRAY_TASK_ID\" --threads \"${SLURM_CPUS_PER_TASK:-0}\"\n";
    return o.str();
}

std::string check_script(const json &job, const fs::path &dir, int submission)
{
    std::ostringstream o;
    o << "#!/bin/bash\n"
      << "#SBATCH --job-name=" << sbatch_quote("posthaste-check-" + dir.filename().string())
      << "\n#SBATCH --output="
      << sbatch_quote(slurm_filename((dir / "logs").string()) + "/check-s" +
                      std::to_string(submission) + ".out")
      << "\n";
    if (!job["slurm"].value("partition", "").empty()) {
        o << "#SBATCH --partition=" << job["slurm"]["partition"].get<std::string>() << "\n";
    }
    o << "cd " << shell_quote(job["cwd"]) << " || exit 1\n"
      << "exec " << shell_quote(job["binary"]) << " farm check " << shell_quote(dir.string())
      << "\n";
    return o.str();
}

/// Write the scripts of submission `s` (chunks in job["submissions"][s]) and submit them.
void submit(json &job, const fs::path &dir, int s, bool *array_refused = nullptr)
{
    json &sub = job["submissions"][std::size_t(s)];
    const int chunks = int(sub["chunks"].size());
    const fs::path run = dir / ("run-s" + std::to_string(s) + ".sbatch");
    const fs::path check = dir / ("check-s" + std::to_string(s) + ".sbatch");
    write_text_file(run.string(), batch_script(job, dir, s, chunks));
    write_text_file(check.string(), check_script(job, dir, s));
    sub["array_job"] = sbatch(shell_quote(run.string()), array_refused);
    sub["check_job"] = sbatch("--dependency=afterany:" + sub["array_job"].get<std::string>() +
                              " --kill-on-invalid-dep=yes " + shell_quote(check.string()));
    write_text_file((dir / "job.json").string(), job.dump(2) + "\n");
}

// ---------------------------------------------------------------------------------------------
// Submit, resubmit, task, check

int submit_command(const SubmitOptions &o)
{
    if (o.chunk != "auto") {
        bool automatic = false;
        chunk_size(o.chunk, o.slurm, 0, &automatic);  // a bad count fails before anything else
    }
    fs::path dir = fs::absolute(o.job_dir).lexically_normal();
    dir = dir.has_filename() ? dir : dir.parent_path();  // "job/", ".": the folder's own name
    if (dir.string().find_first_of("\n\r") != std::string::npos) {
        throw_usage("farm submit: a line break in the job directory's name (#SBATCH lines)");
    }
    if (dir.string().find('\\') != std::string::npos) {
        // Slurm expands no %a in an --output path holding a backslash: every task's log would
        // go to one file.
        throw_usage("farm submit: a backslash in the job directory's name (Slurm's log names)");
    }
    farm::require_sbatch_value("--partition", o.slurm.partition);
    farm::require_sbatch_value("--mem", o.slurm.mem);
    farm::require_sbatch_value("--time", o.slurm.time);
    std::error_code ec;
    if (fs::exists(dir, ec) && !o.force) {
        throw_usage("farm submit: job directory ",
                    dir.string(),
                    " exists (choose another, or --force to replace it)");
    }
    // Validate exactly as `run` does: a typo fails here, before anything is queued.
    Graph graph = Graph::load(o.graph, nodes::catalog(), o.sets);
    const std::vector<int> frames =
        o.frames.empty() ? graph.default_frames() : parse_frame_list(o.frames, "--frames");
    graph.check(frames);
    // Every frame must be one the graph's sources have (a sequence on disk, a scene's range).
    for (const GraphNode &gn : graph.nodes()) {
        if (!gn.inputs.empty() || !gn.type->discover_frames) {
            continue;
        }
        const std::vector<int> have = gn.type->discover_frames(gn.params);
        std::vector<int> outside;
        for (int f : frames) {
            if (!std::binary_search(have.begin(), have.end(), f)) {
                outside.push_back(f);
            }
        }
        if (!outside.empty() && !have.empty()) {
            throw_usage("farm submit: --frames: ",
                        outside.size(),
                        " frame(s) outside what ",
                        gn.identity.describe(),
                        " has (",
                        have.front(),
                        "-",
                        have.back(),
                        "), first ",
                        outside.front());
        }
    }
    if (!o.dry_run) {
        require_slurm("sbatch");
    }
    bool automatic = false;
    const int chunk = chunk_size(o.chunk, o.slurm, frames.size(), &automatic);
    json job;
    job["graph"] = "graph.json";
    job["source_graph"] = fs::absolute(o.graph).string();
    job["sets"] = o.sets;
    job["cwd"] = fs::current_path().string();
    job["binary"] = self_binary();
    job["frames"] = frames;
    job["chunk"] = chunk;
    job["chunk_auto"] = automatic;
    // One wave of tasks: deal the frames round-robin unless a node looks back.
    const bool interleaved = automatic && !graph.looks_back();
    job["interleaved"] = interleaved;
    job["slurm"] = {{"max_running", o.slurm.max_running},
                    {"partition", o.slurm.partition},
                    {"cpus_per_task", o.slurm.cpus_per_task},
                    {"mem", o.slurm.mem},
                    {"time", o.slurm.time}};
    json sub;
    sub["chunks"] = make_chunks(frames, chunk, interleaved);
    job["submissions"] = json::array({sub});
    const std::string graph_text = apply_sets(o.graph, graph, o.sets);
    if (o.force) {
        std::vector<std::string> outputs;
        for (int f : frames) {
            for (std::string &p : graph.outputs(f)) {
                outputs.push_back(std::move(p));
            }
        }
        farm::require_replaceable(dir, o.graph, outputs);
    }
    if (o.dry_run) {
        std::printf(
            "# %s/graph.json: %s with %zu --set value(s); %zu frame(s) in %zu chunk(s) of %d%s\n",
            dir.string().c_str(),
            o.graph.c_str(),
            o.sets.size(),
            frames.size(),
            sub["chunks"].size(),
            chunk,
            automatic ? (interleaved ? " (auto, interleaved)" : " (auto)") : "");
        std::printf("# run-s0.sbatch\n%s",
                    batch_script(job, dir, 0, int(sub["chunks"].size())).c_str());
        std::printf("# check-s0.sbatch (afterany on the array, --kill-on-invalid-dep=yes)\n%s",
                    check_script(job, dir, 0).c_str());
        return 0;
    }
    // --force: the old job directory goes aside, back when nothing was queued, and away once
    // the new job is.
    const fs::path aside = dir.parent_path() / ("." + dir.filename().string() + ".replaced-" +
                                                std::to_string(::getpid()));
    const bool replacing = o.force && fs::exists(fs::symlink_status(dir, ec));
    if (replacing) {
        fs::rename(dir, aside, ec);
        if (ec) {
            throw_runtime(
                dir.string(), ": cannot move the old job directory aside: ", ec.message());
        }
    }
    fs::create_directories(dir / "logs", ec);
    if (ec) {
        std::error_code rm;
        if (replacing) {
            fs::rename(aside, dir, rm);
        }
        throw_runtime(dir.string(), ": cannot create the job directory: ", ec.message());
    }
    bool array_refused = false;
    try {
        write_text_file((dir / "graph.json").string(), graph_text);
        // The written graph is the same graph.
        Graph::load((dir / "graph.json").string(), nodes::catalog());
        write_text_file((dir / "frames.txt").string(), join_frames(frames) + "\n");
        submit(job, dir, 0, &array_refused);
    } catch (const Error &e) {
        std::error_code rm;
        const json &sub = job["submissions"][0];
        if (sub.contains("array_job")) {
            // The array is queued and only the check job was refused: the directory stays.
            write_text_file((dir / "job.json").string(), job.dump(2) + "\n");
            fs::remove_all(aside, rm);
            throw Error(e.code(),
                        str_cat(e.what(),
                                " (array job ",
                                sub["array_job"].get<std::string>(),
                                " is queued; its job directory ",
                                dir.string(),
                                " stays)"));
        }
        if (array_refused || !fs::exists(dir / "run-s0.sbatch")) {
            // Nothing was queued (sbatch refused the array, or it was never called): no half-made
            // job directory is left to block the next submit, and a replaced one comes back.
            fs::remove_all(dir, rm);
            if (replacing) {
                fs::rename(aside, dir, rm);
            }
        } else if (replacing) {
            throw Error(e.code(), str_cat(e.what(), " (the old job directory is ", aside, ")"));
        }
        throw;
    }
    if (replacing) {
        fs::remove_all(aside, ec);
    }
    std::printf("%s %s\n",
                job["submissions"][0]["array_job"].get<std::string>().c_str(),
                dir.string().c_str());
    return 0;
}

int resubmit_command(const std::string &dir_text, bool dry_run)
{
    const fs::path dir = fs::absolute(dir_text);
    json job = read_job(dir);
    if (!dry_run) {
        // Without squeue a running chunk would look missing and be rendered twice.
        require_slurm("squeue");
    }
    const std::string cwd = fs::current_path().string();
    const Graph graph = load_job_graph(job, dir);
    std::vector<int> todo;
    for (const auto &[f, st] : frame_states(job, dir, graph)) {
        if (st.state == "missing" || st.state == "failed") {
            todo.push_back(f);
        }
    }
    if (todo.empty()) {
        std::printf("nothing to resubmit: every frame is done, running or queued\n");
        return 0;
    }
    int chunk = job["chunk"].get<int>();
    if (job.value("chunk_auto", false)) {  // one wave again, over the frames left
        SlurmOptions so;
        so.partition = job["slurm"].value("partition", "");
        so.cpus_per_task = job["slurm"].value("cpus_per_task", 0);
        so.max_running = job["slurm"].value("max_running", 0);
        bool automatic = false;
        chunk = chunk_size("auto", so, todo.size(), &automatic);
    }
    json sub;
    sub["chunks"] = make_chunks(todo, chunk, job.value("interleaved", false));
    const int s = int(job["submissions"].size());
    if (dry_run) {
        std::printf("# would resubmit frames %s in %zu chunk(s)\n",
                    join_frames(todo).c_str(),
                    sub["chunks"].size());
        return 0;
    }
    require_slurm("sbatch");
    job["submissions"].push_back(sub);
    submit(job, dir, s);
    std::printf("%s %s (frames %s)\n",
                job["submissions"][std::size_t(s)]["array_job"].get<std::string>().c_str(),
                dir.string().c_str(),
                join_frames(todo).c_str());
    std::error_code ec;
    fs::current_path(cwd, ec);
    return 0;
}

int task_command(const std::string &dir_text, int submission, int chunk, int threads)
{
    const fs::path dir = fs::absolute(dir_text);
    const json job = read_job(dir);
    const json &subs = job["submissions"];
    if (submission < 0 || submission >= int(subs.size()) || chunk < 0 ||
        chunk >= int(subs[std::size_t(submission)]["chunks"].size())) {
        throw_usage("farm task: no chunk ", chunk, " in submission ", submission);
    }
    const std::vector<int> frames =
        subs[std::size_t(submission)]["chunks"][std::size_t(chunk)].get<std::vector<int>>();
    Graph graph = load_job_graph(job, dir);
    const fs::path log_path =
        dir / "logs" /
        ("s" + std::to_string(submission) + "-chunk" + std::to_string(chunk) + ".jsonl");
    std::ofstream log(log_path, std::ios::app);
    if (!log) {
        throw_runtime(log_path.string(), ": cannot write the task's log");
    }
    bool log_failed = false;
    RunSettings rs;
    rs.frames = join_frames(frames);
    rs.threads = threads;
    rs.quiet = true;
    rs.keep_going = true;
    std::map<std::string, double> node_seconds;
    rs.node_seconds = &node_seconds;
    int finished = 0;
    rs.on_frame = [&](int frame, double start, double seconds, const std::string &error) {
        json line = {{"frame", frame},
                     {"start", start},
                     {"seconds", seconds},
                     {"status", error.empty() ? "done" : "failed"}};
        if (!error.empty()) {
            line["error"] = error;
        } else {
            // What was written, as status and the check job verify it (farm_job.h).
            std::vector<farm::OutputRecord> records;
            for (const std::string &p : graph.outputs(frame)) {
                farm::OutputRecord r;
                if (farm::record_output(p, r)) {
                    records.push_back(std::move(r));
                }
            }
            line["outputs"] = farm::records_json(records);
        }
        log_failed = log_failed || !(log << line.dump() << "\n" << std::flush);
        ++finished;
        std::printf("openjd_status: frame %d %s\nopenjd_progress: %.1f\n",
                    frame,
                    error.empty() ? "done" : "failed",
                    100.0 * finished / double(frames.size()));
        std::fflush(stdout);
    };
    std::printf("openjd_status: chunk %d of submission %d, frames %s\n",
                chunk,
                submission,
                rs.frames.c_str());
    std::fflush(stdout);
    int code = 0;
    std::string failure;
    try {
        code = run_graph(graph, rs);
    } catch (const Error &e) {
        code = e.exit_code();
        failure = e.what();
    }
    const fs::path times_path =
        dir / "logs" /
        ("s" + std::to_string(submission) + "-chunk" + std::to_string(chunk) + ".nodes.json");
    std::ofstream times(times_path);
    const bool times_failed = !(times << json(node_seconds).dump() << "\n" << std::flush);
    if (!failure.empty()) {
        throw Error(ExitCode(code), failure);
    }
    // A frame whose line is lost counts as never run: the task must not say it succeeded.
    if (log_failed || times_failed) {
        throw_runtime((log_failed ? log_path : times_path).string(), ": cannot be written");
    }
    return code;
}

}  // namespace

void add_farm_command(CLI::App &app, int &exit_code)
{
    CLI::App *farm = app.add_subcommand("farm", "Run a sequence on a Slurm cluster");
    farm->require_subcommand(1);

    auto so = std::make_shared<SubmitOptions>();
    CLI::App *sub = farm->add_subcommand(
        "submit", "Validate a graph, write a job directory, submit a job array and a check job");
    sub->add_option("graph", so->graph, "Graph file (JSON)")->required();
    sub->add_option("--frames,-f", so->frames, "Frames: 1-480, 1-48x2, 1,5,10-20");
    sub->add_option("--chunk",
                    so->chunk,
                    "Frames per array task (default 8), or auto: the frames spread over the "
                    "tasks the partition runs at once (its CPUs over --cpus-per-task, at most "
                    "--max-running), so each task starts once");
    sub->add_option("--job-dir",
                    so->job_dir,
                    "Job directory (must not exist, unless --force and it is a job directory)")
        ->required();
    sub->add_option("--max-running", so->slurm.max_running, "Array tasks running at once")
        ->check(in_range(0, 100000));
    sub->add_option("--partition", so->slurm.partition, "Slurm partition");
    sub->add_option("--cpus-per-task", so->slurm.cpus_per_task, "CPUs per task (the threads)")
        ->check(in_range(0, 1024));  // farm task --threads' range
    sub->add_option("--mem", so->slurm.mem, "Memory per task (Slurm syntax: 8G)");
    sub->add_option("--time", so->slurm.time, "Time limit per task (Slurm syntax: 1:00:00)");
    sub->add_option("--set,-s", so->sets, "Override a parameter: node.param=value")
        ->allow_extra_args(false);
    sub->add_flag("--dry-run", so->dry_run, "Validate and print the scripts; submit nothing");
    sub->add_flag(
        "--force", so->force, "Replace an existing job directory (once the new job is queued)");
    sub->callback([so, &exit_code] { exit_code = submit_command(*so); });

    auto dir = std::make_shared<std::string>();
    auto as_json = std::make_shared<bool>(false);
    CLI::App *st = farm->add_subcommand(
        "status", "Per frame: done (read back whole), failed, running, queued or missing");
    st->add_option("job_dir", *dir, "Job directory")->required();
    st->add_flag("--json", *as_json, "Machine-readable output");
    st->callback([dir, as_json, &exit_code] { exit_code = status_command(*dir, *as_json); });

    auto rdir = std::make_shared<std::string>();
    auto rdry = std::make_shared<bool>(false);
    CLI::App *re = farm->add_subcommand(
        "resubmit", "Submit the missing and failed frames again, with a new check job");
    re->add_option("job_dir", *rdir, "Job directory")->required();
    re->add_flag("--dry-run", *rdry, "Print what would be resubmitted");
    re->callback([rdir, rdry, &exit_code] { exit_code = resubmit_command(*rdir, *rdry); });

    auto tdir = std::make_shared<std::string>();
    auto tsub = std::make_shared<int>(0);
    auto tchunk = std::make_shared<int>(-1);
    auto tthreads = std::make_shared<int>(0);
    CLI::App *task = farm->add_subcommand("task", "Run one chunk (what an array task runs)");
    task->add_option("job_dir", *tdir, "Job directory")->required();
    task->add_option("--submission", *tsub, "Submission index");
    task->add_option("--chunk", *tchunk, "Chunk index (the array task id)")->required();
    task->add_option("--threads", *tthreads, "Worker threads (0: all cores)")
        ->check(in_range(0, 1024));
    task->callback([tdir, tsub, tchunk, tthreads, &exit_code] {
        exit_code = task_command(*tdir, *tsub, *tchunk, *tthreads);
    });

    auto cdir = std::make_shared<std::string>();
    CLI::App *check = farm->add_subcommand(
        "check", "Write report.json and report.html; exit 1 unless every frame is done");
    check->add_option("job_dir", *cdir, "Job directory")->required();
    check->callback([cdir, &exit_code] { exit_code = check_command(*cdir); });
}

}  // namespace posthaste::cli
