#pragma once
// Meshes for the rasterizer: voxel chunks (only faces between a block and air, optionally merged
// greedily per material), boxes and tessellated spheres with analytic normals and tangents.
// Winding: a triangle (a, b, c) faces outward along cross(b - a, c - a).

#include <cstdint>
#include <glm/vec3.hpp>
#include <vector>

#include "raster/scene.h"

namespace posthaste::raster {

struct Mesh {
    std::vector<glm::vec3> positions;
    std::vector<glm::vec3> normals;   ///< Unit, per vertex.
    std::vector<glm::vec3> tangents;  ///< Unit, per vertex, perpendicular to the normal.
    std::vector<glm::uvec3> triangles;
    std::vector<std::uint8_t> materials;  ///< Material id per triangle.
    glm::vec3 bounds_min{0.0f}, bounds_max{0.0f};

    std::size_t triangle_count() const { return triangles.size(); }
    void compute_bounds();
};

inline constexpr int kChunkSize = 16;

/// One mesh per non-empty chunk of kChunkSize^3 blocks. Faces are emitted only where a solid
/// block meets air (cells outside the grid are air). With `greedy`, coplanar faces of one
/// material are merged into rectangles: fewer triangles, but T-junctions, so edges are no longer
/// guaranteed watertight after snapping. Runs in parallel over chunks; deterministic.
std::vector<Mesh> mesh_chunks(const VoxelGrid &grid, bool greedy);

/// An axis-aligned box [min, min + size] with outward faces.
Mesh mesh_box(const glm::vec3 &min, const glm::vec3 &size, int material);

/// A UV sphere centred at the origin: `segments` longitudes, segments / 2 latitude bands.
/// Normals are p / radius; tangents follow increasing longitude (d p / d phi).
Mesh mesh_sphere(float radius, int segments, int material);

}  // namespace posthaste::raster
