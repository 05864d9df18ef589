// The scene's voxel world: the procedural terrain (value-noise heights, layered materials,
// trees and water) and the boxes placed over it; parse_scene (scene.cpp) calls generate_world.

#include <algorithm>
#include <cmath>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/hash.h"
#include "core/json_error.h"
#include "raster/scene.h"

namespace posthaste::raster {
namespace {

// Value noise for the terrain height field.
float lattice(int x, int z, std::uint32_t seed)
{
    return hash_unit(x, z, 0, seed);
}

float value_noise(float x, float z, std::uint32_t seed)
{
    const int x0 = int(std::floor(x)), z0 = int(std::floor(z));
    float fx = x - float(x0), fz = z - float(z0);
    fx = fx * fx * (3 - 2 * fx);
    fz = fz * fz * (3 - 2 * fz);
    const float a = lattice(x0, z0, seed), b = lattice(x0 + 1, z0, seed);
    const float c = lattice(x0, z0 + 1, seed), d = lattice(x0 + 1, z0 + 1, seed);
    return (a + (b - a) * fx) + ((c + (d - c) * fx) - (a + (b - a) * fx)) * fz;
}

int find_material(const Scene &s, const char *name)
{
    for (const Material &m : s.materials) {
        if (m.name == name) {
            return m.id;
        }
    }
    throw_usage(s.path.empty() ? s.name : s.path,
                ":/world: procedural terrain needs a material named ",
                posthaste::quoted(name));
}

void generate_procedural(Scene &s)
{
    const WorldParams &p = s.world_params;
    VoxelGrid &w = s.world;
    const auto grass = std::uint8_t(find_material(s, "grass"));
    const auto dirt = std::uint8_t(find_material(s, "dirt"));
    const auto stone = std::uint8_t(find_material(s, "stone"));
    const auto sand = std::uint8_t(find_material(s, "sand"));
    const auto wood = std::uint8_t(find_material(s, "wood"));
    const auto leaves = std::uint8_t(find_material(s, "leaves"));
    const auto water = std::uint8_t(find_material(s, "water"));

    std::vector<int> height(std::size_t(w.nx) * std::size_t(w.nz));
    const float lake_x = w.nx * 0.7f, lake_z = w.nz * 0.35f, lake_r = std::min(w.nx, w.nz) * 0.12f;
    for (int z = 0; z < w.nz; ++z) {
        for (int x = 0; x < w.nx; ++x) {
            float n = 0.0f, amp = 1.0f, freq = 1.0f / 24.0f, norm = 0.0f;
            for (int o = 0; o < 4; ++o) {
                n += amp * value_noise(x * freq, z * freq, p.seed + std::uint32_t(o) * 7919u);
                norm += amp;
                amp *= 0.5f;
                freq *= 2.0f;
            }
            n /= norm;
            float h = float(p.base_height) + (n - 0.5f) * 2.0f * float(p.height_amplitude);
            // The lake: a smooth bowl.
            const float d = std::hypot(x - lake_x, z - lake_z) / lake_r;
            if (d < 1.6f) {
                const float bowl = float(p.base_height) - 5.0f + 5.0f * d * d / 2.56f;
                h = std::min(h, bowl);
            }
            // Not std::clamp: a grid 1 or 2 cells high has no room between its bounds.
            height[std::size_t(z) * std::size_t(w.nx) + std::size_t(x)] =
                std::max(1, std::min(int(std::lround(h)), w.ny - 2));
        }
    }
    const int water_level = p.base_height - 2;
    for (int z = 0; z < w.nz; ++z) {
        for (int x = 0; x < w.nx; ++x) {
            const int h = height[std::size_t(z) * std::size_t(w.nx) + std::size_t(x)];
            const bool beach = h <= water_level + 1;
            for (int y = 0; y < h; ++y) {
                std::uint8_t m = stone;
                if (y == h - 1) {
                    m = beach ? sand : grass;
                } else if (y >= h - 4) {
                    m = beach ? sand : dirt;
                }
                w.set(x, y, z, m);
            }
            for (int y = h; y < water_level; ++y) {
                w.set(x, y, z, water);
            }
        }
    }
    auto ground = [&](int x, int z) {
        return height[std::size_t(z) * std::size_t(w.nx) + std::size_t(x)];
    };
    // Trees: trunks of wood with a blob of leaves, avoiding the lake. Their trunks stand 3 cells
    // inside the edges, so a grid narrower than 7 cells has none.
    const int trees = w.nx >= 7 && w.nz >= 7 ? p.trees : 0;
    for (int i = 0; i < trees; ++i) {
        const int x = 3 + int(hash_unit(i, 1, 0, p.seed) * float(w.nx - 6));
        const int z = 3 + int(hash_unit(i, 2, 0, p.seed) * float(w.nz - 6));
        const int g = ground(x, z);
        if (g <= water_level + 1) {
            continue;
        }
        const int trunk = 4 + int(hash_unit(i, 3, 0, p.seed) * 3.0f);
        for (int y = g; y < g + trunk; ++y) {
            w.set(x, y, z, wood);
        }
        const int top = g + trunk;
        for (int dy = -2; dy <= 1; ++dy) {
            const int r = dy == 1 ? 1 : 2;
            for (int dz = -r; dz <= r; ++dz) {
                for (int dx = -r; dx <= r; ++dx) {
                    if (std::abs(dx) == r && std::abs(dz) == r &&
                        hash_unit(x + dx, z + dz, dy, p.seed) < 0.6f) {
                        continue;  // ragged corners
                    }
                    if (w.at(x + dx, top + dy, z + dz) == 0) {
                        w.set(x + dx, top + dy, z + dz, leaves);
                    }
                }
            }
        }
    }
    // Thin pillars (1 x 1 blocks, tall) and a 1-block-thin beam between pairs: features against
    // the sky at many depths.
    const int pillars = w.nx >= 5 && w.nz >= 5 ? p.pillars : 0;  // 2 cells inside the edges
    for (int i = 0; i < pillars; ++i) {
        const int x = 2 + int(hash_unit(i, 4, 0, p.seed) * float(w.nx - 4));
        const int z = 2 + int(hash_unit(i, 5, 0, p.seed) * float(w.nz - 4));
        const int g = ground(x, z);
        const int top = std::min(w.ny - 1, g + 8 + int(hash_unit(i, 6, 0, p.seed) * 12.0f));
        for (int y = g; y < top; ++y) {
            w.set(x, y, z, stone);
        }
        if (i % 3 == 0 && x + 6 < w.nx) {
            const int top2 = std::min(w.ny - 1, ground(x + 6, z) + 8);
            const int beam = std::min(top, top2) - 1;
            for (int y = ground(x + 6, z); y < top2; ++y) {
                w.set(x + 6, y, z, stone);
            }
            for (int bx = x; bx <= x + 6; ++bx) {
                w.set(bx, beam, z, wood);
            }
        }
    }
}

}  // namespace

void generate_world(Scene &s)
{
    const WorldParams &p = s.world_params;
    s.world.nx = p.size_x;
    s.world.ny = p.size_y;
    s.world.nz = p.size_z;
    s.world.cells.assign(std::size_t(p.size_x) * std::size_t(p.size_y) * std::size_t(p.size_z), 0);
    if (p.terrain == "procedural") {
        generate_procedural(s);
    }
    // A box may reach past the world (any int corners are accepted, e.g. "everything below y =
    // 3"): only its part inside the grid is visited, a row at a time, so the cost is bounded by
    // the grid's size whatever the corners are.
    const glm::ivec3 grid(s.world.nx, s.world.ny, s.world.nz);
    for (const Box &b : s.boxes) {
        const glm::ivec3 lo = glm::clamp(b.min, glm::ivec3(0), grid);
        const glm::ivec3 hi = glm::clamp(b.max, glm::ivec3(0), grid);
        if (lo.x >= hi.x) {
            continue;
        }
        for (int y = lo.y; y < hi.y; ++y) {
            for (int z = lo.z; z < hi.z; ++z) {
                std::uint8_t *row =
                    s.world.cells.data() +
                    (std::size_t(y) * std::size_t(grid.z) + std::size_t(z)) * std::size_t(grid.x);
                std::fill(row + lo.x, row + hi.x, std::uint8_t(b.material));
            }
        }
    }
    s.invalidate_cache();
}

}  // namespace posthaste::raster
