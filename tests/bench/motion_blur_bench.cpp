// Benchmarks of the motion_blur filter at 1920x1080 on the default scene's fast-translation
// frame (6: every pixel moves) and fast-turn frame (20), beside baselines in the same run:
// copying the color pass, and the uniform blur along each pixel's motion (the seeds' method).
// Counters: per-stage wall and process-CPU milliseconds of the last iteration (pack, tile max,
// neighbour max, gather), tiles copied / coherent, 8-pixel groups and how many shared a run,
// and process CPU ms per iteration (all threads; on a shared machine wall time also counts
// waiting for a core).
//   build/tests/posthaste_benchmarks --benchmark_filter=MotionBlur
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
#include <benchmark/benchmark.h>

#include <ctime>
#include <map>
#include <string>

#include "bench_util.h"
#include "core/simd.h"
#include "raster/render.h"
#include "shading/motion_blur/motion_blur.h"
#include "shading/motion_blur/reproject.h"

namespace posthaste::shading {
namespace {

const Frame &input_frame(int frame)
{
    return bench::minecrappy_frame(frame, {"color", "depth", "motion"});
}

using bench::process_cpu_ms;

void BM_MotionBlurCopy(benchmark::State &state)
{
    const Frame &f = input_frame(int(state.range(0)));
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image copy(f.image("color"));
        benchmark::DoNotOptimize(copy.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
}

// Times motion_blur on frame f with options o; the counters of the last iteration.
void time_blur(benchmark::State &state, const Frame &f, const MotionBlurOptions &o)
{
    MotionBlurStats st;
    const double cpu0 = process_cpu_ms();
    for (auto _ : state) {
        Image out = motion_blur(f.image("color"), f.image("motion"), f.image("depth"), o, &st);
        benchmark::DoNotOptimize(out.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - cpu0) / double(state.iterations());
    state.counters["pack_ms"] = st.pack_ms;
    state.counters["tile_max_ms"] = st.tile_max_ms;
    state.counters["neighbour_max_ms"] = st.neighbour_max_ms;
    state.counters["gather_ms"] = st.gather_ms;
    state.counters["pack_cpu_ms"] = st.pack_cpu_ms;
    state.counters["tile_max_cpu_ms"] = st.tile_max_cpu_ms;
    state.counters["neighbour_max_cpu_ms"] = st.neighbour_max_cpu_ms;
    state.counters["gather_cpu_ms"] = st.gather_cpu_ms;
    state.counters["groups"] = double(st.groups);
    state.counters["groups_shared"] = double(st.groups_shared);
    state.counters["tiles_copied"] = st.tiles_copied;
    state.counters["tiles_coherent"] = st.tiles_coherent;
    state.counters["tiles"] = st.tiles_total;
}

// The default options for frame f (its shutter from the header).
MotionBlurOptions options_for(const Frame &f)
{
    MotionBlurOptions o;
    o.shutter = f.camera.shutter.value_or(0.5f);
    return o;
}

void run_blur(benchmark::State &state, BlurMethod method)
{
    const Frame &f = input_frame(int(state.range(0)));
    MotionBlurOptions o = options_for(f);
    o.method = method;
    time_blur(state, f, o);
}

void BM_MotionBlurUniform(benchmark::State &state)
{
    run_blur(state, BlurMethod::Uniform);
}
void BM_MotionBlurReconstruct(benchmark::State &state)
{
    run_blur(state, BlurMethod::Reconstruct);
}

// The portable scalar path of the same filter (POSTHASTE_SIMD=scalar), as a same-run baseline of
// the AVX2 rows.
void BM_MotionBlurReconstructScalar(benchmark::State &state)
{
    simd::ScopedLevel scalar(simd::Level::Scalar);
    run_blur(state, BlurMethod::Reconstruct);
}
void BM_MotionBlurUniformScalar(benchmark::State &state)
{
    simd::ScopedLevel scalar(simd::Level::Scalar);
    run_blur(state, BlurMethod::Uniform);
}

void BM_MotionBlurCameraMotion(benchmark::State &state)
{
    const Frame &f = input_frame(int(state.range(0)));
    for (auto _ : state) {
        Image m = camera_motion(f.image("depth"), f.camera, "bench");
        benchmark::DoNotOptimize(m.data());
    }
}

BENCHMARK(BM_MotionBlurCopy)->Arg(6)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MotionBlurUniform)->Arg(6)->Arg(20)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MotionBlurReconstruct)->Arg(6)->Arg(20)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_MotionBlurReconstructScalar)
    ->Arg(6)
    ->Arg(20)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_MotionBlurUniformScalar)->Arg(6)->Unit(benchmark::kMillisecond)->UseRealTime();

// Quality sweep on frame 6: samples 4, 8, 16 (default), 32.
void BM_MotionBlurReconstructSamples(benchmark::State &state)
{
    const Frame &f = input_frame(6);
    MotionBlurOptions o = options_for(f);
    o.samples = int(state.range(0));
    time_blur(state, f, o);
}
BENCHMARK(BM_MotionBlurReconstructSamples)
    ->Arg(4)
    ->Arg(8)
    ->Arg(32)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
// Shared runs on frame 6: group_tolerance 0 (every pixel samples on its own), 0.25, 0.5
// (default), 1 px; the argument is hundredths of a pixel.
void BM_MotionBlurReconstructTolerance(benchmark::State &state)
{
    const Frame &f = input_frame(6);
    MotionBlurOptions o = options_for(f);
    o.group_tolerance = float(state.range(0)) / 100.0f;
    time_blur(state, f, o);
}
BENCHMARK(BM_MotionBlurReconstructTolerance)
    ->Arg(0)
    ->Arg(25)
    ->Arg(100)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();
BENCHMARK(BM_MotionBlurCameraMotion)->Arg(6)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste::shading
