// The ao node at 1920x1080 (frame 30 of the Minecrappy scene): the default (GTAO, reachable
// crossings) against every crossing and the bitmask, and the GTAO kernel alone with and without
// the reachable crossings' gate: what each setting costs against the 25 ms budget, as medians of
// repetitions.

#include <benchmark/benchmark.h>

#include <memory>
#include <string>

#include "bench_util.h"
#include "core/parallel.h"
#include "shading/ao/gtao.h"
#include "shading/camera_rays.h"
#include "shading/lighting/occluder_thickness.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &gbuffer()
{
    return bench::minecrappy_frame(30, {"normal", "depth"}, false);
}

void run_node(benchmark::State &state, const std::string &params)
{
    const test::NodeRunner ao("ao", params);
    const auto input = std::make_shared<const Frame>(gbuffer());
    bench::timed_loop(state, [&] {
        const Frame out = ao.run(input, 30);
        benchmark::DoNotOptimize(out.image("ao").data());
    });
    state.counters["threads"] = thread_count();
}

void BM_AoDefault(benchmark::State &state)
{
    run_node(state, "{}");
}

void BM_AoAllCrossings(benchmark::State &state)
{
    run_node(state, R"({"crossings": "all"})");
}

void BM_AoThreeSlices(benchmark::State &state)
{
    run_node(state, R"({"slices": 3})");
}

void BM_AoBitmaskExtent(benchmark::State &state)
{
    run_node(state, R"({"method": "bitmask", "occluders": "extent"})");
}

/// The GTAO kernel alone at half resolution (the default), with `reachable` its gate reading a
/// map made once outside the loop.
void run_kernel(benchmark::State &state, bool reachable)
{
    const Frame &in = gbuffer();
    const shading::CameraRays rays(*in.camera.world_to_camera, *in.camera.world_to_ndc);
    const Image map = shading::occluder_thickness(
        in.image("depth"), in.image("normal"), rays, 2.0f, 2, shading::SurfaceExtent::widest);
    shading::GtaoParams p;
    p.stride = 2;
    p.reach_map = reachable ? &map : nullptr;
    p.map_stride = 2;
    for (auto _ : state) {
        const Image ao = shading::gtao(in.image("depth"), in.image("normal"), rays, p);
        benchmark::DoNotOptimize(ao.data());
    }
}

void BM_GtaoKernel(benchmark::State &state)
{
    run_kernel(state, false);
}

void BM_GtaoKernelReachable(benchmark::State &state)
{
    run_kernel(state, true);
}

BENCHMARK(BM_AoDefault)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AoAllCrossings)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AoThreeSlices)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_AoBitmaskExtent)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_GtaoKernel)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_GtaoKernelReachable)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
