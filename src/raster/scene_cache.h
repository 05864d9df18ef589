#pragma once
// What a scene keeps between renders: its meshes (the static world per meshing mode, the balls,
// the movers) and its static shadow maps, built on first use and shared by copies of the scene
// (Scene::cache). It sits below the renderer: scene.cpp makes an empty one, render.cpp fills it.

#include <glm/mat4x4.hpp>
#include <map>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "raster/mesh.h"

namespace posthaste::raster {

struct Scene;

/// A depth map from the sun: world points to texels and their depth along the sun direction.
struct ShadowMap {
    glm::mat4 raster{1.0f};  // world -> (X, Y, Q, 1); Q grows toward the sun
    int size = 0;
    float texel_m = 0.0f;  // texel size in metres
    std::vector<float> keys;
};

/// The scene's triangle meshes.
struct SceneMeshes {
    std::vector<Mesh> chunks;  // static world
    std::vector<Mesh> balls;   // one per Scene::balls, centred at the origin
    std::vector<Mesh> movers;  // one per Scene::movers, in world space at offset 0
};

/// Meshes per meshing mode and static shadow maps per (meshing mode, size), under one lock.
struct SceneCache {
    std::mutex mutex;
    std::map<bool, std::shared_ptr<const SceneMeshes>> meshes;
    std::map<std::pair<bool, int>, std::shared_ptr<const ShadowMap>> shadows;
};

/// A new, empty cache.
std::shared_ptr<SceneCache> make_scene_cache();

/// The scene's meshes for one meshing mode (`greedy`), built on first use; thread-safe.
std::shared_ptr<const SceneMeshes> scene_meshes(const Scene &s, SceneCache &cache, bool greedy);

}  // namespace posthaste::raster
