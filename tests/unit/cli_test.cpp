// The command line as a user meets it: exit codes, one-line errors, missing frames reported by
// number, --skip-bad-frames, --set echoing the command line, info's pass mapping, nodes docs.

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "graph/run.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;
using test::run_command;

const std::string kBin = POSTHASTE_BINARY;

int line_count(const std::string &s)
{
    return int(std::count(s.begin(), s.end(), '\n'));
}

std::string write_graph(const std::string &dir)
{
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")"
                         << dir << R"(/in.####.exr"}},
        {"id": "cc", "type": "ocio", "inputs": {"image": "src"}},
        {"id": "out", "type": "write", "inputs": {"image": "cc"},
         "params": {"path": ")"
                         << dir << R"(/out/o.####.exr", "passes": "color"}},
        {"id": "png", "type": "write", "inputs": {"image": "src"},
         "params": {"path": ")"
                         << dir << R"(/out/p.####.png"}}]})";
    return graph;
}

void write_inputs(const std::string &dir, std::initializer_list<int> frames)
{
    for (int f : frames) {
        write_exr(
            test::make_sample_frame(32, 16, f), expand_frame_pattern(dir + "/in.####.exr", f), {});
    }
}

/// dir/g.json: dir/in.####.exr -> dof -> dir/OUTPUT; its path.
std::string write_dof_graph(const std::string &dir, const std::string &output)
{
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")"
                                   << dir << R"(/in.####.exr"}},
        {"id": "d", "type": "dof", "inputs": {"image": "in"}, "params": {}},
        {"id": "out", "type": "write", "inputs": {"image": "d"},
         "params": {"path": ")" << dir
                                   << "/" << output << R"("}}]})";
    return dir + "/g.json";
}

TEST(Cli, RunsFramesFoundOnDisk)
{
    const std::string dir = test::scratch_dir("cli_run");
    write_inputs(dir, {1, 2, 3});
    const std::string graph = write_graph(dir);
    std::string out;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 2 --jobs 2", &out), 0) << out;
    for (int f : {1, 2, 3}) {
        EXPECT_TRUE(fs::exists(expand_frame_pattern(dir + "/out/o.####.exr", f))) << f;
        EXPECT_TRUE(fs::exists(expand_frame_pattern(dir + "/out/p.####.png", f))) << f;
    }
    EXPECT_NE(out.find("3 frame(s)"), std::string::npos) << out;
    EXPECT_NE(out.find("cc"), std::string::npos) << out;  // per-node timing table
    const Frame o = read_frame(dir + "/out/o.0002.exr", nullptr, 2);
    EXPECT_EQ(o.pass_names(), std::vector<std::string>{"color"});
    EXPECT_TRUE(o.camera.world_to_ndc.has_value());  // header carried through

    ASSERT_EQ(run_command(kBin + " run " + graph + " --dry-run", &out), 0) << out;
    EXPECT_NE(out.find("valid; 3 frame(s)"), std::string::npos) << out;
    // A dry run checks every requested frame's input (a run reports a missing one by number
    // when it reaches it, or passes over it with --skip-bad-frames); a frame listed twice runs
    // once.
    EXPECT_EQ(run_command(kBin + " run " + graph + " --dry-run --frames 1-5", &out), 1) << out;
    EXPECT_NE(out.find("node \"src\" (read): no input file for 2 requested frames (first: " + dir +
                       "/in.0004.exr)"),
              std::string::npos)
        << out;
    ASSERT_EQ(
        run_command(kBin + " run " + graph + " --dry-run --frames 1-5 --skip-bad-frames", &out), 0)
        << out;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --dry-run --frames 3,1-3,2", &out), 0) << out;
    EXPECT_NE(out.find("valid; 3 frame(s)"), std::string::npos) << out;
}

// Options that cannot apply are usage errors, not ignored: a truth option without its truth, a
// --size past int's range (it wrapped to a 64x36 frame), a test suite's --only name that no
// graph has, --update with a report, a NaN for a number, a NAME.test.json without its graph.
TEST(Cli, RenderAndTestOptionsThatCannotApply)
{
    const std::string dir = test::scratch_dir("cli_cannot_apply");
    const std::string scene = std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/cube.json";
    const std::string render = kBin + " render " + scene + " -o " + dir + "/r.####.exr -f 1 ";
    std::string out;
    EXPECT_EQ(run_command(render + "--size 4294967360x36", &out), 2) << out;
    EXPECT_NE(out.find("--size: expected WIDTHxHEIGHT"), std::string::npos) << out;
    EXPECT_EQ(run_command(render + "--size 16x9 --samples 4", &out), 2) << out;
    EXPECT_NE(out.find("--samples applies only to --truth or --probe"), std::string::npos) << out;
    EXPECT_EQ(run_command(render + "--size 16x9 --truth motion --ao-radius 2", &out), 2) << out;
    // A NaN passed CLI11's range test (every comparison with it is false) and reached the node
    // as JSON null: "overscan: expected a number, got null".
    EXPECT_EQ(run_command(kBin + " render " + scene + " -o '' -f 1 --size 16x9", &out), 2) << out;
    EXPECT_NE(out.find("--output: an empty value"), std::string::npos) << out;
    EXPECT_EQ(run_command(render + "--size 16x9 --overscan nan", &out), 2) << out;
    EXPECT_NE(out.find("--overscan: expected a number in 0..4096, got \"nan\""), std::string::npos)
        << out;
    EXPECT_FALSE(fs::exists(dir + "/r.0001.exr"));
    fs::create_directories(dir + "/suite");
    std::ofstream(dir + "/suite/a.json") << "{}";
    EXPECT_EQ(run_command(kBin + " test " + dir + "/suite --only a nosuch", &out), 2) << out;
    EXPECT_NE(out.find("--only names \"nosuch\""), std::string::npos) << out;
    EXPECT_EQ(
        run_command(kBin + " test " + dir + "/suite --update --junit " + dir + "/j.xml", &out), 2)
        << out;
    // A spec left behind by a renamed graph: its thresholds applied to nothing, and the run passed.
    std::ofstream(dir + "/suite/b.test.json") << "{\"frames\": \"1\"}";
    EXPECT_EQ(run_command(kBin + " test " + dir + "/suite", &out), 2) << out;
    EXPECT_NE(out.find("b.test.json: no graph b.json beside it"), std::string::npos) << out;
}

// What a command prints must arrive: `nodes`, `--help` and a diff's report into a full disk
// exited 0 (or diff's verdict) with nothing written.
TEST(Cli, OutputThatCannotReachStandardOutputFails)
{
    std::string out;
    EXPECT_EQ(run_command("{ " + kBin + " nodes > /dev/full; }", &out), 1) << out;
    EXPECT_NE(out.find("error: standard output: No space left on device"), std::string::npos)
        << out;
    EXPECT_EQ(run_command("{ " + kBin + " nodes blur --help > /dev/full; }", &out), 1) << out;
    EXPECT_EQ(run_command("{ " + kBin + " nodes > /dev/null; }", &out), 0) << out;
    const std::string dir = test::scratch_dir("cli_stdout_full");
    const std::string scene = std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/cube.json";
    ASSERT_EQ(
        run_command(kBin + " render " + scene + " -o " + dir + "/r.####.exr -f 1 --size 8x8 -q",
                    &out),
        0)
        << out;
    const std::string frame = dir + "/r.0001.exr";
    EXPECT_EQ(run_command("{ " + kBin + " diff " + frame + " " + frame + " > /dev/full; }", &out),
              4)
        << out;
}

TEST(Cli, GraphPathsResolveAgainstTheGraphsFolder)
{
    // A graph in shot/comp/ reads ../plates/in.####.exr and writes out/o.####.exr: run from
    // another folder, both resolve against shot/comp/. A --set path stays relative to the
    // current folder, as everything else on a command line is.
    const std::string dir = test::scratch_dir("cli_relative");
    fs::create_directories(dir + "/shot/comp");
    fs::create_directories(dir + "/shot/plates");
    fs::create_directories(dir + "/elsewhere");
    write_inputs(dir + "/shot/plates", {1, 2});
    std::ofstream(dir + "/shot/comp/g.json") << R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "../plates/in.####.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "src"},
         "params": {"path": "out/o.####.exr", "passes": "color"}},
        {"id": "png", "type": "write", "inputs": {"image": "src"},
         "params": {"path": "out/p.####.png"}}]})";
    std::string out;
    ASSERT_EQ(run_command("cd " + dir + "/elsewhere && " + kBin + " run ../shot/comp/g.json " +
                              "--set png.path=previews/p.####.png",
                          &out),
              0)
        << out;
    for (int f : {1, 2}) {
        EXPECT_TRUE(fs::exists(expand_frame_pattern(dir + "/shot/comp/out/o.####.exr", f))) << f;
        EXPECT_TRUE(fs::exists(expand_frame_pattern(dir + "/elsewhere/previews/p.####.png", f)))
            << f;
    }
    // A missing input names the resolved path.
    fs::remove(dir + "/shot/plates/in.0002.exr");
    ASSERT_NE(run_command("cd " + dir + "/elsewhere && " + kBin + " run ../shot/comp/g.json " +
                              "--frames 2",
                          &out),
              0);
    EXPECT_NE(out.find("shot/plates/in.0002.exr"), std::string::npos) << out;
    // A graph from a pipe resolves against the current folder (against /dev it named nothing).
    EXPECT_EQ(run_command("cd " + dir + "/shot/comp && cat g.json | " + kBin +
                              " run /dev/stdin --frames 1 --dry-run",
                          &out),
              0)
        << out;
    // "base_dir" in the graph moves the anchor (the farm's copy of a graph uses it).
    std::ofstream(dir + "/moved.json") << R"({"base_dir": "shot/comp", "nodes": [
        {"id": "src", "type": "read", "params": {"path": "../plates/in.####.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "src"},
         "params": {"path": "moved/o.####.exr", "passes": "color"}}]})";
    ASSERT_EQ(run_command(kBin + " run " + dir + "/moved.json --frames 1", &out), 0) << out;
    EXPECT_TRUE(fs::exists(dir + "/shot/comp/moved/o.0001.exr"));
}

TEST(Cli, TheDemoGraphRunsFromAnotherFolder)
{
    const std::string dir = test::scratch_dir("cli_demo_elsewhere");
    const std::string graph =
        (fs::path(POSTHASTE_TEST_DIR) / "../graphs/minecrappy.json").lexically_normal().string();
    std::string out;
    // Outputs go to the scratch folder (--set, relative to the current folder); the scene is
    // found through the graph's own relative path.
    ASSERT_EQ(run_command("cd " + dir + " && " + kBin + " run " + graph +
                              " --frames 1 --set scene.width=64 --set scene.height=36 "
                              "--set exr.path=a.####.exr --set preview.path=a.####.png "
                              "--set hatched_preview.path=b.####.png",
                          &out),
              0)
        << out;
    EXPECT_TRUE(fs::exists(dir + "/a.0001.exr")) << out;
}

TEST(Cli, ProgressLineOnATerminalPlainLinesOtherwise)
{
    const std::string dir = test::scratch_dir("cli_progress");
    write_inputs(dir, {1, 2, 3});
    const std::string graph = write_graph(dir);
    // `script` gives the command a terminal (util-linux, in every Debian).
    std::string tty;
    ASSERT_EQ(run_command("script -qec '" + kBin + " run " + graph + " --jobs 1' /dev/null", &tty),
              0)
        << tty;
    EXPECT_NE(tty.find("\r[##########--------------------] 1/3 frames"), std::string::npos) << tty;
    EXPECT_NE(tty.find("3/3 frames"), std::string::npos) << tty;
    EXPECT_NE(tty.find(" fps  ETA "), std::string::npos) << tty;
    EXPECT_NE(tty.find("slowest: "), std::string::npos) << tty;
    EXPECT_EQ(tty.find("frame 1 done in"), std::string::npos) << tty;
    // Not a terminal: one plain line per frame, no carriage returns.
    std::string plain;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --jobs 1", &plain), 0) << plain;
    EXPECT_NE(plain.find("frame 1 done in"), std::string::npos) << plain;
    EXPECT_EQ(plain.find('\r'), std::string::npos) << plain;
    // --quiet: neither.
    std::string quiet;
    ASSERT_EQ(run_command("script -qec '" + kBin + " run " + graph + " --jobs 1 --quiet' /dev/null",
                          &quiet),
              0);
    EXPECT_EQ(quiet.find("frames"), std::string::npos) << quiet;
}

TEST(Cli, MissingFrameIsReportedByNumber)
{
    const std::string dir = test::scratch_dir("cli_missing");
    write_inputs(dir, {1, 2, 4});
    const std::string graph = write_graph(dir);
    std::string out;
    EXPECT_EQ(run_command(kBin + " run " + graph + " --frames 1-4 --jobs 1 -q", &out), 1) << out;
    EXPECT_NE(
        out.find("error: node \"src\" (read), frame 3: " + dir + "/in.0003.exr: no such file"),
        std::string::npos)
        << out;
    EXPECT_EQ(line_count(out), 1) << out;
    EXPECT_FALSE(fs::exists(dir + "/out/o.0004.exr"));  // the run stopped at frame 3

    EXPECT_EQ(run_command(kBin + " run " + graph + " --frames 1-4 --skip-bad-frames", &out), 0)
        << out;
    EXPECT_NE(out.find("warning: frame 3 skipped"), std::string::npos) << out;
    EXPECT_NE(out.find("1 skipped"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(dir + "/out/o.0004.exr"));

    // An output that cannot be written is no bad input: --skip-bad-frames (with --keep-going
    // or not) still fails the run, naming it (it exited 0).
    fs::remove(dir + "/out/o.0002.exr");
    fs::create_directories(dir + "/out/o.0002.exr");
    for (const char *more : {"", " --keep-going"}) {
        EXPECT_EQ(
            run_command(kBin + " run " + graph + " --frames 1-4 --skip-bad-frames -q" + more, &out),
            1)
            << more << out;
        EXPECT_NE(out.find("error: node \"out\" (write), frame 2: " + dir + "/out/o.0002.exr"),
                  std::string::npos)
            << more << out;
    }
    // A string parameter given as a JSON string: the quotes are JSON's, not the value's.
    EXPECT_EQ(run_command(kBin + " run " + graph + " --dry-run --set 'cc.to=\"srgb\"'", &out), 0)
        << out;
}

TEST(Cli, UsageErrorsAreOneLineWithExitCodeTwo)
{
    const std::string dir = test::scratch_dir("cli_usage");
    write_inputs(dir, {1});
    const std::string graph = write_graph(dir);
    std::string out;
    EXPECT_EQ(run_command(kBin + " run " + graph + " --set cc.to=srgbb", &out), 2) << out;
    EXPECT_NE(out.find("param \"to\": unknown color space \"srgbb\""), std::string::npos) << out;
    EXPECT_NE(out.find("[command line: "), std::string::npos) << out;
    EXPECT_EQ(line_count(out), 1) << out;
    // A byte that is not UTF-8 (in a file name, or in what nlohmann last read) is printed in
    // hex: the terminal and a log got the raw byte.
    std::ofstream(dir + "/bad_byte.json") << "{\"nodes\": [{\"id\": \"a\xff\"}]}";
    EXPECT_EQ(run_command(kBin + " run " + dir + "/bad_byte.json", &out), 2) << out;
    EXPECT_NE(out.find("last read: '\"a\\xff'"), std::string::npos) << out;
    EXPECT_EQ(out.find('\xff'), std::string::npos) << out;
    // A count that is not a number says so (it was "Value abc not in range 0 to 1024").
    EXPECT_EQ(run_command(kBin + " run " + graph + " --threads abc", &out), 2) << out;
    EXPECT_NE(out.find("--threads: expected a whole number in 0..1024, got \"abc\""),
              std::string::npos)
        << out;

    EXPECT_EQ(run_command(kBin + " run " + dir + "/nope.json", &out), 2) << out;
    EXPECT_NE(out.find("nope.json: cannot open graph file"), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " run " + dir, &out), 2) << out;  // (it read as empty JSON)
    EXPECT_NE(out.find(": is a directory, not a graph file"), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " run " + graph + " --frames 3-1", &out), 2) << out;
    EXPECT_EQ(run_command(kBin + " run " + graph + " --jobs -4", &out), 2) << out;
    EXPECT_EQ(run_command(kBin + " frobnicate", &out), 2) << out;
    EXPECT_NE(out.find("unknown command \"frobnicate\" (commands: run, render"), std::string::npos)
        << out;
    EXPECT_EQ(line_count(out), 1) << out;
    // A pass listed twice is the graph's mistake, found before anything runs.
    EXPECT_EQ(run_command(kBin + " render " + test::scene_path("minecrappy.json") +
                              " --passes color,depth,color --frames 1 --size 16x16 -o " + dir +
                              "/r.####.exr",
                          &out),
              2)
        << out;
    // In the command's terms: the option, not the location in the command's own graph.
    EXPECT_NE(out.find("error: render --passes: lists \"color\" twice"), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " render " + dir + " --frames 1 -o " + dir + "/r.exr", &out), 2)
        << out;
    EXPECT_NE(out.find("error: render: " + dir + ": is a folder, not a scene file"),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find("error: ", 1), std::string::npos) << out;  // said once
    EXPECT_EQ(run_command(kBin + " render " + test::scene_path("minecrappy.json") +
                              " --frames 1-2 --size 16x16 -o " + dir + "/r.exr",
                          &out),
              2)
        << out;
    EXPECT_NE(out.find("error: render -o: \"" + dir + "/r.exr\" has no frame placeholder"),
              std::string::npos)
        << out;
    EXPECT_EQ(run_command(kBin + " render " + test::scene_path("minecrappy.json") +
                              " --passes colr --frames 1 --size 16x16 -o " + dir + "/r.####.exr",
                          &out),
              2)
        << out;
    EXPECT_NE(out.find("error: render --passes: the renderer makes no pass \"colr\" (it makes: "),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find("downstream"), std::string::npos) << out;
    // A bound is said as a bound (CLI11's own check wrote out DBL_MAX).
    EXPECT_EQ(run_command(kBin + " diff a.exr b.exr --ppd 0", &out), 2) << out;
    EXPECT_NE(out.find("--ppd: must be a number above 0 and at most 1000, got 0"),
              std::string::npos)
        << out;
    EXPECT_EQ(run_command(kBin + " diff a.exr b.exr --diff-scale -1", &out), 2) << out;
    EXPECT_NE(out.find("--diff-scale: must be a number of at least 0, got -1"), std::string::npos)
        << out;
    EXPECT_EQ(run_command(kBin + " nodes mergee", &out), 2) << out;
    EXPECT_NE(out.find("did you mean \"merge\""), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " --help", &out), 0);
    EXPECT_EQ(run_command(kBin + " run --help", &out), 0);
    EXPECT_NE(out.find("--skip-bad-frames"), std::string::npos);
    EXPECT_EQ(run_command(kBin + " --version", &out), 0);
    EXPECT_NE(out.find("posthaste 0."), std::string::npos);
    // The SIMD switch: its two values run, anything else is refused before any work.
    EXPECT_EQ(run_command("POSTHASTE_SIMD=avx512 " + kBin + " run " + graph, &out), 2) << out;
    EXPECT_NE(out.find("POSTHASTE_SIMD: unknown value \"avx512\""), std::string::npos) << out;
    EXPECT_EQ(line_count(out), 1) << out;
    EXPECT_EQ(run_command("POSTHASTE_SIMD=scalar " + kBin + " nodes merge", &out), 0) << out;
    EXPECT_EQ(run_command("POSTHASTE_SIMD=avx2 " + kBin + " nodes merge", &out), 0) << out;
}

TEST(Cli, MemoryBudgetStopsAFrameBeforeItIsAllocated)
{
    const std::string dir = test::scratch_dir("cli_budget");
    const std::string bin = POSTHASTE_BINARY;
    std::string out;
    // A 16384x16384 all-pass render (inside the declared size range) under a 1 GiB budget: an
    // error from the estimate, before any pixel is allocated, nothing written.
    const int rc = run_command(bin + " render " + std::string(POSTHASTE_TEST_DIR) +
                                   "/../samples/scenes/minecrappy.json -o " + dir +
                                   "/big.####.exr --frames 1 --size 16384x16384 --max-memory 1G",
                               &out);
    EXPECT_EQ(rc, 1) << out;
    EXPECT_NE(out.find("a 16384x16384 frame (supersample 1) needs about"), std::string::npos)
        << out;
    EXPECT_NE(out.find("over --max-memory 1024 MiB"), std::string::npos) << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
    EXPECT_FALSE(fs::exists(dir + "/big.0001.exr"));
    // The allocation itself is budgeted too: a read -> dof graph under 64 KiB.
    Frame f = test::make_sample_frame(64, 64, 1);
    write_exr(f, dir + "/in.0001.exr", {});
    write_dof_graph(dir, "out.####.exr");
    EXPECT_EQ(run_command(bin + " run " + dir + "/g.json --frames 1 --max-memory 64K", &out), 1)
        << out;
    EXPECT_NE(out.find("memory budget: a 64x64x"), std::string::npos) << out;
    EXPECT_NE(out.find("over --max-memory 64 KiB"), std::string::npos) << out;
    EXPECT_EQ(run_command(bin + " run " + dir + "/g.json --frames 1 --max-memory 1", &out), 1)
        << out;
    EXPECT_NE(out.find("over --max-memory 1 byte ("), std::string::npos) << out;  // not "0 KiB"
    EXPECT_EQ(run_command(bin + " run " + dir + "/g.json --frames 1 --max-memory lots", &out), 2)
        << out;
    EXPECT_EQ(run_command(bin + " run " + dir + "/g.json --frames 1 --max-memory 1G", &out), 0)
        << out;
}

// The default jobs give each frame two threads or more, one job at least and four at most; the
// summary of a run without --jobs says what it took.
TEST(Cli, DefaultJobsGiveEachFrameTwoThreads)
{
    const int want[][2] = {{1, 1}, {2, 1}, {3, 1}, {4, 2}, {5, 2}, {6, 3}, {8, 4}, {64, 4}};
    for (const auto &[threads, jobs] : want) {
        EXPECT_EQ(default_jobs(threads), jobs) << threads << " threads";
    }
    const std::string dir = test::scratch_dir("cli_jobs_default");
    write_inputs(dir, {1, 2});
    const std::string graph = write_graph(dir);
    std::string out;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 4", &out), 0) << out;
    EXPECT_NE(out.find("2 job(s), 4 thread(s)"), std::string::npos) << out;
}

TEST(Cli, JobsAutoTakesAThreadEachUnlessTheBudgetHoldsFewer)
{
    const std::string dir = test::scratch_dir("cli_jobs_auto");
    write_inputs(dir, {1, 2, 3, 4, 5});
    const std::string graph = write_graph(dir);
    std::string out;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 3 --jobs 1 --quiet", &out), 0)
        << out;
    const std::string reference = dir + "/ref";
    fs::rename(dir + "/out", reference);
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 3 --jobs auto", &out), 0) << out;
    EXPECT_NE(out.find("--jobs auto: 3 (3 thread(s); a frame peaked at "), std::string::npos)
        << out;
    EXPECT_NE(out.find("5 frame(s) in"), std::string::npos) << out;
    EXPECT_NE(out.find("3 job(s), 3 thread(s)"), std::string::npos) << out;
    for (int f = 1; f <= 5; ++f) {  // the same bits as one frame at a time
        const std::string name = expand_frame_pattern("/o.####.exr", f);
        std::string diff;
        EXPECT_EQ(run_command(kBin + " diff " + reference + name + " " + dir + "/out" + name +
                                  " --fail 0 --quiet",
                              &diff),
                  0)
            << f << ": " << diff;
    }
    // A budget a third larger than the first frame's peak holds one frame at a time (3/4 of it
    // is under a frame).
    const std::size_t at = out.find("peaked at ") + 10;
    const long peak = std::stol(out.substr(at));
    const bool mib = out.compare(out.find(' ', at) + 1, 3, "MiB") == 0;
    const long budget_k = (mib ? peak * 1024 : peak) * 4 / 3 + 1;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 3 --jobs auto --max-memory " +
                              std::to_string(budget_k) + "K",
                          &out),
              0)
        << out;
    EXPECT_NE(out.find("--jobs auto: 1 (3 thread(s)"), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " run " + graph + " --jobs lots", &out), 2) << out;
    EXPECT_NE(out.find("--jobs: expected a number in [0, 256] or auto, got \"lots\""),
              std::string::npos)
        << out;
}

// Frames that the budget holds one at a time but not two: with --jobs 2 the refused frames ran
// into the budget's error and failed the run; now they run again with half the frames at once,
// and every output is the one a single job makes.
TEST(Cli, JobsOverTheBudgetRunAgainWithFewerFramesAtOnce)
{
    const std::string dir = test::scratch_dir("cli_jobs_budget");
    for (int f = 1; f <= 6; ++f) {
        write_exr(test::make_sample_frame(384, 256, f),
                  expand_frame_pattern(dir + "/in.####.exr", f),
                  {});
    }
    const std::string graph = write_dof_graph(dir, "out/o.####.exr");
    std::string out;
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 2 --jobs 1 --quiet", &out), 0)
        << out;
    fs::rename(dir + "/out", dir + "/ref");
    // The first frame's peak, from --jobs auto (which then runs one at a time under the budget).
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 2 --jobs auto --frames 1-2", &out),
              0)
        << out;
    const std::size_t at = out.find("peaked at ");
    ASSERT_NE(at, std::string::npos) << out;
    const double peak = std::stod(out.substr(at + 10));
    const bool mib = out.compare(out.find(' ', at + 10) + 1, 3, "MiB") == 0;
    // The peak is printed cut to whole MiB: one more, and a fifth over it, holds a frame.
    const long budget_k = long(((mib ? peak * 1024 : peak) + (mib ? 1024 : 1)) * 1.2);
    fs::remove_all(dir + "/out");
    const std::string budget = " --max-memory " + std::to_string(budget_k) + "K";
    ASSERT_EQ(run_command(kBin + " run " + graph + " --threads 2 --jobs 2" + budget, &out), 0)
        << out;
    EXPECT_NE(out.find("6 frame(s) in"), std::string::npos) << out;
    const std::size_t warned = out.find("warning: over the memory budget");
    if (warned != std::string::npos) {  // two frames met (nearly always on two threads)
        EXPECT_NE(out.find("with 2 frames at once: the ", warned), std::string::npos) << out;
        EXPECT_NE(out.find("1 job(s), 2 thread(s)"), std::string::npos) << out;
    }
    for (int f = 1; f <= 6; ++f) {
        const std::string name = expand_frame_pattern("/o.####.exr", f);
        std::string diff;
        EXPECT_EQ(run_command(kBin + " diff " + dir + "/ref" + name + " " + dir + "/out" + name +
                                  " --fail 0 --quiet",
                              &diff),
                  0)
            << f << ": " << diff;
    }
    // One frame at a time, the budget's refusal is the run's error, as before.
    EXPECT_EQ(run_command(kBin + " run " + graph + " --threads 2 --jobs 1 --max-memory " +
                              std::to_string(budget_k / 3) + "K",
                          &out),
              1)
        << out;
    EXPECT_NE(out.find("memory budget: a "), std::string::npos) << out;
    EXPECT_EQ(out.find("warning: over the memory budget"), std::string::npos) << out;
}

// OpenColorIO's own warnings came as "[OpenColorIO Warning]: ..." on stderr, outside the
// project's format; they are "warning: OpenColorIO: ...", one line each.
TEST(Cli, OpenColorIOWarningsAreTheProjectsLines)
{
    const std::string dir = test::scratch_dir("cli_ocio_warning");
    write_inputs(dir, {1});
    const std::string graph = write_graph(dir);
    std::ifstream in(std::string(POSTHASTE_TEST_DIR) + "/../samples/ocio/config.ocio");
    std::string config((std::istreambuf_iterator<char>(in)), {});
    const std::string at = "    name: srgb\n";
    ASSERT_NE(config.find(at), std::string::npos);
    config.insert(config.find(at) + at.size(), "    dummyKey: dummyValue\n");
    std::ofstream(dir + "/config.ocio") << config;
    std::string out;
    ASSERT_EQ(run_command("OCIO=" + dir + "/config.ocio " + kBin + " run " + graph + " -q", &out),
              0)
        << out;
    EXPECT_NE(out.find("warning: OpenColorIO: At line "), std::string::npos) << out;
    EXPECT_NE(out.find("unknown key 'dummyKey'"), std::string::npos) << out;
    EXPECT_EQ(out.find("[OpenColorIO"), std::string::npos) << out;
}

// A preview path without a frame placeholder took every frame in turn (the last one stayed);
// alpha on a format without it was dropped (JPEG) or failed at frame 1 (PPM). Both are the
// graph's errors now, before any frame.
TEST(Cli, PreviewPathsAndAlphaAreCheckedBeforeAnyFrame)
{
    const std::string dir = test::scratch_dir("cli_preview_checks");
    write_inputs(dir, {1, 2});
    const auto graph = [&](const std::string &params) {
        std::ofstream(dir + "/g.json") << R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": ")"
                                       << dir << R"(/in.####.exr"}},
            {"id": "p", "type": "write", "inputs": {"image": "src"}, "params": )"
                                       << params << "}]}";
        return dir + "/g.json";
    };
    std::string out;
    EXPECT_EQ(run_command(kBin + " run " + graph(R"({"path": "p.png"})") + " --frames 1-2", &out),
              2)
        << out;
    EXPECT_NE(out.find("/p.png\" has no frame placeholder (####) but 2 frames"), std::string::npos)
        << out;
    EXPECT_EQ(run_command(kBin + " run " + graph(R"({"path": "p.png"})") + " --frames 1 -q", &out),
              0)
        << out;
    for (const char *ext : {"jpg", "ppm"}) {
        const std::string params =
            std::string(R"({"path": "p.####.)") + ext + R"(", "alpha": true})";
        EXPECT_EQ(run_command(kBin + " run " + graph(params) + " --frames 1-2", &out), 2) << out;
        EXPECT_NE(out.find("param \"alpha\": a "), std::string::npos) << out;
        EXPECT_NE(out.find(" preview has no alpha channel"), std::string::npos) << out;
        EXPECT_FALSE(fs::exists(dir + "/p.0001." + ext)) << ext;
    }
    EXPECT_EQ(run_command(kBin + " run " + graph(R"({"path": "p.####.tif", "alpha": true})") +
                              " --frames 1-2 -q",
                          &out),
              0)
        << out;
}

TEST(Cli, RenderProbeWritesTheMapWithItsDistancesAndPosition)
{
    const std::string dir = test::scratch_dir("cli_probe");
    const std::string scene = std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/glossy.json";
    std::string out;
    ASSERT_EQ(run_command(kBin + " render " + scene + " --probe --size 64x32 --samples 1 -q -o " +
                              dir + "/p.####.exr --frames 1",
                          &out),
              0)
        << out;
    const Frame f = read_frame(dir + "/p.0001.exr", nullptr, 1);
    EXPECT_EQ(f.width(), 64);
    EXPECT_EQ(f.height(), 32);
    EXPECT_TRUE(f.has("color"));
    EXPECT_TRUE(f.has("depth"));
    EXPECT_NE(f.attributes.find_pv("posthaste:probePosition"), nullptr);
    // A probe is not a ground truth.
    EXPECT_EQ(run_command(kBin + " render " + scene + " --probe --truth ao --size 64x32 -o " + dir +
                              "/q.####.exr --frames 1",
                          &out),
              2)
        << out;
    EXPECT_NE(out.find("error: render --probe: latlong makes no ground truth"), std::string::npos)
        << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;
}

TEST(Cli, InfoShowsTheMapping)
{
    const std::string dir = test::scratch_dir("cli_info");
    ASSERT_EQ(run_command("oiiotool --pattern constant:color=1,1,1,1,3,2,1 4x4 7 --chnames "
                          "RL.Combined.R,RL.Combined.G,RL.Combined.B,RL.Combined.A,RL.Depth.Z,"
                          "RL.Vector.X,RL.Vector.Y -d float -o " +
                          dir + "/b.exr"),
              0);
    std::string out;
    ASSERT_EQ(run_command(kBin + " info " + dir + "/b.exr", &out), 0) << out;
    EXPECT_NE(out.find("color        <- RL.Combined.R, RL.Combined.G, RL.Combined.B, "
                       "RL.Combined.A (Blender)"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("motion       <- -RL.Vector.X, RL.Vector.Y (Blender)"), std::string::npos)
        << out;
    EXPECT_NE(out.find("normal       absent"), std::string::npos) << out;
    EXPECT_EQ(run_command(kBin + " info " + dir + "/none.exr", &out), 1) << out;
    EXPECT_NE(out.find("none.exr: no such file"), std::string::npos) << out;
}

TEST(Cli, NodesDocumentsEveryParameter)
{
    std::string out;
    ASSERT_EQ(run_command(kBin + " nodes merge", &out), 0) << out;
    EXPECT_NE(out.find("mix"), std::string::npos);
    EXPECT_NE(out.find("range 0..1"), std::string::npos) << out;
    ASSERT_EQ(run_command(kBin + " nodes all", &out), 0) << out;
    for (const char *t : {"read:", "write:", "ocio:", "merge:", "channels:"}) {
        EXPECT_NE(out.find(t), std::string::npos) << t;
    }
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

// A disk that fills up mid-run: a 1 MiB tmpfs (root only; skipped elsewhere). The run stops
// with one line naming the frame, the path and the cause, exits 1, leaves no file at the final
// name of the frame that failed, no temporary, and the frames before it whole.
// Inputs that would block or exhaust: a FIFO given as an image is refused, not read forever; a
// farm task's thread count is held to the run's range (it took 17 GB for 2^31 threads); a
// submit that sbatch refuses leaves no half-made job directory to block the next one.
TEST(Cli, PipesThreadCountsAndRefusedSubmitsAreOneLineErrors)
{
    namespace fs = std::filesystem;
    const std::string dir = test::scratch_dir("cli_odd_inputs");
    const std::string fifo = dir + "/fifo.exr";
    ASSERT_EQ(run_command("mkfifo " + fifo), 0);
    std::string out;
    // diff exits with idiff's 4 for a file it cannot read.
    for (const auto &[cmd, rc] : {std::pair<std::string, int>{" info ", 1},
                                  {" info --verify ", 1},
                                  {" diff " + fifo + " ", 4}}) {
        EXPECT_EQ(run_command("timeout 20 " + kBin + cmd + fifo, &out), rc) << cmd << out;
        EXPECT_NE(out.find("fifo.exr: not a regular file"), std::string::npos) << cmd << out;
        EXPECT_EQ(line_count(out), 1) << out;
    }
    EXPECT_EQ(run_command(kBin + " farm task " + dir + " --chunk 0 --threads 2147483647", &out), 2)
        << out;
    EXPECT_EQ(run_command(kBin + " farm task " + dir + " --chunk 0 --threads -1", &out), 2) << out;
    // A stand-in sbatch that refuses every job.
    const std::string bin = dir + "/bin";
    fs::create_directories(bin);
    std::ofstream(bin + "/sbatch") << "#!/bin/sh\necho 'sbatch: error: refused' >&2\nexit 1\n";
    fs::permissions(bin + "/sbatch", fs::perms::owner_all);
    write_inputs(dir, {1});
    const std::string graph = write_graph(dir);
    EXPECT_EQ(run_command("PATH=" + bin + ":$PATH " + kBin + " farm submit " + graph +
                              " --frames 1 --job-dir " + dir + "/job",
                          &out),
              1)
        << out;
    EXPECT_NE(out.find("sbatch failed"), std::string::npos) << out;
    EXPECT_FALSE(fs::exists(dir + "/job")) << "a half-made job directory was left";
    // An sbatch that warns before the array's id and then refuses the check job: the array is
    // queued, so its directory stays, recorded, and the message names the array.
    std::ofstream(bin + "/sbatch") << "#!/bin/sh\nif [ -e " << bin
                                   << "/queued ]; then echo 'sbatch: error: no' >&2; exit 1; fi\n"
                                      "touch "
                                   << bin
                                   << "/queued\necho 'sbatch: warning: site note' >&2\n"
                                      "echo '4242;posthaste'\n";
    EXPECT_EQ(run_command("PATH=" + bin + ":$PATH " + kBin + " farm submit " + graph +
                              " --frames 1 --job-dir " + dir + "/job2",
                          &out),
              1)
        << out;
    EXPECT_NE(out.find("array job 4242 is queued"), std::string::npos) << out;
    EXPECT_TRUE(fs::exists(dir + "/job2/job.json")) << out;
    // A line break in the job directory's name would end an #SBATCH line and start another.
    EXPECT_EQ(run_command(kBin + " farm submit " + graph + " --frames 1 --job-dir '" + dir +
                              "/a\n#SBATCH --wrap=x'",
                          &out),
              2)
        << out;
    EXPECT_NE(out.find("line break"), std::string::npos) << out;
    // A space or a # in its name: sbatch reads #SBATCH lines itself, where a space ends a value
    // and a # starts a comment, so the values go in double quotes.
    std::ofstream(bin + "/sbatch") << "#!/bin/sh\necho '77;posthaste'\n";
    const std::string odd = dir + "/a b#c";
    EXPECT_EQ(run_command("PATH=" + bin + ":$PATH " + kBin + " farm submit " + graph +
                              " --frames 1 --job-dir '" + odd + "'",
                          &out),
              0)
        << out;
    const std::string script = test::read_bytes(odd + "/run-s0.sbatch");
    EXPECT_NE(script.find("#SBATCH --output=\"" + odd + "/logs/slurm-s0-%a.out\"\n"),
              std::string::npos)
        << script;
    EXPECT_NE(script.find("#SBATCH --job-name=\"posthaste-a b#c\"\n"), std::string::npos) << script;
    // --mem, --time and --partition go into #SBATCH lines as they are: a line break started a
    // shell line in the batch script (and ended its directives there). Slurm's syntax only.
    for (const std::string opt :
         {"--mem '8G\necho INJECTED'", "--time '1:00;x'", "--partition 'a b'"}) {
        EXPECT_EQ(run_command("PATH=" + bin + ":$PATH " + kBin + " farm submit " + graph +
                                  " --frames 1 --job-dir " + dir + "/job3 " + opt,
                              &out),
                  2)
            << opt << out;
        EXPECT_NE(out.find("is not Slurm syntax"), std::string::npos) << out;
        EXPECT_EQ(line_count(out), 1) << out;
        EXPECT_FALSE(fs::exists(dir + "/job3")) << opt;
    }
    EXPECT_EQ(run_command("PATH=" + bin + ":$PATH " + kBin + " farm submit " + graph +
                              " --frames 1 --job-dir " + dir +
                              "/job4 --mem 8G --time 1:00:00 "
                              "--partition gpu_a-1",
                          &out),
              0)
        << out;
}

// A run stopped while it writes removes its temporary: a 1080p frame of float passes with zip
// takes most of a second to write, and the signals land at several points of it.
TEST(Cli, ASignalRemovesTheTemporaryBeingWritten)
{
    namespace fs = std::filesystem;
    const std::string dir = test::scratch_dir("cli_signal");
    int stopped = 0;
    for (const char *delay : {"0.5", "0.8", "1.1", "1.4"}) {
        const std::string out = dir + "/" + std::string(delay);
        fs::create_directories(out);
        const int rc = run_command(
            "timeout -s TERM " + std::string(delay) + " " + kBin + " render " + POSTHASTE_TEST_DIR +
            "/../samples/scenes/minecrappy.json -f 1-3 --size 1920x1080 --passes "
            "all --compression zip -q -o " +
            out + "/f.####.exr");
        stopped += rc == 124;
        for (const auto &e : fs::directory_iterator(out)) {
            const std::string name = e.path().filename().string();
            EXPECT_NE(name[0], '.')
                << "a temporary was left: " << name << " (after " << delay << " s)";
            EXPECT_TRUE(verify_image_file(e.path().string()).empty()) << name;
        }
    }
    EXPECT_GT(stopped, 0);
}

// A file system with no capacity (/proc) reports 0 KiB free: the write's failure is its own
// cause, not a full disk (it said "no space left on the device: 0 KiB free").
TEST(Cli, AnUnwritablePlaceIsNotAFullDisk)
{
    const std::string dir = test::scratch_dir("proc_write");
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "scene", "type": "render", "params": {"scene": ")"
                                   << POSTHASTE_TEST_DIR << R"(/../samples/scenes/minecrappy.json",
         "width": 8, "height": 8}},
        {"id": "out", "type": "write", "inputs": {"image": "scene"},
         "params": {"path": "/proc/posthaste_test.####.exr"}}]})";
    std::string log;
    const int rc = test::run_command(
        std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1 --quiet", &log);
    EXPECT_NE(rc, 0) << log;
    EXPECT_NE(log.find("/proc/posthaste_test.0001.exr"), std::string::npos) << log;
    EXPECT_EQ(log.find("KiB free"), std::string::npos) << log;
    EXPECT_EQ(log.find("no space left"), std::string::npos) << log;
}

/// A 1 MiB tmpfs mounted on a scratch folder while the object lives (root only: elsewhere
/// `mounted` is false and the test skips), unmounted however the test ends.
struct SmallDisk {
    explicit SmallDisk(const std::string &name)
        : path(test::scratch_dir(name)),
          mounted(test::run_command("mount -t tmpfs -o size=1m tmpfs " + path) == 0)
    {
    }
    ~SmallDisk()
    {
        if (mounted) {
            test::run_command("umount " + path);
        }
    }
    SmallDisk(const SmallDisk &) = delete;
    SmallDisk &operator=(const SmallDisk &) = delete;
    const std::string path;
    const bool mounted;
};

TEST(Cli, FullDiskStopsTheRunCleanly)
{
    namespace fs = std::filesystem;
    const SmallDisk disk("full_disk");
    if (!disk.mounted) {
        GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
    }
    const std::string &mnt = disk.path;
    const std::string dir = test::scratch_dir("full_disk_graph");
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "scene", "type": "render", "params": {"scene": ")"
                                   << POSTHASTE_TEST_DIR << R"(/../samples/scenes/minecrappy.json",
         "width": 64, "height": 36}},
        {"id": "out", "type": "write", "inputs": {"image": "scene"},
         "params": {"path": ")" << mnt
                                   << R"(/f.####.exr", "passes": "color,depth",
                    "compression": "none"}}]})";
    std::string log;
    const int rc = test::run_command(
        std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1-48 --jobs 1 --quiet",
        &log);
    std::vector<std::string> names;
    for (const auto &e : fs::directory_iterator(mnt)) {
        names.push_back(e.path().filename().string());
    }
    std::sort(names.begin(), names.end());
    int whole = 0;
    for (const std::string &n : names) {
        EXPECT_EQ(n[0] == '.', false) << "a temporary was left: " << n;
        whole += verify_image_file(mnt + "/" + n).empty();
    }
    EXPECT_EQ(rc, 1) << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
    // The cause and the free space, once: OpenEXR's "No space left on device" or, from a writer
    // that does not say why, the writer's own words.
    const auto said = log.find("No space left on device. (");
    const bool cause =
        (said != std::string::npos && log.find(" KiB free)", said) != std::string::npos) ||
        log.find("(no space left on the device: ") != std::string::npos;
    EXPECT_TRUE(cause) << log;
    EXPECT_EQ(log.find(".tmp"), std::string::npos) << "names the temporary: " << log;
    const std::string failed = "frame " + std::to_string(names.size() + 1) + ": " + mnt + "/f." +
                               (names.size() + 1 < 10 ? "000" : "00") +
                               std::to_string(names.size() + 1) + ".exr";
    EXPECT_NE(log.find(failed), std::string::npos) << log;
    EXPECT_GT(names.size(), 3u);
    EXPECT_LT(names.size(), 48u);
    EXPECT_EQ(whole, int(names.size()));  // every frame before the failure reads back whole
}

// A preview that does not fit the space left: the run fails with one line naming the file and
// the cause, and leaves neither the file nor a temporary. libtiff wrote a cut TIFF (45056 bytes
// free) and said nothing, so it was renamed into place and the run exited 0; libjpeg ended the
// process on its own words and left the temporary (8192 bytes free).
TEST(Cli, FullDiskPreviewsFailCleanly)
{
    namespace fs = std::filesystem;
    const SmallDisk disk("full_disk_previews");
    if (!disk.mounted) {
        GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
    }
    const std::string &mnt = disk.path;
    const std::string dir = test::scratch_dir("full_disk_previews_graph");
    for (const auto &[ext, free_bytes] :
         {std::pair<std::string, long>{"tif", 45056}, {"jpg", 8192}, {"jpg", 0}}) {
        SCOPED_TRACE(ext + " with " + std::to_string(free_bytes) + " bytes free");
        const fs::space_info space = fs::space(mnt);
        ASSERT_EQ(
            test::run_command("fallocate -l " + std::to_string(long(space.available) - free_bytes) +
                              " " + mnt + "/filler"),
            0);
        std::ofstream(dir + "/g.json")
            << R"({"nodes": [
            {"id": "in", "type": "read", "params": {"path": ")"
            << POSTHASTE_TEST_DIR << R"(/../samples/cycles/closeup.passes.exr",
             "solve_camera": "never"}},
            {"id": "out", "type": "write", "inputs": {"image": "in"},
             "params": {"path": ")"
            << mnt << "/x." << ext << R"("}}]})";
        std::string log;
        const int rc = test::run_command(
            std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1 --quiet", &log);
        std::vector<std::string> left;
        for (const auto &e : fs::directory_iterator(mnt)) {
            if (e.path().filename() != "filler") {
                left.push_back(e.path().filename().string());
            }
        }
        fs::remove(mnt + "/filler");
        EXPECT_EQ(rc, 1) << log;
        EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
        EXPECT_NE(log.find(mnt + "/x." + ext + ": cannot write: No space left on device"),
                  std::string::npos)
            << log;
        EXPECT_TRUE(left.empty()) << left[0];
    }
}

// What a write replaces: a link is written through to its target (the rename replaced the link
// with a file), a file written again keeps its permissions, a name of 255 bytes is written (its
// temporary's name was longer, "File name too long"), and a JPEG or PNG cut short is not whole
// for --skip-existing (libjpeg decodes it with grey below the cut).
TEST(Cli, WritesKeepLinksModesAndLongNames)
{
    namespace fs = std::filesystem;
    const std::string dir = test::scratch_dir("write_replaces");
    const std::string long_name = std::string(251, 'n') + ".png";
    ASSERT_EQ(long_name.size(), 255u);
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "scene", "type": "render", "params": {"scene": ")"
                                   << POSTHASTE_TEST_DIR << R"(/../samples/scenes/minecrappy.json",
         "width": 64, "height": 36}},
        {"id": "exr", "type": "write", "inputs": {"image": "scene"},
         "params": {"path": "link.exr", "passes": "color"}},
        {"id": "jpg", "type": "write", "inputs": {"image": "scene"}, "params": {"path": "p.jpg"}},
        {"id": "long", "type": "write", "inputs": {"image": "scene"},
         "params": {"path": ")" << long_name
                                   << R"("}}]})";
    fs::create_directories(dir + "/real");
    fs::create_symlink("real/target.exr", dir + "/link.exr");
    std::ofstream(dir + "/p.jpg") << "old";
    fs::permissions(dir + "/p.jpg",
                    fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    std::string log;
    ASSERT_EQ(
        test::run_command(
            std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1 --quiet", &log),
        0)
        << log;
    EXPECT_TRUE(fs::is_symlink(dir + "/link.exr"));
    EXPECT_EQ(verify_image_file(dir + "/real/target.exr"), "");
    EXPECT_EQ(fs::status(dir + "/p.jpg").permissions() & fs::perms::all,
              fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
    EXPECT_EQ(verify_image_file(dir + "/" + long_name), "");
    // Cut the JPEG short: not whole, so --skip-existing writes it again.
    ASSERT_EQ(verify_image_file(dir + "/p.jpg"), "");
    const auto size = fs::file_size(dir + "/p.jpg");
    fs::resize_file(dir + "/p.jpg", size / 2);
    EXPECT_NE(verify_image_file(dir + "/p.jpg").find("the JPEG is cut short"), std::string::npos);
    // And the PNG: found cut before libpng reads it (libpng printed its own line on stderr).
    const auto png_size = fs::file_size(dir + "/" + long_name);
    fs::resize_file(dir + "/" + long_name, png_size - 20);
    EXPECT_NE(verify_image_file(dir + "/" + long_name).find("the PNG is cut short"),
              std::string::npos);
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " run " + dir +
                                    "/g.json --frames 1 --quiet --skip-existing",
                                &log),
              0)
        << log;
    EXPECT_EQ(log, "");
    EXPECT_EQ(fs::file_size(dir + "/p.jpg"), size);
    EXPECT_EQ(fs::file_size(dir + "/" + long_name), png_size);
}

}  // namespace
}  // namespace posthaste
