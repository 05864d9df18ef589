// The farm commands without a cluster: stand-in sbatch and squeue scripts on PATH, and job
// directories written or damaged by hand. What --force may replace, what counts as done, a
// failing squeue, damaged job files and log lines, --set values as the tasks read them.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "io/image_file.h"
#include "io/sequence.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;
using test::run_command;

const std::string kBin = POSTHASTE_BINARY;

int line_count(const std::string &s)
{
    return int(std::count(s.begin(), s.end(), '\n'));
}

/// A scratch folder with frames 1-3 of a small input, a graph writing dir/out/o.####.exr, and
/// a bin/ with an sbatch that prints ids 100, 101, ... (or refuses when bin/refuse exists) and
/// an squeue that lists nothing (or exits 3 when bin/sqfail exists).
struct FarmScratch {
    std::string dir, graph, bin, path;

    explicit FarmScratch(const std::string &name) : dir(test::scratch_dir(name))
    {
        for (int f : {1, 2, 3}) {
            write_exr(test::make_sample_frame(32, 16, f),
                      expand_frame_pattern(dir + "/in.####.exr", f),
                      {});
        }
        graph = dir + "/g.json";
        std::ofstream(graph) << R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": ")"
                             << dir << R"(/in.####.exr"}},
            {"id": "out", "type": "write", "inputs": {"image": "src"},
             "params": {"path": ")"
                             << dir << R"(/out/o.####.exr", "passes": "color"}}]})";
        bin = dir + "/bin";
        fs::create_directories(bin);
        std::ofstream(bin + "/sbatch")
            << "#!/bin/sh\nif [ -e " << bin << "/refuse ]; then echo 'sbatch: error: no' >&2; "
            << "exit 1; fi\nn=$(cat " << bin << "/n 2>/dev/null || echo 99)\nn=$((n+1))\n"
            << "echo $n > " << bin << "/n\necho $n\n";
        std::ofstream(bin + "/squeue") << "#!/bin/sh\nif [ -e " << bin
                                       << "/sqfail ]; then echo 'squeue: error: down' >&2; "
                                          "exit 3; fi\n";
        for (const char *p : {"/sbatch", "/squeue"}) {
            fs::permissions(bin + p, fs::perms::owner_all);
        }
        path = "PATH=" + bin + ":$PATH ";
    }
    /// `posthaste farm ARGS` with the stand-ins on PATH, in `cwd` (the scratch folder by default).
    int farm(const std::string &args, std::string *out, const std::string &cwd = "") const
    {
        return run_command(
            "cd '" + (cwd.empty() ? dir : cwd) + "' && " + path + kBin + " farm " + args, out);
    }
    std::string submit(const std::string &job_dir, const std::string &more = "") const
    {
        return "submit " + graph + " --frames 1-3 --job-dir " + job_dir + " " + more;
    }
};

json read_json_file(const std::string &path)
{
    std::ifstream in(path);
    return json::parse(in, nullptr, false);
}

// --force replaced whatever --job-dir named: a folder of the user's, the current folder, the
// graph's folder, the outputs; and a refused sbatch then left neither job.
TEST(FarmCli, ForceReplacesOnlyAJobDirectoryAndOnlyOnceTheNewJobIsQueued)
{
    const FarmScratch s("farm_force");
    std::string out;
    fs::create_directories(s.dir + "/mine");
    std::ofstream(s.dir + "/mine/precious.txt") << "keep\n";
    EXPECT_EQ(s.farm(s.submit(s.dir + "/mine", "--force"), &out), 2) << out;
    EXPECT_NE(out.find("mine is not a posthaste job directory"), std::string::npos) << out;
    EXPECT_EQ(line_count(out), 1) << out;
    EXPECT_TRUE(fs::exists(s.dir + "/mine/precious.txt"));
    EXPECT_EQ(s.farm(s.submit(s.graph, "--force"), &out), 2) << out;  // the graph file itself
    EXPECT_NE(out.find("is not a job directory"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(s.graph));

    // A job directory, queued; then folders holding job.json that are also the current folder,
    // the graph's folder or the outputs' folder.
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job"), &out), 0) << out;
    EXPECT_EQ(read_json_file(s.dir + "/job/job.json")["submissions"][0]["array_job"], "100");
    EXPECT_EQ(s.farm(s.submit(".", "--force"), &out, s.dir + "/job"), 2) << out;
    EXPECT_NE(out.find("is the current folder"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(s.dir + "/job/job.json"));
    std::ofstream(s.dir + "/job.json") << "{}\n";  // the scratch folder holds the graph
    EXPECT_EQ(s.farm(s.submit(s.dir, "--force"), &out, "/"), 2) << out;
    EXPECT_NE(out.find("holds the graph"), std::string::npos) << out;
    fs::create_directories(s.dir + "/out");
    std::ofstream(s.dir + "/out/job.json") << "{}\n";
    EXPECT_EQ(s.farm(s.submit(s.dir + "/out", "--force --dry-run"), &out), 2) << out;
    EXPECT_NE(out.find("holds the output " + s.dir + "/out/o.0001.exr"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(s.dir + "/out/job.json"));

    // sbatch refuses: the old job stays as it was.
    std::ofstream(s.bin + "/refuse") << "";
    EXPECT_EQ(s.farm(s.submit(s.dir + "/job", "--force"), &out), 1) << out;
    EXPECT_NE(out.find("sbatch failed"), std::string::npos) << out;
    EXPECT_EQ(read_json_file(s.dir + "/job/job.json")["submissions"][0]["array_job"], "100");
    fs::remove(s.bin + "/refuse");
    // Queued: replaced, and nothing left beside it; an empty folder may be replaced too.
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job/", "--force"), &out), 0) << out;
    EXPECT_EQ(read_json_file(s.dir + "/job/job.json")["submissions"][0]["array_job"], "102");
    for (const auto &e : fs::directory_iterator(s.dir)) {
        EXPECT_EQ(e.path().filename().string().find(".job."), std::string::npos) << e.path();
    }
    fs::create_directories(s.dir + "/empty");
    EXPECT_EQ(s.farm(s.submit(s.dir + "/empty", "--force"), &out), 0) << out;
    EXPECT_TRUE(fs::exists(s.dir + "/empty/job.json"));
    // The task's --threads range: --cpus-per-task above it failed every task.
    EXPECT_EQ(s.farm(s.submit(s.dir + "/cpus", "--cpus-per-task 2000"), &out), 2) << out;
    EXPECT_FALSE(fs::exists(s.dir + "/cpus"));
}

// Done needs a task's log line: files of an earlier run at the output paths are not this job's
// (5/5 done for frames no task ran). A failing squeue is an error, not "nothing running".
TEST(FarmCli, LeftoverOutputsAreNotDoneAndAFailingSqueueIsAnError)
{
    const FarmScratch s("farm_status");
    std::string out;
    ASSERT_EQ(run_command(kBin + " run " + s.graph + " --frames 1-3", &out), 0) << out;
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job"), &out), 0) << out;
    EXPECT_EQ(s.farm("status " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("0/3 done, 0 failed, 0 running, 0 queued, 3 missing"), std::string::npos)
        << out;
    // A log line without records (an older version's) is read back whole: done.
    std::ofstream(s.dir + "/job/logs/s0-chunk0.jsonl")
        << R"({"frame": 1, "start": 0, "seconds": 1.5, "status": "done"})"
        << "\n";
    EXPECT_EQ(s.farm("status " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("1/3 done, 0 failed, 0 running, 0 queued, 2 missing"), std::string::npos)
        << out;

    std::ofstream(s.bin + "/sqfail") << "";
    EXPECT_EQ(s.farm("status " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("farm: squeue failed (exit status 3: squeue: error: down)"),
              std::string::npos)
        << out;
    EXPECT_EQ(line_count(out), 1) << out;
    EXPECT_EQ(s.farm("resubmit " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("squeue failed"), std::string::npos) << out;
    EXPECT_EQ(read_json_file(s.dir + "/job/job.json")["submissions"].size(), 1u);
    // The check job runs after the array: there it only warns.
    EXPECT_EQ(s.farm("check " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("warning: farm: squeue failed"), std::string::npos) << out;
    EXPECT_NE(out.find("1/3 done"), std::string::npos) << out;
}

// Damaged job files: a SIGSEGV (a missing key read from a const json), or nlohmann's messages;
// an array_job went into squeue's command line as it was.
TEST(FarmCli, ADamagedJobFileIsOneLineNamingTheKey)
{
    const FarmScratch s("farm_damaged");
    std::string out;
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job"), &out), 0) << out;
    const std::string file = s.dir + "/job/job.json";
    json good = read_json_file(file);
    const auto expect = [&](const json &job, const std::string &message) {
        std::ofstream(file) << job.dump();
        for (const char *cmd : {"status ", "check ", "resubmit --dry-run "}) {
            EXPECT_EQ(s.farm(cmd + s.dir + "/job", &out), 1) << cmd << job << out;
            EXPECT_NE(out.find(file + ": " + message), std::string::npos) << cmd << job << out;
            EXPECT_EQ(line_count(out), 1) << out;
        }
    };
    expect(json::parse(R"({"cwd":"/tmp","frames":[1],"submissions":[{"chunks":[[1]]},{}]})"),
           "/submissions/1/chunks: missing");
    expect(json::object(), "/cwd: missing");
    json j = good;
    j["cwd"] = 5;
    expect(j, "/cwd: expected a string");
    j = good;
    j["submissions"][0]["chunks"][0][0] = "1";
    expect(j, "/submissions/0/chunks/0: expected an array of frame numbers");
    j = good;
    j["submissions"][0]["chunks"][0][0] = 77;
    expect(j, "/submissions/0/chunks/0: expected frames of /frames (77 is not one)");
    j = good;
    j["submissions"][0]["array_job"] = "1 -o x; touch " + s.dir + "/PWN";
    expect(j, "/submissions/0/array_job: expected a Slurm job id (digits)");
    EXPECT_FALSE(fs::exists(s.dir + "/PWN"));
    j = good;
    j["slurm"]["cpus_per_task"] = "2";
    expect(j, "/slurm/cpus_per_task: expected a whole number of at least 0");
}

// Log lines with a bad type (a raw type_error before), and a frame that is not the job's (an
// extra frame counted, and resubmitted), are skipped with a warning naming the line.
TEST(FarmCli, BadLogLinesAreSkippedWithAWarning)
{
    const FarmScratch s("farm_loglines");
    std::string out;
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job"), &out), 0) << out;
    ASSERT_EQ(run_command(kBin + " run " + s.graph + " --frames 1-3", &out), 0) << out;
    const std::string log = s.dir + "/job/logs/s0-chunk0.jsonl";
    std::ofstream(log) << R"({"frame": "1", "status": "done"})"
                       << "\n"
                       << R"({"frame": 2, "seconds": "fast", "status": "done"})"
                       << "\n"
                       << R"({"frame": 77, "seconds": 1, "status": "done"})"
                       << "\n"
                       << R"({"frame": 3, "seconds": 2, "status": "done"})"
                       << "\n"
                       << R"({"frame": 1, "sec)";
    for (const char *cmd : {"status ", "check ", "resubmit --dry-run "}) {
        EXPECT_EQ(s.farm(cmd + s.dir + "/job", &out),
                  std::string(cmd) == "resubmit --dry-run " ? 0 : 1)
            << cmd << out;
        EXPECT_EQ(out.find("json.exception"), std::string::npos) << cmd << out;
        EXPECT_NE(out.find("warning: " + log + ":1: skipped: \"frame\" is not a frame number"),
                  std::string::npos)
            << cmd << out;
        EXPECT_NE(out.find(log + ":2: skipped: \"seconds\" is not a number"), std::string::npos)
            << out;
        EXPECT_NE(out.find(log + ":3: skipped: frame 77 is not one of the job's"),
                  std::string::npos)
            << out;
        EXPECT_EQ(out.find(":5: skipped"), std::string::npos) << out;  // a cut line: silent
    }
    EXPECT_EQ(s.farm("status " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("1/3 done, 0 failed, 0 running, 0 queued, 2 missing"), std::string::npos)
        << out;
    EXPECT_EQ(s.farm("resubmit --dry-run " + s.dir + "/job", &out), 0) << out;
    EXPECT_NE(out.find("would resubmit frames 1,2 in"), std::string::npos) << out;
    std::ofstream(s.dir + "/job/logs/s0-chunk0.nodes.json") << R"j({"src (read)": "x"})j";
    EXPECT_EQ(s.farm("check " + s.dir + "/job", &out), 1) << out;
    EXPECT_NE(out.find("\"src (read)\": not a number of seconds, skipped"), std::string::npos)
        << out;
    EXPECT_TRUE(fs::exists(s.dir + "/job/report.html")) << out;
}

// A task that cannot write its log said it succeeded: its frames then count as never run.
TEST(FarmCli, ATaskThatCannotWriteItsLogFails)
{
    const FarmScratch s("farm_task_log");
    std::string out;
    ASSERT_EQ(s.farm(s.submit(s.dir + "/job"), &out), 0) << out;
    fs::remove_all(s.dir + "/job/logs");
    EXPECT_EQ(s.farm("task " + s.dir + "/job --chunk 0 --threads 1", &out), 1) << out;
    EXPECT_NE(out.find(s.dir + "/job/logs/s0-chunk0.jsonl: cannot write the task's log"),
              std::string::npos)
        << out;
    EXPECT_FALSE(fs::exists(s.dir + "/out/o.0001.exr")) << "it ran without a log";
}

// --set as `run` types it: 6 for a string parameter was written as the number 6, which the
// written graph's load (and every task's) refused.
TEST(FarmCli, SetValuesAreWrittenAsRunTypesThem)
{
    const FarmScratch s("farm_sets");
    const std::string graph = s.dir + "/relight.json";
    std::ofstream(graph) << R"({"frames": "1-2", "nodes": [
        {"id": "scene", "type": "render", "params": {"scene": ")"
                         << POSTHASTE_TEST_DIR << R"(/../samples/scenes/minecrappy.json",
         "width": 32, "height": 18}},
        {"id": "relight", "type": "relight", "inputs": {"image": "scene"},
         "params": {"mode": "add", "lights": [{"type": "point", "position": [61, 18, 62],
                    "intensity": 25}]}},
        {"id": "exr", "type": "write", "inputs": {"image": "relight"},
         "params": {"path": "rl/out.####.exr", "passes": "color"}}]})";
    std::string out;
    const std::string sets = " -s relight.toon_ids=6 -s 'exr.passes=\"color\"' -s scene.width=40";
    ASSERT_EQ(run_command(kBin + " run " + graph + " --dry-run" + sets, &out), 0) << out;
    ASSERT_EQ(s.farm("submit " + graph + " --job-dir " + s.dir + "/job" + sets, &out), 0) << out;
    const json g = read_json_file(s.dir + "/job/graph.json");
    EXPECT_EQ(g["nodes"][1]["params"]["toon_ids"], "6") << g;
    EXPECT_EQ(g["nodes"][2]["params"]["passes"], "color") << g;
    EXPECT_EQ(g["nodes"][0]["params"]["width"], 40) << g;
}

// A "%" in the job directory went into the log pattern as Slurm's own ("job%a" named a log per
// task elsewhere); a backslash turns Slurm's patterns off (every task's log in one file).
TEST(FarmCli, JobDirectoryNamesAreLiteralInSlurmsLogPatterns)
{
    const FarmScratch s("farm_percent");
    std::string out;
    ASSERT_EQ(s.farm(s.submit(s.dir + "/50%all"), &out), 0) << out;
    std::ifstream run(s.dir + "/50%all/run-s0.sbatch");
    const std::string script((std::istreambuf_iterator<char>(run)), {});
    EXPECT_NE(script.find("#SBATCH --output=\"" + s.dir + "/50%%all/logs/slurm-s0-%a.out\""),
              std::string::npos)
        << script;
    std::ifstream check(s.dir + "/50%all/check-s0.sbatch");
    const std::string check_text((std::istreambuf_iterator<char>(check)), {});
    EXPECT_NE(check_text.find("/50%%all/logs/check-s0.out"), std::string::npos) << check_text;
    EXPECT_EQ(s.farm(s.submit(s.dir + "/a\\\\b"), &out), 2) << out;
    EXPECT_NE(out.find("a backslash in the job directory's name"), std::string::npos) << out;
    EXPECT_EQ(line_count(out), 1) << out;
}

}  // namespace
}  // namespace posthaste
