// The camera solved from position + depth (core/camera_solve.h) on a 1920x1080 frame of the
// default scene, beside reading those two passes from an EXR (what a read that solves must do
// anyway, half+piz as the write node's default leaves them): what the solve adds to a read of a
// file without camera matrices.
//   build/tests/posthaste_benchmarks --benchmark_filter=CameraSolve --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <filesystem>

#include "bench_util.h"
#include "core/camera_solve.h"
#include "io/image_file.h"

namespace posthaste {
namespace {

const Frame &frame()
{
    return bench::minecrappy_frame(20, {"position", "depth"});
}

void BM_CameraSolve(benchmark::State &state)
{
    const Frame &f = frame();
    set_thread_count(2);
    for (auto _ : state) {
        const CameraSolve s = solve_camera(
            f.image("position"), f.image("depth"), f.display_window, f.data_window, "bench");
        benchmark::DoNotOptimize(s.residual_px);
    }
    set_thread_count(0);
}
BENCHMARK(BM_CameraSolve)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_CameraSolveReadPositionDepth(benchmark::State &state)
{
    const std::string path =
        (std::filesystem::temp_directory_path() / "posthaste_camera_solve_bench.exr").string();
    write_exr(frame(), path, {});
    const std::set<std::string> wanted = {"position", "depth"};
    set_thread_count(2);
    for (auto _ : state) {
        const Frame f = read_frame(path, &wanted, 20);
        benchmark::DoNotOptimize(f.image("depth").data());
    }
    set_thread_count(0);
    std::filesystem::remove(path);
}
BENCHMARK(BM_CameraSolveReadPositionDepth)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
