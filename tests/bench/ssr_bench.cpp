// Benchmarks of the ssr node (nodes/ssr.cpp) at 1920x1080 on the glossy scene
// (samples/scenes/glossy.json: polished floor, mirror panel, balls), the frames of
// graphs/bench/ssr.json (1: wide view; 16: close to the floor), rendered once: the default
// settings, one ray a pixel, and full resolution; beside the copy of the colour pass the node
// pays at least. cpu_ms is the process CPU time per iteration (all threads).
//   build/tests/posthaste_benchmarks --benchmark_filter=Ssr --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <memory>
#include <string>

#include "bench_util.h"
#include "core/parallel.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &glossy_frame(int frame)
{
    return bench::scene_frame(
        "glossy.json", frame, {"color", "depth", "normal", "albedo", "material"}, true);
}

void run_ssr(benchmark::State &state, const std::string &params)
{
    const int frame = int(state.range(0));
    const auto input = std::make_shared<const Frame>(glossy_frame(frame));
    const test::NodeRunner ssr("ssr", params);
    set_thread_count(2);
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = bench::process_cpu_ms();
        const Frame out = ssr.run(input, frame);
        benchmark::DoNotOptimize(out.image("color").data());
        cpu += bench::process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
    set_thread_count(0);
}

void BM_SsrNode(benchmark::State &state)
{
    run_ssr(state, "{}");
}
void BM_SsrNodeRays1(benchmark::State &state)
{
    run_ssr(state, R"({"rays": 1})");
}
void BM_SsrNodeFull(benchmark::State &state)
{
    run_ssr(state, R"({"resolution": "full"})");
}
void BM_SsrCopyBaseline(benchmark::State &state)
{
    bench::copy_baseline(state, glossy_frame(int(state.range(0))).image("color"));
}

BENCHMARK(BM_SsrNode)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeRays1)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeFull)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrCopyBaseline)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
