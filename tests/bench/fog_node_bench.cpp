// The fog node as a graph runs it (input frame in, new frame out: the sweep, the sky pixels, the
// copy of the untouched passes), at 1920x1080 on the default Minecrappy scene's frame 8 (ground,
// blocks and sky), with the sun from the render's header. Beside, in the same run: a copy of the
// color pass (what any node that outputs a new image pays at least), and each model with the
// portable scalar path forced. The counter cpu_ms is the process CPU time per iteration.
//   build/tests/posthaste_benchmarks --benchmark_filter=FogNode --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <ctime>
#include <string>

#include "bench_util.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &fog_input()
{
    return bench::minecrappy_frame(8, {"color", "depth"}, false);
}

using bench::process_cpu_ms;

void run_fog(benchmark::State &state, const std::string &params, bool scalar)
{
    const simd::ScopedLevel level(scalar ? simd::Level::Scalar : simd::detected());
    set_thread_count(2);
    const test::NodeRunner fog("fog", params);
    const auto input = std::make_shared<const Frame>(fog_input());
    fog.run(input, 8);  // once untimed: the atmosphere's LUTs are built on the first frame
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = process_cpu_ms();
        const Frame out = fog.run(input, 8);
        benchmark::DoNotOptimize(out.image("color").data());
        cpu += process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
    set_thread_count(0);
}

const char *kHeight = R"({"model": "height", "density": 0.02, "falloff": 0.08,
                          "sun_color": [0.5, 0.45, 0.4]})";
const char *kAtmosphere = R"({"model": "atmosphere"})";

void BM_FogNodeCopyBaseline(benchmark::State &state)
{
    bench::copy_baseline(state, fog_input().image("color"));
}
BENCHMARK(BM_FogNodeCopyBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FogNodeHeight(benchmark::State &state)
{
    run_fog(state, kHeight, false);
}
BENCHMARK(BM_FogNodeHeight)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FogNodeHeightScalar(benchmark::State &state)
{
    run_fog(state, kHeight, true);
}
BENCHMARK(BM_FogNodeHeightScalar)->Unit(benchmark::kMillisecond)->UseRealTime();

// With the composite at a filtered colour's depth edges (pixel_filter, for a production
// render's passes): the model run twice more (over colours 1 and 0) and the 3x3 correction.
void BM_FogNodeHeightPixelFilter(benchmark::State &state)
{
    run_fog(state,
            R"({"model": "height", "density": 0.02, "falloff": 0.08,
                "sun_color": [0.5, 0.45, 0.4], "pixel_filter": 0.6})",
            false);
}
BENCHMARK(BM_FogNodeHeightPixelFilter)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FogNodeAtmosphere(benchmark::State &state)
{
    run_fog(state, kAtmosphere, false);
}
BENCHMARK(BM_FogNodeAtmosphere)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FogNodeAtmosphereScalar(benchmark::State &state)
{
    run_fog(state, kAtmosphere, true);
}
BENCHMARK(BM_FogNodeAtmosphereScalar)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
