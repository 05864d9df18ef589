// Tests for src/raster/scene: loading the sample scenes, errors with file and JSON path,
// camera interpolation.
#include "raster/scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "test_util.h"

namespace posthaste::raster {
namespace {

std::string sample(const std::string &name)
{
    return std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/" + name;
}

std::string error_of(const std::string &json)
{
    try {
        parse_scene(json, "test.json");
    } catch (const Error &e) {
        EXPECT_EQ(e.exit_code(), 2);
        return e.what();
    }
    return "";
}

TEST(Scene, LoadsSamples)
{
    for (const char *name : {"minecrappy.json",
                             "cube.json",
                             "plane.json",
                             "two_planes.json",
                             "thin_sky.json",
                             "fast_crossing.json"}) {
        const Scene s = load_scene(sample(name));
        EXPECT_FALSE(s.camera_keys.empty()) << name;
        EXPECT_EQ(s.world.cells.size(),
                  std::size_t(s.world.nx) * std::size_t(s.world.ny) * std::size_t(s.world.nz));
    }
    const Scene s = load_scene(sample("minecrappy.json"));
    EXPECT_EQ(s.name, "minecrappy");
    EXPECT_EQ(s.frame_start, 1);
    EXPECT_EQ(s.frame_end, 48);
    EXPECT_EQ(s.balls.size(), 3u);
    // Every material of the procedural set appears somewhere.
    for (const char *m : {"grass", "dirt", "stone", "sand", "wood", "leaves", "water"}) {
        int id = 0;
        for (const Material &mat : s.materials) {
            if (mat.name == m) {
                id = mat.id;
            }
        }
        ASSERT_NE(id, 0) << m;
        EXPECT_NE(std::count(s.world.cells.begin(), s.world.cells.end(), std::uint8_t(id)), 0) << m;
    }
    // Same seed, same world.
    EXPECT_EQ(load_scene(sample("minecrappy.json")).world.cells, s.world.cells);
}

TEST(Scene, ErrorsNameFileAndPath)
{
    const std::string base = R"({"materials": [{"id": 1}], "camera": [{"frame": 1}])";
    EXPECT_NE(error_of(base + R"(, "balls": [{"radius": -1}]})").find("test.json:/balls/0/radius"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "bogus": 1})").find("test.json:/bogus: unknown key"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "boxes": [{"material": 9}]})").find("/boxes/0/material"),
              std::string::npos);
    EXPECT_NE(error_of(R"({"materials": [{"id": 1}]})").find("/camera"), std::string::npos);
    EXPECT_NE(error_of(base + R"(, "balls": [{"spin_deg": 30, "spin_axis": [0, 0, 0]}]})")
                  .find("test.json:/balls/0/spin_axis: expected a non-zero vector"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "balls": [{"spin_deg": 200}]})").find("/balls/0/spin_deg"),
              std::string::npos);
    EXPECT_NE(error_of("{nope").find("invalid JSON"), std::string::npos);
    // A frame range of 2e9 frames took memory without bound; a mover of negative size was taken.
    EXPECT_NE(
        error_of(base + R"(, "frame_range": [1, 2000000000]})").find("/frame_range: expected"),
        std::string::npos);
    EXPECT_NE(error_of(base + R"(, "frame_range": [1, 1e19]})").find("/frame_range: expected"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "movers": [{"size": [-1, 2, 2]}]})").find("/movers/0/size"),
              std::string::npos);
    // Vectors hold finite floats (1e39 read as infinity), an albedo reflects at most all.
    EXPECT_NE(error_of(base + R"(, "sun": {"color": [1e39, 1, 1]}})")
                  .find("test.json:/sun/color: expected numbers in 0..1e+06"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "balls": [{"center": [0, -1e39, 0]}]})")
                  .find("/balls/0/center: expected numbers in"),
              std::string::npos);
    EXPECT_NE(error_of(R"({"materials": [{"id": 1, "albedo": [0.5, 1e5, 0.5]}], "camera": [{}]})")
                  .find("/materials/0/albedo: expected numbers in 0..1"),
              std::string::npos);
    EXPECT_NE(error_of(base + R"(, "fps": 24, "fps": 25})")
                  .find("test.json: key \"fps\" in the top level is given twice"),
              std::string::npos)
        << error_of(base + R"(, "fps": 24, "fps": 25})");
    EXPECT_NE(error_of(base + R"(, "world": {"terrain": "procedural"}})").find("grass"),
              std::string::npos);
    EXPECT_THROW(load_scene("/nonexistent/scene.json"), Error);
    // The CLI says "error: " once; a folder is named for what it is, not as invalid JSON.
    EXPECT_EQ(error_of("{nope").rfind("error: ", 0), std::string::npos) << error_of("{nope");
    try {
        load_scene(test::scratch_dir("scene_folder"));
        ADD_FAILURE() << "a folder loaded as a scene";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("is a folder, not a scene file"), std::string::npos)
            << e.what();
        EXPECT_EQ(e.exit_code(), 2);
    }
}

// Boxes may reach past the world; only the part inside is filled, at a cost bounded by the
// grid (corners at int's limits once made the fill loop run for ~10^28 steps).
TEST(Scene, BoxesAreClippedToTheWorld)
{
    const std::string head = R"({"materials": [{"id": 1}, {"id": 2}], "camera": [{"frame": 1}],
        "world": {"terrain": "none", "size": [4, 3, 5]}, "boxes": )";
    auto count = [](const Scene &s, int m) {
        return std::count(s.world.cells.begin(), s.world.cells.end(), std::uint8_t(m));
    };
    const Scene all = parse_scene(head + R"([{"min": [-2147483648, -2147483648, -2147483648],
                     "max": [2147483647, 2147483647, 2147483647], "material": 2}]})",
                                  "test.json");
    EXPECT_EQ(count(all, 2), 4 * 3 * 5);
    // Partly outside: x in [2, 4), y in [0, 1), z in [0, 5) -> 2 * 1 * 5 cells; then material 0
    // carves the cell (3, 0, 4); an inverted box and one wholly outside fill nothing.
    const Scene part = parse_scene(head + R"([{"min": [2, -7, -100], "max": [99, 1, 100]},
                                              {"min": [3, 0, 4], "max": [4, 1, 5], "material": 0},
                                              {"min": [3, 2, 4], "max": [1, 3, 5]},
                                              {"min": [4, 0, 0], "max": [9, 3, 5]}]})",
                                   "test.json");
    EXPECT_EQ(count(part, 1), 2 * 1 * 5 - 1);
    EXPECT_EQ(part.world.at(2, 0, 0), 1);
    EXPECT_EQ(part.world.at(3, 0, 3), 1);
    EXPECT_EQ(part.world.at(3, 0, 4), 0);
    EXPECT_EQ(part.world.at(1, 0, 0), 0);
    EXPECT_EQ(part.world.at(2, 1, 0), 0);
    // Integers past int's range are errors, not wrapped values.
    EXPECT_NE(error_of(head + R"([{"min": [4294967296, 0, 0]}]})").find("/boxes/0/min"),
              std::string::npos);
    EXPECT_NE(error_of(head + R"([{"max": [0, -2147483649, 0]}]})").find("/boxes/0/max"),
              std::string::npos);
    EXPECT_NE(error_of(head + R"([{"material": 18446744073709551615}]})").find("/boxes/0/material"),
              std::string::npos);
}

// Procedural terrain on grids too small for its trees, pillars or a layer between bedrock and
// sky: every size in range gives a world (ASan checks the indices).
TEST(Scene, ProceduralTerrainOnTinyWorlds)
{
    const std::string materials = R"({"materials": [{"id": 1, "name": "grass"},
        {"id": 2, "name": "dirt"}, {"id": 3, "name": "stone"}, {"id": 4, "name": "sand"},
        {"id": 5, "name": "wood"}, {"id": 6, "name": "leaves"}, {"id": 7, "name": "water"}],
        "camera": [{"frame": 1}], "world": {"terrain": "procedural", "trees": 50, "pillars": 50,
        "size": )";
    for (const char *size : {"[1, 1, 1]", "[2, 2, 2]", "[6, 3, 6]", "[7, 4, 7]", "[1, 256, 9]"}) {
        const Scene s = parse_scene(materials + size + "}}", "test.json");
        EXPECT_EQ(s.world.cells.size(),
                  std::size_t(s.world.nx) * std::size_t(s.world.ny) * std::size_t(s.world.nz))
            << size;
        // The ground's top layer is at y >= 1 wherever the grid is at least 3 high.
        if (s.world.ny >= 3) {
            EXPECT_NE(s.world.at(0, 0, 0), 0) << size;
        }
    }
}

TEST(Scene, CameraInterpolationIsSmoothAndHitsKeys)
{
    const Scene s = parse_scene(R"({"materials": [{"id": 1}], "world": {"terrain": "none"},
        "camera": [{"frame": 1, "position": [0, 0, 0], "yaw_deg": 0},
                   {"frame": 5, "position": [4, 0, 0], "yaw_deg": 40},
                   {"frame": 9, "position": [4, 4, 0], "yaw_deg": 40}]})",
                                "test.json");
    EXPECT_FLOAT_EQ(s.camera_at(5.0).position.x, 4.0f);
    EXPECT_FLOAT_EQ(s.camera_at(5.0).yaw_deg, 40.0f);
    EXPECT_FLOAT_EQ(s.camera_at(0.0).position.x, 0.0f);
    // Continuity across a key and at sub-frame steps.
    const float a = s.camera_at(5.0 - 1e-4).position.x, b = s.camera_at(5.0 + 1e-4).position.x;
    EXPECT_NEAR(a, b, 1e-3);
    EXPECT_GT(s.camera_at(3.0).position.x, 1.0f);
    EXPECT_LT(s.camera_at(3.0).position.x, 3.0f);
}

TEST(Scene, CameraAxes)
{
    CameraState c;
    c.yaw_deg = 90.0f;
    const glm::mat4 m = c.camera_to_world();
    EXPECT_NEAR(m[2].x, 1.0f, 1e-6);  // yaw 90 looks along +X
    EXPECT_NEAR(m[0].z, -1.0f, 1e-6);
    c.yaw_deg = 0.0f;
    c.pitch_deg = 30.0f;
    EXPECT_GT(c.camera_to_world()[2].y, 0.49f);  // positive pitch looks up
}

}  // namespace
}  // namespace posthaste::raster
