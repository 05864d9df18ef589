// Benchmarks of depth of field at 1920x1080 (full resolution, the default, and half) on the default
// scene's close-up (frame 48: 55 mm, f/1.4, focus 6 m; most of the frame is out of focus), beside
// baselines in the same run: a plain copy of the color pass and the simple method (disc of each
// pixel's own CoC). Counters give the per-pass split of the last iteration (CoC + colour prepare,
// tile max + dilation, gather with the near-over-background composite fused in) and process CPU
// time per iteration.
//   build/tests/posthaste_benchmarks --benchmark_filter=Dof --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <ctime>
#include <string>

#include "bench_util.h"
#include "raster/render.h"
#include "shading/dof/dof_gather.h"

namespace posthaste {
namespace {

const Frame &closeup_frame()
{
    return bench::minecrappy_frame(48, {"color", "depth"});
}

using bench::process_cpu_ms;

shading::DofLens lens_of(const Camera &c)
{
    return {*c.fstop, *c.focus_distance, *c.focal_length_mm, *c.sensor_width_mm};
}

void BM_DofCopy(benchmark::State &state)
{
    const Image &color = closeup_frame().image("color");
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image out(color);
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}

void dof_bench(benchmark::State &state, shading::DofMethod method, bool half = false)
{
    const Frame &f = closeup_frame();
    shading::DofSettings s;
    s.method = method;
    s.samples = int(state.range(0));
    s.half_res = half;
    shading::DofTimes t;
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image out;
        shading::apply_dof(f.image("color"), f.image("depth"), lens_of(f.camera), s, out, &t);
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
    state.counters["coc_ms"] = t.coc_ms;
    state.counters["tiles_ms"] = t.tiles_ms;
    state.counters["gather_ms"] = t.gather_ms;
    state.counters["composite_ms"] = t.composite_ms;
    state.counters["coc_cpu"] = t.coc_cpu_ms;
    state.counters["tiles_cpu"] = t.tiles_cpu_ms;
    state.counters["gather_cpu"] = t.gather_cpu_ms;
    state.counters["composite_cpu"] = t.composite_cpu_ms;
    state.counters["tiles_copied"] = t.tiles_copied;
    state.counters["tiles_gathered"] = t.tiles_gathered;
}

void BM_DofSimple(benchmark::State &state)
{
    dof_bench(state, shading::DofMethod::Simple);
}

void BM_DofGather(benchmark::State &state)
{
    dof_bench(state, shading::DofMethod::Gather);
}

void BM_DofGatherHalf(benchmark::State &state)
{
    dof_bench(state, shading::DofMethod::Gather, true);
}

BENCHMARK(BM_DofCopy)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DofSimple)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DofGather)->Arg(16)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DofGatherHalf)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
