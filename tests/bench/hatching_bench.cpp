// Benchmarks of the hatching kernel at 1920x1080 on one rendered Minecrappy frame (frame 20,
// rendered once): surface-anchored (dominant-axis and triplanar), the screen-space baseline, and a
// plain copy of the color pass; plus the TAM build at start-up.
//   build/tests/posthaste_benchmarks --benchmark_filter=Hatching --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true  (one command line)
#include <benchmark/benchmark.h>

#include <ctime>
#include <string>

#include "bench_util.h"
#include "core/disk_cache.h"
#include "core/simd.h"
#include "raster/render.h"
#include "shading/hatching/hatch.h"
#include "shading/hatching/tam.h"

namespace posthaste::shading {
namespace {

using bench::process_cpu_ms;

const Frame &frame_1080p()
{
    return bench::minecrappy_frame(20, {"color", "depth", "normal", "position"});
}

const Tam &default_tam()
{
    static const Tam t = build_tam(TamParams{});
    return t;
}

void hatch_bench(benchmark::State &state, HatchSettings s)
{
    const Frame &f = frame_1080p();
    const HatchInputs in{
        &f.image("color"), &f.image("depth"), &f.image("normal"), &f.image("position")};
    const Tam &tam = default_tam();
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image out = hatch(in, s, tam);
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["process_cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}

void BM_HatchingSurface1080p(benchmark::State &state)
{
    hatch_bench(state, HatchSettings{});
}
BENCHMARK(BM_HatchingSurface1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

// The same default settings on Highway's portable one-lane target of the same source
// (simd::Level::Scalar), as the same-run reference for the vector targets.
void BM_HatchingSurfaceScalar1080p(benchmark::State &state)
{
    simd::ScopedLevel scalar(simd::Level::Scalar);
    hatch_bench(state, HatchSettings{});
}
BENCHMARK(BM_HatchingSurfaceScalar1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingSurfaceTriplanar1080p(benchmark::State &state)
{
    HatchSettings s;
    s.triplanar = true;
    hatch_bench(state, s);
}
BENCHMARK(BM_HatchingSurfaceTriplanar1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingScreenBaseline1080p(benchmark::State &state)
{
    HatchSettings s;
    s.screen_space = true;
    hatch_bench(state, s);
}
BENCHMARK(BM_HatchingScreenBaseline1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingSurfaceNoOutline1080p(benchmark::State &state)
{
    HatchSettings s;
    s.outline_width = 0.0f;
    hatch_bench(state, s);
}
BENCHMARK(BM_HatchingSurfaceNoOutline1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingScreenNoOutline1080p(benchmark::State &state)
{
    HatchSettings s;
    s.screen_space = true;
    s.outline_width = 0.0f;
    hatch_bench(state, s);
}
BENCHMARK(BM_HatchingScreenNoOutline1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingCopyBaseline1080p(benchmark::State &state)
{
    const Image &color = frame_1080p().image("color");
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image out(color);
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["process_cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}
BENCHMARK(BM_HatchingCopyBaseline1080p)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_HatchingTamBuild256(benchmark::State &state)
{
    disk_cache::set_enabled(false);  // the build itself
    for (auto _ : state) {
        Tam t = build_tam(TamParams{});
        benchmark::DoNotOptimize(t.texels(0, 0));
    }
    disk_cache::set_enabled(true);
}
BENCHMARK(BM_HatchingTamBuild256)->Unit(benchmark::kMillisecond)->UseRealTime();

/// The same map read from the disk cache (a warm page cache).
void BM_HatchingTamLoad256(benchmark::State &state)
{
    Tam first = build_tam(TamParams{});  // stores the entry when it is not there
    benchmark::DoNotOptimize(first.texels(0, 0));
    if (!disk_cache::enabled()) {
        state.SkipWithError("the disk cache is off");
        return;
    }
    for (auto _ : state) {
        Tam t = build_tam(TamParams{});
        benchmark::DoNotOptimize(t.texels(0, 0));
    }
}
BENCHMARK(BM_HatchingTamLoad256)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste::shading
