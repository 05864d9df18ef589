// Benchmarks of the relight node (nodes/relight.cpp) at 1920x1080 on a G-buffer of the default
// Minecrappy scene (frame 30, rendered once): 4 lights (a sun, two points, a spot) in the
// default options, with energy compensation, and with screen-space shadows; beside two baselines
// measured in the same run: a tile-parallel copy of the color pass, and a Lambert-only pass
// over the same 4 lights (what the node costs at the least). The counter cpu_ms is the process
// CPU time per iteration (all threads): on a shared machine, divide by the threads for what an
// idle machine would approach.
//   build/tests/posthaste_benchmarks --benchmark_filter=Relight --benchmark_repetitions=5
//       --benchmark_report_aggregates_only=true   (one command line)
#include <benchmark/benchmark.h>
#include <hwy/targets.h>

#include <ctime>
#include <glm/geometric.hpp>
#include <string>

#include "bench_util.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "shading/camera_rays.h"
#include "shading/lighting/occluder_thickness.h"
#include "test_util.h"

namespace posthaste {
namespace {

const Frame &gbuffer()
{
    return bench::minecrappy_frame(
        30, {"color", "normal", "position", "albedo", "material", "tangent", "id", "depth"}, false);
}

using bench::process_cpu_ms;

const char *kLights = R"("lights": [
    {"type": "directional", "direction": [0.4, 0.75, 0.3], "color": [1, 0.95, 0.88], "intensity": 4},
    {"type": "point", "position": [60, 20, 60], "color": [1, 0.6, 0.3], "intensity": 200},
    {"type": "point", "position": [70, 18, 50], "color": [0.3, 0.6, 1], "intensity": 150},
    {"type": "spot", "position": [64, 30, 64], "direction": [0, -1, 0.2], "intensity": 900,
     "inner_deg": 15, "outer_deg": 35}])";

void run_node(benchmark::State &state, const std::string &options)
{
    const Frame &in = gbuffer();
    const test::NodeRunner relight(
        "relight", R"({"mode": "add", "toon_ids": "6", )" + std::string(kLights) + options + "}");
    const auto input = std::make_shared<const Frame>(in);
    bench::timed_loop(state, [&] {
        const Frame out = relight.run(input, 30);
        benchmark::DoNotOptimize(out.image("color").data());
    });
    state.counters["threads"] = thread_count();
}

void BM_OccluderThickness(benchmark::State &state)
{
    // The occluders' thickness the shadow march reads (shading/lighting/occluder_thickness.h),
    // alone: its share of the shadowed run.
    const Frame &in = gbuffer();
    const Camera &camera = in.camera;
    const shading::CameraRays rays(*camera.world_to_camera, *camera.world_to_ndc);
    for (auto _ : state) {
        const Image t =
            shading::occluder_thickness(in.image("depth"), in.image("normal"), rays, 0.5f);
        benchmark::DoNotOptimize(t.data());
    }
}

void BM_RelightBaselineCopy(benchmark::State &state)
{
    const Image &c = gbuffer().image("color");
    bench::timed_loop(state, [&] {
        Image out = Image::uninitialized(c.width(), c.height(), c.channels());
        parallel_for_tiles(out.bounds(), [&](const Rect &t) {
            for (int y = t.y0; y < t.y1; ++y) {
                std::copy(
                    c.pixel(t.x0, y), c.pixel(t.x1 - 1, y) + c.channels(), out.pixel(t.x0, y));
            }
        });
        benchmark::DoNotOptimize(out.data());
    });
}

// Lambert only, the same 4 lights as points/suns (spot cone ignored): the floor of any
// per-pixel, per-light relighting that reads N, P and albedo.
void BM_RelightBaselineLambert(benchmark::State &state)
{
    const Frame &f = gbuffer();
    const Image &c = f.image("color"), &n = f.image("normal"), &p = f.image("position");
    const Image &a = f.image("albedo");
    const glm::vec3 sun = glm::normalize(glm::vec3(0.4f, 0.75f, 0.3f));
    const glm::vec3 pts[3] = {{60, 20, 60}, {70, 18, 50}, {64, 30, 64}};
    const float power[3] = {200, 150, 900};
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = process_cpu_ms();
        Image out = Image::uninitialized(c.width(), c.height(), 4);
        parallel_for_tiles(out.bounds(), [&](const Rect &t) {
            for (int y = t.y0; y < t.y1; ++y) {
                for (int x = t.x0; x < t.x1; ++x) {
                    const glm::vec3 nn(n.at(x, y, 0), n.at(x, y, 1), n.at(x, y, 2));
                    const glm::vec3 pp(p.at(x, y, 0), p.at(x, y, 1), p.at(x, y, 2));
                    float e = 4.0f * std::max(glm::dot(nn, sun), 0.0f);
                    for (int k = 0; k < 3; ++k) {
                        const glm::vec3 d = pts[k] - pp;
                        const float d2 = glm::dot(d, d);
                        e += power[k] * std::max(glm::dot(nn, d), 0.0f) / (d2 * std::sqrt(d2));
                    }
                    float *o = out.pixel(x, y);
                    const float *ci = c.pixel(x, y);
                    for (int ch = 0; ch < 3; ++ch) {
                        o[ch] = ci[ch] + a.at(x, y, ch) * e * (1.0f / 3.14159265f);
                    }
                    o[3] = ci[3];
                }
            }
        });
        benchmark::DoNotOptimize(out.data());
        cpu += process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
}

void BM_Relight4Lights(benchmark::State &state)
{
    run_node(state, "");
}

// The same work on one thread: its CPU time is the work itself, free of the pool's spinning.
void BM_Relight4LightsOneThread(benchmark::State &state)
{
    set_thread_count(1);
    run_node(state, "");
    set_thread_count(0);
}

// The same work on the reference, one pixel at a time (POSTHASTE_SIMD=scalar; the same bits).
void BM_Relight4LightsPortable(benchmark::State &state)
{
    simd::ScopedLevel scalar(simd::Level::Scalar);
    run_node(state, "");
}

// The same work on the vector rows compiled for Highway's portable one-lane target.
void BM_Relight4LightsOneLane(benchmark::State &state)
{
    hwy::SetSupportedTargetsForTest(HWY_SCALAR | HWY_EMU128);
    run_node(state, "");
    hwy::SetSupportedTargetsForTest(0);
}

void BM_Relight4LightsEnergyCompensation(benchmark::State &state)
{
    run_node(state, R"(, "energy_compensation": true)");
}

void BM_Relight4LightsScreenShadows(benchmark::State &state)
{
    run_node(state, R"(, "shadows": true)");
}

BENCHMARK(BM_RelightBaselineCopy)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_RelightBaselineLambert)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4Lights)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4LightsOneThread)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4LightsPortable)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4LightsOneLane)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4LightsEnergyCompensation)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Relight4LightsScreenShadows)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_OccluderThickness)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
}  // namespace posthaste
