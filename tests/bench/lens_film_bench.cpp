// The lens-and-film nodes as a graph runs them (input frame in, new frame out) at 1920x1080 on
// the default Minecrappy scene's frame 8 (color and depth passes), with a copy of the color pass
// beside them in the same run (what any node that outputs a new image pays at least). Auto exposure
// runs without a history here (one frame metered alone): its per-frame cost, warm-up frames aside.
//   build/tests/posthaste_benchmarks --benchmark_filter='LensFilm' --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>

#include <string>

#include "bench_util.h"
#include "core/parallel.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

using bench::process_cpu_ms;

const Frame &input_frame()
{
    return bench::minecrappy_frame(8, {"color", "depth"}, true);
}

void run_node(benchmark::State &state, const std::string &type, const std::string &params)
{
    set_thread_count(2);
    const test::NodeRunner node(type, params);
    const auto input = std::make_shared<const Frame>(input_frame());
    node.run(input, 8);  // once untimed: per-node caches (bloom's fit, FFT plans) are built
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = process_cpu_ms();
        const Frame out = node.run(input, 8);
        benchmark::DoNotOptimize(out.image("color").data());
        cpu += process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
    set_thread_count(0);
}

void BM_LensFilmCopyBaseline(benchmark::State &state)
{
    bench::copy_baseline(state, input_frame().image("color"));
}
BENCHMARK(BM_LensFilmCopyBaseline)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmExposureEv(benchmark::State &state)
{
    run_node(state, "exposure", R"({"exposure": 0.5})");
}
BENCHMARK(BM_LensFilmExposureEv)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmExposureAuto(benchmark::State &state)
{
    run_node(state, "exposure", R"({"mode": "auto"})");
}
BENCHMARK(BM_LensFilmExposureAuto)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmGrainMono(benchmark::State &state)
{
    run_node(state, "grain", "{}");
}
BENCHMARK(BM_LensFilmGrainMono)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmGrainColor(benchmark::State &state)
{
    run_node(state, "grain", R"({"mode": "color"})");
}
BENCHMARK(BM_LensFilmGrainColor)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmLensBicubic(benchmark::State &state)
{
    run_node(state, "lens", R"({"k1": -0.05, "k2": 0.01})");
}
BENCHMARK(BM_LensFilmLensBicubic)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmLensBicubicAberration(benchmark::State &state)
{
    run_node(state, "lens", R"({"k1": -0.05, "k2": 0.01, "chromatic_aberration": 0.002})");
}
BENCHMARK(BM_LensFilmLensBicubicAberration)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmLensBilinear(benchmark::State &state)
{
    run_node(state, "lens", R"({"k1": -0.05, "k2": 0.01, "filter": "bilinear"})");
}
BENCHMARK(BM_LensFilmLensBilinear)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmBloomPyramid(benchmark::State &state)
{
    run_node(state, "bloom", "{}");
}
BENCHMARK(BM_LensFilmBloomPyramid)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmBloomFft(benchmark::State &state)
{
    run_node(state, "bloom", R"({"method": "fft"})");
}
BENCHMARK(BM_LensFilmBloomFft)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmGradeCdl(benchmark::State &state)
{
    run_node(
        state, "grade", R"({"temperature": 5600, "slope": [1.1, 1, 0.95], "saturation": 1.1})");
}
BENCHMARK(BM_LensFilmGradeCdl)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmTonemapAgx(benchmark::State &state)
{
    run_node(state, "tonemap", "{}");
}
BENCHMARK(BM_LensFilmTonemapAgx)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_LensFilmTonemapAces(benchmark::State &state)
{
    run_node(state, "tonemap", R"({"curve": "aces"})");
}
BENCHMARK(BM_LensFilmTonemapAces)->Unit(benchmark::kMillisecond)->UseRealTime();

// The image operations (OpenImageIO's ImageBufAlgo), on the colour and depth passes.
void BM_ImageOpsReformatHalf(benchmark::State &state)
{
    run_node(state, "reformat", R"({"scale": 0.5})");
}
BENCHMARK(BM_ImageOpsReformatHalf)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsReformatHalfTriangle(benchmark::State &state)
{
    run_node(state, "reformat", R"({"scale": 0.5, "filter": "triangle"})");
}
BENCHMARK(BM_ImageOpsReformatHalfTriangle)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsTransformRotate(benchmark::State &state)
{
    run_node(state, "transform", R"({"rotate": 5, "scale": 1.05})");
}
BENCHMARK(BM_ImageOpsTransformRotate)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsTransformRotateCubic(benchmark::State &state)
{
    run_node(state, "transform", R"({"rotate": 5, "scale": 1.05, "filter": "catmull-rom"})");
}
BENCHMARK(BM_ImageOpsTransformRotateCubic)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsCrop(benchmark::State &state)
{
    run_node(state, "crop", R"({"box": [160, 90, 1760, 990]})");
}
BENCHMARK(BM_ImageOpsCrop)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsBlur(benchmark::State &state)
{
    run_node(state, "blur", R"({"sigma": )" + std::to_string(state.range(0)) + "}");
}
BENCHMARK(BM_ImageOpsBlur)->Arg(2)->Arg(8)->Arg(32)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ImageOpsSharpen(benchmark::State &state)
{
    run_node(state, "sharpen", "{}");
}
BENCHMARK(BM_ImageOpsSharpen)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
