// Benchmarks of the ssgi node (nodes/ssgi.cpp) at 1920x1080 on the default scene, frames 8 and
// 40 of graphs/bench/ssgi.json, rendered once with the header's sun (so the default re-shades):
// the default settings (quarter resolution) with the scene's probe (512x256, 4 rays a texel,
// from the camera), samples as the camera saw them, without the probe, 4 steps, no denoise,
// half resolution, the glossy planes' reflected sun left to the slices, and beside them the copy
// of the colour pass the node pays at least; and the default with and without the reflected sun
// on the glossy scene, frames 1 and 16 of graphs/bench/ssgi_glossy.json, where it is traced
// for the polished floor and the mirror. cpu_ms is the process CPU time per iteration (all
// threads).
//   build/tests/posthaste_benchmarks --benchmark_filter=Ssgi --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <map>
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

/// The frame as the render node gives it: the passes ssgi reads (the shadow pass for the
/// re-shading) and the header's sun and sky.
const Frame &lit_frame(const std::string &scene, int frame)
{
    return bench::sun_frame(
        scene, frame, {"color", "depth", "normal", "albedo", "material", "shadow"});
}

/// A scene's probe at frame `frame`, as graphs/bench/graphs/ssgi_graph.json makes it.
const Frame &probe(const std::string &scene, int frame)
{
    static std::map<std::pair<std::string, int>, Frame> probes;
    auto it = probes.find({scene, frame});
    if (it == probes.end()) {
        const raster::Scene s = raster::load_scene(test::scene_path(scene));
        raster::EnvironmentProbe p = raster::render_environment_probe(s, frame, 512, 256, 4, 0);
        Frame f;
        f.set_size(512, 256);
        f.set("color", std::move(p.color));
        f.set("depth", std::move(p.distance));
        it = probes.emplace(std::pair(scene, frame), std::move(f)).first;
    }
    return it->second;
}

void run_ssgi(benchmark::State &state,
              const std::string &params,
              bool with_probe,
              const std::string &scene = "minecrappy.json")
{
    const int frame = int(state.range(0));
    std::vector<std::pair<std::string, Frame>> inputs = {{"image", lit_frame(scene, frame)}};
    if (with_probe) {
        inputs.emplace_back("environment", probe(scene, frame));
    }
    const test::NodeRunner ssgi("ssgi", params);
    set_thread_count(2);
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = bench::process_cpu_ms();
        const Frame out = ssgi.run_ports(inputs, frame);
        benchmark::DoNotOptimize(out.image("color").data());
        cpu += bench::process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
    set_thread_count(0);
}

void BM_SsgiNode(benchmark::State &state)
{
    run_ssgi(state, "{}", true);
}
void BM_SsgiNodeAsSeen(benchmark::State &state)
{
    run_ssgi(state, R"({"reshade": "off"})", true);
}
void BM_SsgiNodeScreenOnly(benchmark::State &state)
{
    run_ssgi(state, "{}", false);
}
void BM_SsgiNodeHalf(benchmark::State &state)
{
    run_ssgi(state, R"({"resolution": "half"})", true);
}
void BM_SsgiNodeSteps4(benchmark::State &state)
{
    run_ssgi(state, R"({"steps": 4})", true);
}
void BM_SsgiNodeNoDenoise(benchmark::State &state)
{
    run_ssgi(state, R"({"denoise": false})", true);
}
void BM_SsgiNodeNoReflectedSun(benchmark::State &state)
{
    run_ssgi(state, R"({"reflected_sun": false})", true);
}
void BM_SsgiNodeGlossy(benchmark::State &state)
{
    run_ssgi(state, "{}", true, "glossy.json");
}
void BM_SsgiNodeGlossyNoReflectedSun(benchmark::State &state)
{
    run_ssgi(state, R"({"reflected_sun": false})", true, "glossy.json");
}
void BM_SsgiCopyBaseline(benchmark::State &state)
{
    bench::copy_baseline(state, lit_frame("minecrappy.json", int(state.range(0))).image("color"));
}

BENCHMARK(BM_SsgiNode)->Arg(8)->Arg(40)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeAsSeen)->Arg(8)->Arg(40)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeScreenOnly)->Arg(8)->Arg(40)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeHalf)->Arg(8)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeSteps4)->Arg(8)->Arg(40)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeNoDenoise)->Arg(8)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeNoReflectedSun)->Arg(8)->Arg(40)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeGlossy)->Arg(1)->Arg(16)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_SsgiNodeGlossyNoReflectedSun)
    ->Arg(1)
    ->Arg(16)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_SsgiCopyBaseline)->Arg(8)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
