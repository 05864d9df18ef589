// Atmosphere and height fog costs: LUT builds, and per-frame application at 1920x1080 given a
// depth buffer (node targets: height fog <= 10 ms, aerial perspective <= 30 ms on 2 cores).

#include <benchmark/benchmark.h>

#include <cmath>
#include <glm/trigonometric.hpp>

#include "core/camera.h"
#include "core/disk_cache.h"
#include "core/image.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/fog/height_fog.h"

namespace posthaste::shading {
namespace {

constexpr int kWidth = 1920, kHeight = 1080;

// Benchmarks take the worker thread count as their argument (1, and 2 for the target machine).
struct ThreadScope {
    explicit ThreadScope(const benchmark::State &state) { set_thread_count(int(state.range(0))); }
    ~ThreadScope() { set_thread_count(0); }
};

// The per-frame benchmarks run twice: as dispatched (AVX2 on this machine), and with the portable
// scalar path forced, the baseline in the same run.
template <void (*Body)(benchmark::State &)>
void scalar_path(benchmark::State &state)
{
    const simd::ScopedLevel scalar(simd::Level::Scalar);
    Body(state);
}

AtmosphereParams earth_params()
{
    AtmosphereParams p;
    const float e = glm::radians(25.0f), a = glm::radians(40.0f);
    p.sun_direction = {std::cos(e) * std::sin(a), std::sin(e), std::cos(e) * std::cos(a)};
    return p;
}

CameraMatrices bench_camera()
{
    glm::mat4 c2w(1.0f);
    const float pitch = glm::radians(-10.0f);
    c2w[1] = glm::vec4(0.0f, std::cos(pitch), std::sin(pitch), 0.0f);
    c2w[2] = glm::vec4(0.0f, -std::sin(pitch), std::cos(pitch), 0.0f);
    c2w[3] = glm::vec4(0.0f, 20.0f, 0.0f, 1.0f);
    return make_camera_matrices(c2w, 24.0f, 36.0f, float(kWidth) / kHeight, 0.1f);
}

// A ground plane at y = 0 seen from 20 m (distances up to a few km), sky above the horizon.
Image bench_depth(const CameraRays &rays)
{
    Image depth(kWidth, kHeight, 1);
    for (int y = 0; y < kHeight; ++y) {
        for (int x = 0; x < kWidth; ++x) {
            const glm::vec3 p = rays.depth_ray((x + 0.5f) / kWidth, (y + 0.5f) / kHeight);
            depth.at(x, y, 0) = p.y < -1e-3f ? rays.position().y / -p.y : INFINITY;
        }
    }
    return depth;
}

Image bench_color()
{
    Image color(kWidth, kHeight, 4);
    color.fill(0.5f);
    return color;
}

void BM_AtmosphereBuildLuts(benchmark::State &state)
{
    const ThreadScope threads(state);
    const AtmosphereParams p = earth_params();
    disk_cache::set_enabled(false);  // the build itself
    for (auto _ : state) {
        Atmosphere atmo(p);
        benchmark::DoNotOptimize(&atmo);
    }
    disk_cache::set_enabled(true);
}
BENCHMARK(BM_AtmosphereBuildLuts)->Unit(benchmark::kMillisecond)->UseRealTime()->Arg(1)->Arg(2);

/// The same LUTs read from the disk cache (a warm page cache: the entry is read every iteration).
void BM_AtmosphereLoadLuts(benchmark::State &state)
{
    const AtmosphereParams p = earth_params();
    Atmosphere first(p);  // stores the entry when it is not there
    benchmark::DoNotOptimize(&first);
    if (!disk_cache::enabled()) {
        state.SkipWithError("the disk cache is off");
        return;
    }
    for (auto _ : state) {
        Atmosphere atmo(p);
        benchmark::DoNotOptimize(&atmo);
    }
}
BENCHMARK(BM_AtmosphereLoadLuts)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_SkyViewBuild(benchmark::State &state)
{
    const ThreadScope threads(state);
    const Atmosphere atmo(earth_params());
    for (auto _ : state) {
        SkyView view = atmo.make_sky_view(glm::vec3(0.0f, 20.0f, 0.0f));
        benchmark::DoNotOptimize(&view);
    }
}
BENCHMARK(BM_SkyViewBuild)->Unit(benchmark::kMillisecond)->UseRealTime()->Arg(1)->Arg(2);

void BM_AerialPerspectiveBuild(benchmark::State &state)
{
    const ThreadScope threads(state);
    const Atmosphere atmo(earth_params());
    const CameraMatrices m = bench_camera();
    for (auto _ : state) {
        AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
        benchmark::DoNotOptimize(&ap);
    }
}
BENCHMARK(BM_AerialPerspectiveBuild)->Unit(benchmark::kMillisecond)->UseRealTime()->Arg(1)->Arg(2);

void BM_HeightFogFrame1080p(benchmark::State &state)
{
    const ThreadScope threads(state);
    const CameraMatrices m = bench_camera();
    const CameraRays rays(m.world_to_camera, m.world_to_ndc);
    const Image depth = bench_depth(rays);
    const Image color = bench_color();
    HeightFog fog;
    fog.density = 0.01f;
    fog.falloff = 0.05f;
    fog.sun_color = glm::vec3(0.5f);
    fog.sun_direction = earth_params().sun_direction;
    Image out = color;
    for (auto _ : state) {
        apply_height_fog(fog, rays, depth, out);
        benchmark::ClobberMemory();
    }
}
BENCHMARK_TEMPLATE(scalar_path, BM_HeightFogFrame1080p)
    ->Name("BM_HeightFogFrame1080pScalar")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Arg(2);
BENCHMARK(BM_HeightFogFrame1080p)->Unit(benchmark::kMillisecond)->UseRealTime()->Arg(1)->Arg(2);

// Per frame: build the froxels for the camera, then apply them to every pixel with geometry.
void BM_AerialPerspectiveFrame1080p(benchmark::State &state)
{
    const ThreadScope threads(state);
    const Atmosphere atmo(earth_params());
    const CameraMatrices m = bench_camera();
    const CameraRays rays(m.world_to_camera, m.world_to_ndc);
    const Image depth = bench_depth(rays);
    Image out = bench_color();
    for (auto _ : state) {
        const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
        apply_aerial_perspective(ap, depth, out);
        benchmark::ClobberMemory();
    }
}
BENCHMARK_TEMPLATE(scalar_path, BM_AerialPerspectiveFrame1080p)
    ->Name("BM_AerialPerspectiveFrame1080pScalar")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Arg(2);
BENCHMARK(BM_AerialPerspectiveFrame1080p)
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Arg(1)
    ->Arg(2);

// Per frame: build the froxels, then aerial perspective on geometry plus the sky-view LUT (and
// sun disc) on sky pixels, via apply_atmosphere.
void BM_AtmosphereFrame1080p(benchmark::State &state)
{
    const ThreadScope threads(state);
    const Atmosphere atmo(earth_params());
    const CameraMatrices m = bench_camera();
    const CameraRays rays(m.world_to_camera, m.world_to_ndc);
    const Image depth = bench_depth(rays);
    Image out = bench_color();
    for (auto _ : state) {
        const AerialPerspective ap(atmo, m.world_to_camera, m.world_to_ndc);
        apply_atmosphere(atmo, atmo.cached_sky_view(), ap, depth, out);
        benchmark::ClobberMemory();
    }
}
BENCHMARK_TEMPLATE(scalar_path, BM_AtmosphereFrame1080p)
    ->Name("BM_AtmosphereFrame1080pScalar")
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime()
    ->Arg(2);
BENCHMARK(BM_AtmosphereFrame1080p)->Unit(benchmark::kMillisecond)->UseRealTime()->Arg(1)->Arg(2);

}  // namespace
}  // namespace posthaste::shading
