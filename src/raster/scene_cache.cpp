#include "raster/scene_cache.h"

#include <tbb/task_arena.h>

#include <cstdint>
#include <stdexcept>
#include <string_view>

#include "core/disk_cache.h"
#include "raster/mesh.h"
#include "raster/scene.h"

namespace posthaste::raster {
namespace {

/// mesh_chunks through the disk cache (core/disk_cache.h), keyed by the grid's cells.
std::vector<Mesh> cached_chunks(const VoxelGrid &grid, bool greedy)
{
    disk_cache::Key key("voxel_meshes");
    key.add(std::int32_t(grid.nx)).add(std::int32_t(grid.ny)).add(std::int32_t(grid.nz));
    key.add(std::uint8_t(greedy));
    key.add_string(
        std::string_view(reinterpret_cast<const char *>(grid.cells.data()), grid.cells.size()));
    constexpr std::size_t kMax = std::size_t(1) << 28;
    return disk_cache::cached<std::vector<Mesh>>(
        key,
        [&] { return mesh_chunks(grid, greedy); },
        [](const std::vector<Mesh> &meshes, disk_cache::Writer &w) {
            w.put(std::uint64_t(meshes.size()));
            for (const Mesh &m : meshes) {
                w.put_vector(m.positions);
                w.put_vector(m.normals);
                w.put_vector(m.tangents);
                w.put_vector(m.triangles);
                w.put_vector(m.materials);
                w.put(m.bounds_min);
                w.put(m.bounds_max);
            }
        },
        [&](disk_cache::Reader &r) {
            const auto n = r.get<std::uint64_t>();
            if (n > kMax) {
                throw std::out_of_range("voxel_meshes: too many chunks");
            }
            std::vector<Mesh> meshes(static_cast<std::size_t>(n));
            for (Mesh &m : meshes) {
                m.positions = r.get_vector<glm::vec3>(kMax);
                m.normals = r.get_vector<glm::vec3>(kMax);
                m.tangents = r.get_vector<glm::vec3>(kMax);
                m.triangles = r.get_vector<glm::uvec3>(kMax);
                m.materials = r.get_vector<std::uint8_t>(kMax);
                m.bounds_min = r.get<glm::vec3>();
                m.bounds_max = r.get<glm::vec3>();
                const std::size_t v = m.positions.size();
                if (m.normals.size() != v || m.tangents.size() != v ||
                    m.materials.size() != m.triangles.size()) {
                    throw std::out_of_range("voxel_meshes: inconsistent mesh");
                }
                for (const glm::uvec3 &t : m.triangles) {
                    if (t.x >= v || t.y >= v || t.z >= v) {
                        throw std::out_of_range("voxel_meshes: index out of range");
                    }
                }
            }
            return meshes;
        });
}

}  // namespace

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
        tbb::this_task_arena::isolate([&] { m->chunks = cached_chunks(s.world, greedy); });
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
