// Benchmarks of the ssr node (nodes/ssr.cpp) at 1920x1080 on the glossy scene
// (samples/scenes/glossy.json: polished floor, mirror panel, balls), the frames of
// graphs/bench/ssr.json (1: wide view; 16: close to the floor), rendered once: the default
// settings (quarter resolution at this size), hits not re-shaded (as the camera saw them), those
// weighed as a GGX lobe (brdf ggx), with
// the scene's reflection probe, one ray a pixel, half and full resolution; beside the copy of the
// colour pass the node pays at least. cpu_ms is the process CPU time per iteration (all threads).
//   build/tests/posthaste_benchmarks --benchmark_filter=Ssr --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "bench_util.h"
#include "core/parallel.h"
#include "raster/ray_cast.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// The frame as the render node gives it: the passes ssr reads (the shadow pass for the hits'
/// re-shading) and the header's sun and sky.
const Frame &glossy_frame(int frame)
{
    return bench::sun_frame(
        "glossy.json", frame, {"color", "depth", "normal", "albedo", "material", "shadow"});
}

/// The glossy scene's reflection probe at frame `frame` (1024x512, 16 rays a texel), once.
const Frame &glossy_probe(int frame)
{
    static std::map<int, Frame> probes;
    auto it = probes.find(frame);
    if (it == probes.end()) {
        const raster::Scene s = raster::load_scene(test::scene_path("glossy.json"));
        raster::EnvironmentProbe p = raster::render_environment_probe(s, frame, 1024, 512, 16, 0);
        Frame f;
        f.set_size(1024, 512);
        f.set("color", std::move(p.color));
        f.set("depth", std::move(p.distance));
        f.attributes.push_back(
            OIIO::ParamValue("posthaste:probePosition", OIIO::TypeVector, 1, &p.position));
        it = probes.emplace(frame, std::move(f)).first;
    }
    return it->second;
}

void run_ssr(benchmark::State &state, const std::string &params, bool probe = false)
{
    const int frame = int(state.range(0));
    const Frame &input = glossy_frame(frame);
    std::vector<std::pair<std::string, Frame>> inputs = {{"image", input}};
    if (probe) {
        inputs.emplace_back("environment", glossy_probe(frame));
    }
    const test::NodeRunner ssr("ssr", params);
    set_thread_count(2);
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = bench::process_cpu_ms();
        const Frame out = ssr.run_ports(inputs, frame);
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
void BM_SsrNodeAsSeen(benchmark::State &state)
{
    run_ssr(state, R"({"sun_irradiance": [0, 0, 0]})");
}
void BM_SsrNodeGgx(benchmark::State &state)
{
    // Weighed as a path tracer's GGX lobe (the weight kernel's table look-up), beside AsSeen:
    // the same rays, and the pixels from roughness 0.776 only a GGX lobe reflects.
    run_ssr(state, R"({"sun_irradiance": [0, 0, 0], "brdf": "ggx"})");
}
void BM_SsrNodeProbe(benchmark::State &state)
{
    run_ssr(state, "{}", true);
}
void BM_SsrNodeRays1(benchmark::State &state)
{
    run_ssr(state, R"({"rays": 1})");
}
void BM_SsrNodeHalf(benchmark::State &state)
{
    run_ssr(state, R"({"resolution": "half"})");
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
BENCHMARK(BM_SsrNodeAsSeen)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeGgx)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeProbe)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeRays1)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeHalf)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrNodeFull)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsrCopyBaseline)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
