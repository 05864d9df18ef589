#include "raster/scene_cache.h"

#include <tbb/task_arena.h>

#include "raster/scene.h"

namespace posthaste::raster {

std::shared_ptr<SceneCache> make_scene_cache()
{
    return std::make_shared<SceneCache>();
}

std::shared_ptr<const SceneMeshes> scene_meshes(const Scene &s, SceneCache &cache, bool greedy)
{
    std::lock_guard<std::mutex> lock(cache.mutex);
    auto &slot = cache.meshes[greedy];
    if (!slot) {
        auto m = std::make_shared<SceneMeshes>();
        // Isolated: while this thread waits inside the parallel loop it must not pick up another
        // frame's task that would block on the mutex it holds.
        tbb::this_task_arena::isolate([&] { m->chunks = mesh_chunks(s.world, greedy); });
        for (const Ball &b : s.balls) {
            m->balls.push_back(mesh_sphere(b.radius, b.segments, b.material));
        }
        for (const Mover &mv : s.movers) {
            m->movers.push_back(mesh_box(mv.min, mv.size, mv.material));
        }
        slot = std::move(m);
    }
    return slot;
}

}  // namespace posthaste::raster
