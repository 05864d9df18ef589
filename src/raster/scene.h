#pragma once
// The Minecrappy scene: a voxel world (procedural terrain plus explicit boxes), materials, a sun,
// glossy "BRDF balls" that roll, moving blocks, and a keyframed camera. Loaded from JSON
// (samples/scenes/*.json; the format is documented in samples/scenes/README.md).
//
// World: y up, 1 block = 1 metre; voxel (i, j, k) fills [i, i+1] x [j, j+1] x [k, k+1]. Camera:
// yaw 0 looks along +Z, yaw 90 along +X; positive pitch looks up; positive roll turns the image
// clockwise. Camera space is OpenEXR's (+X right, +Y up, +Z forward). Time is in frames
// (continuous: frame 12.25 is a quarter frame after frame 12).

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <string>
#include <vector>

namespace posthaste::raster {

/// A surface material. Ids 1..255 (0 is air / sky in the id pass).
struct Material {
    int id = 1;
    std::string name;
    glm::vec3 albedo{0.5f};
    float roughness = 0.8f;  ///< GGX perceptual roughness.
    float metallic = 0.0f;
    float anisotropy = 0.0f;  ///< [-1, 1].
    bool toon = false;        ///< Banded diffuse in the beauty pass.
};

/// The world generator's parameters.
struct WorldParams {
    std::uint32_t seed = 1;
    int size_x = 128, size_y = 48, size_z = 128;  ///< Blocks along x, y (up), z; <= 512, 256, 512.
    /// "procedural" (seeded terrain, trees, pillars, a lake; needs materials named grass, dirt,
    /// stone, sand, wood, leaves, water) or "none" (only the boxes).
    std::string terrain = "procedural";
    int base_height = 12;      ///< Mean terrain height in blocks (procedural).
    int height_amplitude = 8;  ///< Terrain height variation in blocks (procedural).
    int trees = 40;            ///< Number of trees (procedural).
    int pillars = 12;          ///< Number of thin stone pillars (procedural).
};

/// An axis-aligned box of blocks [min, max) filled with a material (0: air) after the terrain.
struct Box {
    glm::ivec3 min{0}, max{1};
    int material = 1;
};

/// Smooth periodic plus linear motion: offset(t) = velocity t + amplitude sin(2 pi (t / period +
/// phase)), t in frames.
struct Motion {
    glm::vec3 velocity{0.0f};   ///< Metres per frame.
    glm::vec3 amplitude{0.0f};  ///< Metres.
    float period = 48.0f;       ///< Frames.
    float phase = 0.0f;         ///< Fraction of a period.

    glm::vec3 offset(double t) const;
};

/// A glossy sphere that rolls on the ground: it translates by Motion and rotates by the
/// distance travelled along its motion direction over its radius, about up x direction.
struct Ball {
    glm::vec3 center{0.0f};
    float radius = 1.0f;
    int material = 1;
    Motion motion;
    int segments = 48;      ///< Longitude segments, 4..180 (latitude bands = segments / 2).
    float spin_deg = 0.0f;  ///< Spin in place, degrees per frame, about spin_axis.
    glm::vec3 spin_axis{0.0f, 1.0f, 0.0f};  ///< Unit (normalised on load).

    /// Object-to-world transform at time t (frames): translation, rolling, then the spin.
    glm::mat4 transform(double t) const;
};

/// A block (box of blocks) that moves by Motion without rotating.
struct Mover {
    glm::vec3 min{0.0f};
    glm::vec3 size{1.0f};
    int material = 1;
    Motion motion;

    glm::mat4 transform(double t) const;
};

struct Sun {
    glm::vec3 direction{0.3f, 0.8f, 0.2f};  ///< Towards the sun (normalised on load).
    glm::vec3 color{1.0f, 0.95f, 0.9f};
    float illuminance = 3.0f;  ///< Irradiance scale at normal incidence.
};

/// One camera keyframe. Values between keys follow a C1 cubic (Catmull-Rom tangents).
struct CameraKey {
    double frame = 1.0;
    glm::vec3 position{0.0f};
    float yaw_deg = 0.0f, pitch_deg = 0.0f, roll_deg = 0.0f;
    float focal_length_mm = 35.0f;
    float sensor_width_mm = 36.0f;
    float fstop = 8.0f;
    float focus_distance = 10.0f;  ///< Metres.
    float shutter = 0.5f;          ///< Fraction of the frame interval.
};

/// The camera at one instant.
struct CameraState {
    glm::vec3 position{0.0f};
    float yaw_deg = 0.0f, pitch_deg = 0.0f, roll_deg = 0.0f;
    float focal_length_mm = 35.0f;
    float sensor_width_mm = 36.0f;
    float fstop = 8.0f;
    float focus_distance = 10.0f;
    float shutter = 0.5f;

    /// Camera-to-world (columns: right, up, forward, position).
    glm::mat4 camera_to_world() const;
};

/// The voxel grid: material ids, 0 = air.
struct VoxelGrid {
    int nx = 0, ny = 0, nz = 0;
    std::vector<std::uint8_t> cells;

    std::uint8_t at(int x, int y, int z) const
    {
        if (x < 0 || y < 0 || z < 0 || x >= nx || y >= ny || z >= nz) {
            return 0;
        }
        return cells[(std::size_t(y) * std::size_t(nz) + std::size_t(z)) * std::size_t(nx) +
                     std::size_t(x)];
    }
    void set(int x, int y, int z, std::uint8_t m)
    {
        if (x >= 0 && y >= 0 && z >= 0 && x < nx && y < ny && z < nz) {
            cells[(std::size_t(y) * std::size_t(nz) + std::size_t(z)) * std::size_t(nx) +
                  std::size_t(x)] = m;
        }
    }
};

struct SceneCache;  // meshes and shadow maps built on first render (scene_cache.h)
/// A new, empty cache (scene_cache.cpp).
std::shared_ptr<SceneCache> make_scene_cache();

struct Scene {
    std::string name = "scene";
    std::string path;  ///< File it came from ("" when built in code).
    double fps = 24.0;
    int frame_start = 1, frame_end = 48;
    WorldParams world_params;
    std::vector<Material> materials;  ///< Indexed by position; look up by id with material().
    std::vector<Box> boxes;
    std::vector<Ball> balls;
    std::vector<Mover> movers;
    Sun sun;
    float sky_ambient = 1.0f;            ///< Scale of the hemispherical sky light.
    float near_clip = 0.05f;             ///< Metres.
    std::vector<CameraKey> camera_keys;  ///< Sorted by frame; at least one.

    VoxelGrid world;  ///< Generated by load_scene / generate_world.

    /// Material by id, or nullptr.
    const Material *material(int id) const;
    /// The interpolated camera at time t (frames); clamped to the first and last keys.
    CameraState camera_at(double t) const;

    /// Meshes of the static world, built on the first render and shared by copies. Call
    /// invalidate_cache() after changing `world` or `materials`.
    std::shared_ptr<SceneCache> cache;
    void invalidate_cache();
};

/// Load and validate a scene file, then generate its world. Throws Error (exit code 2) naming
/// the file and JSON path ("scene.json:/balls/0/radius: expected number > 0, got -1").
Scene load_scene(const std::string &path);
/// Same, from JSON text; `origin` names the source in error messages.
Scene parse_scene(const std::string &json_text, const std::string &origin);
/// (Re)generate scene.world from world_params and boxes.
void generate_world(Scene &scene);

}  // namespace posthaste::raster
