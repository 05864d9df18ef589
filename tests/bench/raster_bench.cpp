// Benchmarks of the Minecrappy renderer on the default scene: a full frame with every pass at
// 1920x1080, the beauty alone, and motion-blur ground truth (256 samples at 960x540). Counters
// report triangles and the time split (mesh, setup+bin, raster, shade, shadow) of the last run.
//   build/tests/posthaste_benchmarks --benchmark_filter=Raster --benchmark_repetitions=5
// POSTHASTE_BENCH_KEEP_HEAP=1 makes glibc serve large blocks from the heap and keep freed memory
// (mallopt M_MMAP_MAX = 0, M_TRIM_THRESHOLD = 1 GiB), so each frame's fresh pass images reuse
// pages instead of faulting in ~180 MB of zeroed memory: a process policy a renderer of many
// frames can choose.
#include <benchmark/benchmark.h>
#include <malloc.h>

#include <cstdlib>
#include <ctime>
#include <string>

#include "bench_util.h"
#include "raster/render.h"

namespace posthaste::raster {
namespace {

const Scene &default_scene()
{
    static const Scene s =
        load_scene(std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/minecrappy.json");
    return s;
}

using bench::process_cpu_ms;

void report(benchmark::State &state, const RenderStats &st)
{
    state.counters["triangles"] = double(st.triangles);
    state.counters["binned"] = double(st.triangles_binned);
    state.counters["mesh_ms"] = st.mesh_ms;
    state.counters["setup_bin_ms"] = st.setup_bin_ms;
    state.counters["raster_ms"] = st.raster_ms;
    state.counters["shade_ms"] = st.shade_ms;
    state.counters["shadow_ms"] = st.shadow_ms;
}

void render_bench(benchmark::State &state,
                  std::set<std::string> passes,
                  int overscan_x = 0,
                  int overscan_y = 0)
{
    const Scene &s = default_scene();
    RenderOptions o;
    o.width = 1920;
    o.height = 1080;
    o.overscan_x = overscan_x;
    o.overscan_y = overscan_y;
    o.passes = std::move(passes);
    render_frame(s, 1, o);  // meshes and the static shadow map are cached per scene
    RenderStats st;
    int frame = 1;
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Frame f = render_frame(s, frame, o, &st);
        benchmark::DoNotOptimize(f);
        frame = frame % 48 + 1;  // walk the camera path
    }
    report(state, st);
    state.counters["process_cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}

void BM_RasterFrameAllPasses1080p(benchmark::State &state)
{
    render_bench(state, render_pass_names());
}
BENCHMARK(BM_RasterFrameAllPasses1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RasterFrameColor1080p(benchmark::State &state)
{
    render_bench(state, {"color"});
}
BENCHMARK(BM_RasterFrameColor1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RasterFrameDepthOnly1080p(benchmark::State &state)
{
    render_bench(state, {"depth"});
}
BENCHMARK(BM_RasterFrameDepthOnly1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

// The passes ssgi reads, without and with render's `overscan: 0.1` (96 px left and right, 54
// top and bottom: 2112x1188, 1.21x the pixels). Like the others these walk the camera path, so
// the two render different frames; docs/PERFORMANCE.md pairs them over the same frames.
void BM_RasterFrameLit1080p(benchmark::State &state)
{
    render_bench(state, {"color", "depth", "normal", "albedo"});
}
BENCHMARK(BM_RasterFrameLit1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RasterFrameLit1080pOverscan10(benchmark::State &state)
{
    render_bench(state, {"color", "depth", "normal", "albedo"}, 96, 54);
}
BENCHMARK(BM_RasterFrameLit1080pOverscan10)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_RasterTruthMotion256(benchmark::State &state)
{
    const Scene &s = default_scene();
    RenderOptions o;
    o.width = 960;
    o.height = 540;
    TruthOptions t;
    t.motion = true;
    t.samples = 256;
    render_frame(s, 1, o);
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Frame f = render_truth(s, 12, o, t);
        benchmark::DoNotOptimize(f);
    }
    state.counters["process_cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}
BENCHMARK(BM_RasterTruthMotion256)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(1);

}  // namespace
}  // namespace posthaste::raster
