// Tests for src/raster/scene: loading the sample scenes, errors with file and JSON path,
// camera interpolation.
#include "raster/scene.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"

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
    EXPECT_NE(error_of(base + R"(, "world": {"terrain": "procedural"}})").find("grass"),
              std::string::npos);
    EXPECT_THROW(load_scene("/nonexistent/scene.json"), Error);
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
