// The farm job directory as status and check read it (farm_job.h): the job file, the job's
// graph, each frame's state from the disk and squeue, the status table and the check job's
// report. cmd_farm.cpp has submit, resubmit and the tasks.

#include "cli/farm_job.h"

#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <climits>
#include <cstdio>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <utility>

#include "core/error.h"
#include "core/hash.h"
#include "core/parallel.h"
#include "core/text.h"
#include "io/image_file.h"
#include "nodes/registry.h"

namespace posthaste::cli::farm {

bool capture(const std::string &command, std::string &out)
{
    return capture_status(command, out) == 0;
}

int capture_status(const std::string &command, std::string &out)
{
    out.clear();
    FILE *pipe = ::popen((command + " 2>&1").c_str(), "r");
    if (!pipe) {
        return -1;
    }
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof(buf), pipe)) {
        out.append(buf, n);
    }
    const int status = ::pclose(pipe);
    return status != -1 && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string shell_quote(const std::string &s)
{
    std::string q = "'";
    for (char c : s) {
        q += c == '\'' ? std::string("'\\''") : std::string(1, c);
    }
    return q + "'";
}

std::string sbatch_quote(const std::string &s)
{
    std::string q = "\"";
    for (char c : s) {
        q += c == '"' || c == '\\' ? std::string("\\") + c : std::string(1, c);
    }
    return q + "\"";
}

std::string slurm_filename(const std::string &path)
{
    std::string out;
    for (const char c : path) {
        out.push_back(c);
        if (c == '%') {
            out.push_back('%');
        }
    }
    return out;
}

void require_sbatch_value(const std::string &option, const std::string &value)
{
    for (const char c : value) {
        if (!std::isalnum(static_cast<unsigned char>(c)) &&
            std::string_view("_-.:,+").find(c) == std::string_view::npos) {
            throw_usage(
                "farm submit: ",
                option,
                ": ",
                c == '\n' || c == '\r' ? std::string("a line break") : std::string{'"', c, '"'},
                " in \"",
                value.substr(0, value.find_first_of("\r\n")),
                "\" is not Slurm syntax (a partition name, 8G, 1:00:00)");
        }
    }
}

void require_slurm(const std::string &program)
{
    if (!on_path(program)) {
        throw_runtime("farm: ",
                      program,
                      " is not on PATH: run on a Slurm submit host, or install Slurm's client "
                      "(Debian: apt-get install --no-install-recommends slurm-client; a local "
                      "cluster also needs slurmctld slurmd munge, see tests/slurm-local.sh)");
    }
}

std::string sbatch(const std::string &args, bool *refused)
{
    std::string out;
    if (!capture("sbatch --parsable " + args, out)) {
        if (refused) {
            *refused = true;
        }
        std::replace(out.begin(), out.end(), '\n', ' ');
        throw_runtime("farm: sbatch failed: ", out);
    }
    // The id ("123" or "123;cluster") is the line of digits; warnings (stderr is captured too)
    // or a site plugin's notes may come before it.
    std::istringstream lines(out);
    for (std::string line; std::getline(lines, line);) {
        const std::string id = line.substr(0, line.find(';'));
        if (!id.empty() && id.find_first_not_of("0123456789") == std::string::npos) {
            return id;
        }
    }
    std::replace(out.begin(), out.end(), '\n', ' ');
    throw_runtime("farm: sbatch printed no job id: ", out);
}

bool on_path(const std::string &program)
{
    const char *path = std::getenv("PATH");
    std::stringstream ss(path ? path : "");
    std::string dir;
    while (std::getline(ss, dir, ':')) {
        if (!dir.empty() && ::access((dir + "/" + program).c_str(), X_OK) == 0) {
            return true;
        }
    }
    return false;
}

json read_json(const fs::path &path)
{
    std::ifstream in(path);
    if (!in) {
        throw_runtime(path.string(), ": cannot read (not a farm job directory?)");
    }
    try {
        return json::parse(in);
    } catch (const json::exception &e) {
        throw_runtime(path.string(), ": malformed job file: ", e.what());
    }
}

/// Load the job's graph from its working directory (graph paths are relative to it).
Graph load_job_graph(const json &job, const fs::path &dir)
{
    std::error_code ec;
    fs::current_path(job["cwd"].get<std::string>(), ec);
    if (ec) {
        throw_runtime(dir.string(), ": cannot enter the job's working directory ", job["cwd"]);
    }
    return Graph::load((dir / "graph.json").string(), nodes::catalog());
}

// ---------------------------------------------------------------------------------------------
// Output records

bool record_output(const std::string &path, OutputRecord &out)
{
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        return false;
    }
    std::vector<char> block(std::size_t(1) << 20);  // a multiple of 8: hash_bytes continues
    std::uint64_t h = kHashBytesSeed, bytes = 0;
    while (in) {
        in.read(block.data(), std::streamsize(block.size()));
        const auto got = std::size_t(in.gcount());
        h = hash_bytes(h, block.data(), got);
        bytes += got;
    }
    if (in.bad()) {
        return false;
    }
    char hex[17];
    std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(h));
    out.path = path;
    out.bytes = bytes;
    out.hash = hex;
    return true;
}

json records_json(const std::vector<OutputRecord> &records)
{
    json a = json::array();
    for (const OutputRecord &r : records) {
        a.push_back({{"path", r.path}, {"bytes", r.bytes}, {"hash", r.hash}});
    }
    return a;
}

std::vector<OutputRecord> records_from(const json &line)
{
    std::vector<OutputRecord> out;
    const auto it = line.find("outputs");
    if (it == line.end() || !it->is_array()) {
        return out;
    }
    for (const json &r : *it) {
        if (r.is_object() && r.contains("path") && r["path"].is_string() &&
            !r["path"].get<std::string>().empty() && r.contains("bytes") &&
            r["bytes"].is_number_unsigned() && r.contains("hash") && r["hash"].is_string() &&
            r["hash"].get<std::string>().size() == 16) {
            out.push_back({r["path"].get<std::string>(),
                           r["bytes"].get<std::uint64_t>(),
                           r["hash"].get<std::string>()});
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Status

namespace {

/// squeue's view of the job's tasks: "JOB_TASK" -> state (RUNNING, PENDING...). None without
/// squeue on PATH (docs/FARM.md). A failing squeue throws, or with `tolerant` warns: running
/// chunks would look missing, and resubmit would render them twice.
std::map<std::string, std::string> scheduler_states(const json &job, bool tolerant)
{
    std::map<std::string, std::string> states;
    if (!on_path("squeue")) {
        return states;
    }
    std::string ids;
    for (const json &sub : job["submissions"]) {
        if (sub.contains("array_job")) {
            ids += (ids.empty() ? "" : ",") + sub["array_job"].get<std::string>();
        }
    }
    if (ids.empty()) {
        return states;
    }
    std::string out;
    // The ids are digits (read_job checks them); quoted all the same.
    if (const int rc = capture_status("squeue -h -r -j " + shell_quote(ids) + " -o '%i %T'", out);
        rc != 0) {
        const std::string said = out.substr(0, out.find('\n'));
        const std::string message =
            str_cat("farm: squeue failed (exit status ", rc, said.empty() ? "" : ": ", said, ")");
        if (!tolerant) {
            throw_runtime(message, ": cannot tell running and queued frames from missing ones");
        }
        std::fprintf(
            stderr, "warning: %s: no frame counts as running or queued\n", message.c_str());
        return {};
    }
    std::istringstream lines(out);
    std::string id, state;
    while (lines >> id >> state) {
        states[id] = state;
    }
    return states;
}

}  // namespace

namespace {

/// A log line's reason to be skipped ("" when it is whole): a cut line (a killed task) or one
/// with a bad type; a frame of another job counts as bad too.
std::string bad_log_line(const json &l, const std::map<int, FrameState> &states)
{
    if (l.is_discarded() || !l.is_object() || !l.contains("frame")) {
        return "cut";
    }
    const json &f = l["frame"];
    if (!f.is_number_integer() ||
        (f.is_number_unsigned() ? f.get<unsigned long long>() > INT_MAX
                                : f.get<long long>() < INT_MIN || f.get<long long>() > INT_MAX)) {
        return "\"frame\" is not a frame number";
    }
    if (!states.count(l["frame"].get<int>())) {
        return str_cat("frame ", l["frame"].get<int>(), " is not one of the job's");
    }
    for (const char *key : {"status", "error"}) {
        if (l.contains(key) && !l[key].is_string()) {
            return str_cat("\"", key, "\" is not a string");
        }
    }
    if (l.contains("seconds") && !l["seconds"].is_number()) {
        return "\"seconds\" is not a number";
    }
    return "";
}

}  // namespace

std::map<int, FrameState> frame_states(const json &job,
                                       const fs::path &dir,
                                       const Graph &graph,
                                       bool tolerant)
{
    std::map<int, FrameState> states;
    for (int f : job["frames"].get<std::vector<int>>()) {
        states[f];
    }
    // The latest submission holding each frame, and the log lines (in submission order).
    const json &subs = job["submissions"];
    for (std::size_t s = 0; s < subs.size(); ++s) {
        for (std::size_t k = 0; k < subs[s]["chunks"].size(); ++k) {
            for (int f : subs[s]["chunks"][k].get<std::vector<int>>()) {
                FrameState &st = states[f];
                st = FrameState{};
                st.submission = int(s);
                st.chunk = int(k);
            }
            const fs::path log_path =
                dir / "logs" / ("s" + std::to_string(s) + "-chunk" + std::to_string(k) + ".jsonl");
            std::ifstream log(log_path);
            std::string line;
            for (int number = 1; std::getline(log, line); ++number) {
                const json l = json::parse(line, nullptr, false);
                if (const std::string bad = bad_log_line(l, states); !bad.empty()) {
                    if (bad != "cut") {  // a line cut by a killed task is expected
                        std::fprintf(stderr,
                                     "warning: %s:%d: skipped: %s\n",
                                     log_path.string().c_str(),
                                     number,
                                     bad.c_str());
                    }
                    continue;
                }
                FrameState &st = states[l["frame"].get<int>()];
                if (st.submission != int(s)) {
                    continue;
                }
                st.seconds = l.value("seconds", -1.0);
                st.error = l.value("error", "");
                st.state = l.value("status", "") == "failed" ? "failed" : "logged";
                st.written = st.state == "logged" ? records_from(l) : std::vector<OutputRecord>{};
            }
        }
    }
    const std::map<std::string, std::string> sched = scheduler_states(job, tolerant);
    // Read every output back, frames in parallel (the check job's main cost).
    std::vector<int> numbers;
    for (const auto &[f, st] : states) {
        numbers.push_back(f);
    }
    std::vector<std::string> damaged_of(numbers.size());
    std::vector<char> whole_of(numbers.size(), 0);
    parallel_for(0, int(numbers.size()), [&](int i) {
        const FrameState &st = std::as_const(states).at(numbers[std::size_t(i)]);
        if (st.state != "logged") {
            return;  // no task wrote it (files of an earlier run are not this job's), or it failed
        }
        const std::vector<std::string> outputs = graph.outputs(numbers[std::size_t(i)]);
        const std::vector<OutputRecord> &written = st.written;
        // The task's records, when they name exactly these outputs; else read every pixel.
        bool recorded = written.size() == outputs.size();
        for (const std::string &p : outputs) {
            recorded = recorded && std::any_of(written.begin(),
                                               written.end(),
                                               [&](const OutputRecord &r) { return r.path == p; });
        }
        bool whole = !outputs.empty();
        for (const std::string &p : outputs) {
            std::error_code ec;
            if (!fs::exists(p, ec)) {
                whole = false;
                continue;
            }
            std::string problem;
            if (recorded) {
                const OutputRecord &want =
                    *std::find_if(written.begin(), written.end(), [&](const OutputRecord &r) {
                        return r.path == p;
                    });
                OutputRecord now;
                if (!record_output(p, now)) {
                    problem = p + ": cannot be read";
                } else if (now.bytes != want.bytes) {
                    problem = str_cat(p, ": ", now.bytes, " bytes, the task wrote ", want.bytes);
                } else if (now.hash != want.hash) {
                    problem = p + ": its bytes differ from what the task wrote";
                }
            } else {
                problem = verify_image_file(p);
            }
            if (!problem.empty()) {
                whole = false;
                damaged_of[std::size_t(i)] = problem;
            }
        }
        whole_of[std::size_t(i)] = whole;
    });
    for (std::size_t i = 0; i < numbers.size(); ++i) {
        FrameState &st = states[numbers[i]];
        const bool whole = whole_of[i] != 0;
        const std::string &damaged = damaged_of[i];
        if (whole) {
            st.state = "done";
            st.error.clear();
            continue;
        }
        if (st.state == "failed") {
            continue;
        }
        st.state = "missing";
        st.error = damaged;
        if (st.submission >= 0 && subs[std::size_t(st.submission)].contains("array_job")) {
            const std::string task =
                subs[std::size_t(st.submission)]["array_job"].get<std::string>() + "_" +
                std::to_string(st.chunk);
            if (auto it = sched.find(task); it != sched.end()) {
                const std::string &s = it->second;
                st.state = s == "RUNNING" || s == "COMPLETING"                       ? "running"
                           : s == "PENDING" || s == "CONFIGURING" || s == "REQUEUED" ? "queued"
                                                                                     : "missing";
            }
        }
    }
    return states;
}

namespace {

json status_json(const std::map<int, FrameState> &states)
{
    json frames = json::array();
    std::map<std::string, int> counts = {
        {"done", 0}, {"failed", 0}, {"running", 0}, {"queued", 0}, {"missing", 0}};
    for (const auto &[f, st] : states) {
        ++counts[st.state];
        json j = {{"frame", f}, {"state", st.state}};
        if (!st.error.empty()) {
            j["error"] = st.error;
        }
        if (st.seconds >= 0.0) {
            j["seconds"] = st.seconds;
        }
        frames.push_back(std::move(j));
    }
    return {{"frames", frames}, {"counts", counts}, {"total", states.size()}};
}

std::string summary_line(const json &status)
{
    const json &c = status["counts"];
    std::ostringstream o;
    o << c["done"].get<int>() << "/" << status["total"].get<std::size_t>() << " done, "
      << c["failed"].get<int>() << " failed, " << c["running"].get<int>() << " running, "
      << c["queued"].get<int>() << " queued, " << c["missing"].get<int>() << " missing";
    return o.str();
}

}  // namespace

int status_command(const std::string &dir_text, bool as_json)
{
    const fs::path dir = fs::absolute(dir_text);
    const json job = read_job(dir);
    const Graph graph = load_job_graph(job, dir);
    const json status = status_json(frame_states(job, dir, graph));
    if (as_json) {
        std::printf("%s\n", status.dump(2).c_str());
    } else {
        for (const json &f : status["frames"]) {
            if (f["state"] != "done") {
                std::printf("frame %d: %s%s%s\n",
                            f["frame"].get<int>(),
                            f["state"].get<std::string>().c_str(),
                            f.contains("error") ? ": " : "",
                            f.value("error", "").c_str());
            }
        }
        std::printf("%s\n", summary_line(status).c_str());
    }
    return status["counts"]["done"].get<int>() == int(status["total"].get<std::size_t>()) ? 0 : 1;
}

int check_command(const std::string &dir_text)
{
    const fs::path dir = fs::absolute(dir_text);
    const json job = read_job(dir);
    const Graph graph = load_job_graph(job, dir);
    // The check job runs once the array has ended: a failing squeue only warns there.
    json report = status_json(frame_states(job, dir, graph, /*tolerant=*/true));
    // Time per frame, the slowest frames, and node times summed over every chunk's log.
    std::vector<std::pair<double, int>> times;
    for (const json &f : report["frames"]) {
        if (f.contains("seconds")) {
            times.emplace_back(f["seconds"].get<double>(), f["frame"].get<int>());
        }
    }
    std::sort(times.rbegin(), times.rend());
    json slowest = json::array();
    for (std::size_t i = 0; i < std::min<std::size_t>(5, times.size()); ++i) {
        slowest.push_back({{"frame", times[i].second}, {"seconds", times[i].first}});
    }
    std::map<std::string, double> nodes;
    for (const auto &entry : fs::directory_iterator(dir / "logs")) {
        if (entry.path().string().ends_with(".nodes.json")) {
            std::ifstream in(entry.path());
            const json n = json::parse(in, nullptr, false);
            for (auto it = n.begin(); n.is_object() && it != n.end(); ++it) {
                if (it.value().is_number()) {
                    nodes[it.key()] += it.value().get<double>();
                } else {
                    std::fprintf(stderr,
                                 "warning: %s: \"%s\": not a number of seconds, skipped\n",
                                 entry.path().string().c_str(),
                                 it.key().c_str());
                }
            }
        }
    }
    double total = 0.0;
    for (const auto &[t, f] : times) {
        total += t;
    }
    report["seconds_per_frame"] = times.empty() ? 0.0 : total / double(times.size());
    report["slowest"] = slowest;
    report["node_seconds"] = nodes;
    write_text_file((dir / "report.json").string(), report.dump(2) + "\n");

    std::ostringstream h;
    h << "<!doctype html><meta charset=utf-8><title>posthaste farm report</title>"
      << "<style>body{font-family:sans-serif}td,th{padding:2px 8px;text-align:left}"
      << ".failed{color:#b00}.missing{color:#a60}</style>"
      << "<h1>" << xml_escape(dir.filename().string()) << "</h1><p>" << summary_line(report) << "; "
      << report["seconds_per_frame"].get<double>() << " s per frame</p>"
      << "<h2>Frames not done</h2><table><tr><th>frame<th>state<th>error";
    for (const json &f : report["frames"]) {
        if (f["state"] != "done") {
            h << "<tr class=" << f["state"].get<std::string>() << "><td>" << f["frame"].get<int>()
              << "<td>" << f["state"].get<std::string>() << "<td>"
              << xml_escape(f.value("error", ""));
        }
    }
    h << "</table><h2>Slowest frames</h2><table><tr><th>frame<th>seconds";
    for (const json &s : slowest) {
        h << "<tr><td>" << s["frame"].get<int>() << "<td>" << s["seconds"].get<double>();
    }
    h << "</table><h2>Node time, summed</h2><table><tr><th>node<th>seconds";
    for (const auto &[n, s] : nodes) {
        h << "<tr><td>" << xml_escape(n) << "<td>" << s;
    }
    h << "</table>\n";
    write_text_file((dir / "report.html").string(), h.str());
    std::printf("%s\n", summary_line(report).c_str());
    const bool all_done =
        report["counts"]["done"].get<int>() == int(report["total"].get<std::size_t>());
    return all_done ? 0 : 1;
}

}  // namespace posthaste::cli::farm
