// Timing of the metrics at 1920x1080: compare (idiff statistics), LDR-FLIP and HDR-FLIP.
// Run: build/tests/posthaste_benchmarks --benchmark_filter=Metrics

#include <benchmark/benchmark.h>

#include "core/hash.h"
#include "metrics/flip.h"
#include "metrics/metrics.h"

namespace posthaste::metrics {
namespace {

constexpr int kWidth = 1920;
constexpr int kHeight = 1080;

Image test_image(std::uint32_t seed, float scale)
{
    Image img(kWidth, kHeight, 3);
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            for (int c = 0; c < 3; ++c) {
                img.at(x, y, c) =
                    scale * hash_unit(x / 8, y / 8, c, 1) + 0.02f * hash_unit(x, y, c, seed);
            }
        }
    }
    return img;
}

void BM_MetricsCompare(benchmark::State &state)
{
    const Image a = test_image(2, 1.0f), b = test_image(3, 1.0f);
    for (auto _ : state) {
        benchmark::DoNotOptimize(compare(a, b));
    }
}
BENCHMARK(BM_MetricsCompare)->Unit(benchmark::kMillisecond);

void BM_MetricsFlipLdr(benchmark::State &state)
{
    const Image a = test_image(2, 0.9f), b = test_image(3, 0.9f);
    for (auto _ : state) {
        benchmark::DoNotOptimize(flip_ldr(a, b).mean);
    }
}
BENCHMARK(BM_MetricsFlipLdr)->Unit(benchmark::kMillisecond);

void BM_MetricsFlipHdr(benchmark::State &state)
{
    const Image a = test_image(2, 8.0f), b = test_image(3, 8.0f);
    FlipResult r;
    for (auto _ : state) {
        r = flip_hdr(a, b);
        benchmark::DoNotOptimize(r.mean);
    }
    state.counters["exposures"] = r.num_exposures;
}
BENCHMARK(BM_MetricsFlipHdr)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace posthaste::metrics
