#pragma once
// Shared by the benchmark files: process CPU time (all threads), and frames of the default
// Minecrappy scene rendered on first use and kept for the process, so each benchmark times its
// node on the same input without rendering it again.

#include <benchmark/benchmark.h>

#include <ctime>
#include <map>
#include <set>
#include <string>
#include <tuple>

#include "core/parallel.h"
#include "raster/render.h"

namespace posthaste::bench {

/// CPU time of the whole process (every thread), milliseconds.
inline double process_cpu_ms()
{
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

/// Runs `body` once per benchmark iteration and reports the process's CPU time per iteration
/// (every thread) as counter cpu_ms, beside the benchmark's wall time.
template <typename Body>
void timed_loop(benchmark::State &state, Body &&body)
{
    double cpu = 0.0;
    for (auto _ : state) {
        const double c0 = process_cpu_ms();
        body();
        cpu += process_cpu_ms() - c0;
    }
    state.counters["cpu_ms"] = cpu / double(state.iterations());
}

/// The baseline a node that outputs a new image pays at least: a copy of `image` into a fresh
/// one, rows in parallel on 2 threads; counter cpu_ms as the node benchmarks report it.
inline void copy_baseline(benchmark::State &state, const Image &image)
{
    set_thread_count(2);
    timed_loop(state, [&] {
        Image out = Image::uninitialized(image.width(), image.height(), image.channels());
        parallel_for(0, image.height(), [&](int y) {
            std::copy(image.pixel(0, y),
                      image.pixel(0, y) + std::size_t(image.width()) * image.channels(),
                      out.pixel(0, y));
        });
        benchmark::DoNotOptimize(out.data());
    });
    set_thread_count(0);
}

/// Frame `frame` of samples/scenes/`scene_file` at 1920x1080 with `passes`, rendered once.
/// Benchmarks register and run on one thread, so the cache needs no lock.
inline const Frame &scene_frame(const std::string &scene_file,
                                int frame,
                                const std::set<std::string> &passes,
                                bool shadows = true)
{
    using Key = std::tuple<std::string, int, std::set<std::string>, bool>;
    static std::map<Key, Frame> frames;
    static std::map<std::string, raster::Scene> scenes;
    const Key key{scene_file, frame, passes, shadows};
    auto it = frames.find(key);
    if (it == frames.end()) {
        auto sc = scenes.find(scene_file);
        if (sc == scenes.end()) {
            sc = scenes
                     .emplace(scene_file,
                              raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) +
                                                 "/samples/scenes/" + scene_file))
                     .first;
        }
        raster::RenderOptions o;
        o.width = 1920;
        o.height = 1080;
        o.shadows = shadows;
        o.passes = passes;
        it = frames.emplace(key, raster::render_frame(sc->second, frame, o)).first;
    }
    return it->second;
}

/// scene_frame with the header's sun and sky as the render node writes them (posthaste:
/// sunDirection, skyAmbient, sunIrradiance), for the nodes that default to them (ssr, ssgi).
inline const Frame &sun_frame(const std::string &scene_file,
                              int frame,
                              const std::set<std::string> &passes)
{
    using Key = std::tuple<std::string, int, std::set<std::string>>;
    static std::map<Key, Frame> frames;
    const Key key{scene_file, frame, passes};
    auto it = frames.find(key);
    if (it == frames.end()) {
        Frame f = scene_frame(scene_file, frame, passes, true);
        const raster::Scene s =
            raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/" + scene_file);
        const glm::vec3 d = s.sun.direction, sun = s.sun.color * s.sun.illuminance;
        f.attributes.push_back(OIIO::ParamValue("posthaste:sunDirection", OIIO::TypeVector, 1, &d));
        f.attributes.push_back(OIIO::ParamValue("posthaste:skyAmbient", s.sky_ambient));
        f.attributes.push_back(
            OIIO::ParamValue("posthaste:sunIrradiance", OIIO::TypeVector, 1, &sun));
        it = frames.emplace(key, std::move(f)).first;
    }
    return it->second;
}

/// Frame `frame` of samples/scenes/minecrappy.json at 1920x1080 with `passes`, rendered once.
inline const Frame &minecrappy_frame(int frame,
                                     const std::set<std::string> &passes,
                                     bool shadows = true)
{
    return scene_frame("minecrappy.json", frame, passes, shadows);
}

}  // namespace posthaste::bench
