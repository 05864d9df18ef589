// The camera solved from position and depth passes (core/camera_solve.h) and the read node's
// camera sources: the header, the graph's `camera` parameter, or the solve.

#include "core/camera_solve.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>

#include "core/error.h"
#include "io/image_file.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// The largest difference of two matrices relative to the larger one's largest element.
double relative_difference(const glm::mat4 &a, const glm::mat4 &b)
{
    double diff = 0.0, scale = 0.0;
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            diff = std::max(diff, double(std::abs(a[c][r] - b[c][r])));
            scale = std::max({scale, double(std::abs(a[c][r])), double(std::abs(b[c][r]))});
        }
    }
    return diff / scale;
}

/// A frame of the bundled scene with position and depth, rendered by the rasterizer.
Frame rendered(int frame, int w = 320, int h = 180)
{
    static const raster::Scene scene = raster::load_scene(test::scene_path("minecrappy.json"));
    return raster::render_frame(scene, frame, test::render_options(w, h, {"position", "depth"}));
}

/// Pixels of the depth pass projected through a camera: the largest distance in pixels between
/// where worldToNDC puts each position and the pixel that holds it.
double max_reprojection_px(const Frame &f, const glm::mat4 &world_to_ndc)
{
    const Image &p = f.image("position");
    const Image &d = f.image("depth");
    double worst = 0.0;
    for (int y = 0; y < p.height(); y += 3) {
        for (int x = 0; x < p.width(); x += 3) {
            if (!std::isfinite(d.pixel(x, y)[0])) {
                continue;
            }
            glm::vec2 px;
            const float *q = p.pixel(x, y);
            if (world_to_pixel(world_to_ndc, {q[0], q[1], q[2]}, p.width(), p.height(), px)) {
                worst = std::max(worst, double(std::hypot(px.x - (x + 0.5f), px.y - (y + 0.5f))));
            }
        }
    }
    return worst;
}

TEST(CameraSolve, EqualsTheHeaderOnTheRasterizersFrames)
{
    for (int frame : {1, 20, 48}) {
        const Frame f = rendered(frame);
        CameraSolveOptions o;
        o.near_clip = f.camera.near_clip;
        o.stride = 1;
        const CameraSolve s = solve_camera(
            f.image("position"), f.image("depth"), f.display_window, f.data_window, "test", o);
        EXPECT_LT(s.residual_px, 0.01) << "frame " << frame;
        EXPECT_LT(relative_difference(s.world_to_camera, *f.camera.world_to_camera), 1e-4)
            << "frame " << frame;
        EXPECT_LT(relative_difference(s.world_to_ndc, *f.camera.world_to_ndc), 1e-4)
            << "frame " << frame;
        EXPECT_FALSE(s.right_handed_world);
        // focal / sensor width of the scene's camera.
        EXPECT_NEAR(
            s.focal_over_sensor_width, *f.camera.focal_length_mm / *f.camera.sensor_width_mm, 1e-4);
        EXPECT_GT(s.pixels_kept, s.pixels_valid * 9 / 10);
    }
}

TEST(CameraSolve, TheDefaultSampleBudgetHoldsAt1080p)
{
    // Every 5th pixel in x and y at this size (83k samples).
    const Frame f = rendered(20, 1920, 1080);
    CameraSolveOptions o;
    o.near_clip = f.camera.near_clip;
    const CameraSolve s = solve_camera(
        f.image("position"), f.image("depth"), f.display_window, f.data_window, "test", o);
    EXPECT_LT(s.pixels_valid, 100000u);
    EXPECT_LT(s.residual_px, 0.01);
    EXPECT_LT(relative_difference(s.world_to_camera, *f.camera.world_to_camera), 1e-4);
    EXPECT_LT(relative_difference(s.world_to_ndc, *f.camera.world_to_ndc), 1e-4);
}

TEST(CameraSolve, AMirroredWorldGivesAMirroredCameraThatProjectsTheSame)
{
    Frame f = rendered(20);
    Image p = f.image("position");
    for (std::size_t i = 0; i < p.pixel_count(); ++i) {
        p.data()[i * 3] = -p.data()[i * 3];
    }
    f.set("position", std::move(p));
    const CameraSolve s =
        solve_camera(f.image("position"), f.image("depth"), f.display_window, f.data_window, "t");
    EXPECT_TRUE(s.right_handed_world);
    EXPECT_LT(s.residual_px, 0.01);
    EXPECT_LT(max_reprojection_px(f, s.world_to_ndc), 0.02);
    // worldToCamera of the mirrored world is the header's with the world's x negated.
    const glm::mat4 mirror = glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.0f, 1.0f));
    EXPECT_LT(relative_difference(s.world_to_camera * mirror, *f.camera.world_to_camera), 1e-4);
}

TEST(CameraSolve, FilteredEdgesAndSkyAreLeftOut)
{
    // A box filter over 2x2 pixels averages positions and depths across every silhouette, as a
    // production renderer's pixel filter does; the mixed pixels must not bend the camera.
    const Frame sharp = rendered(30, 640, 360);
    const Image &p = sharp.image("position");
    const Image &d = sharp.image("depth");
    Image fp(320, 180, 3), fd(320, 180, 1);
    for (int y = 0; y < 180; ++y) {
        for (int x = 0; x < 320; ++x) {
            float acc[4] = {0, 0, 0, 0};
            int sky = 0;
            for (int j = 0; j < 2; ++j) {
                for (int i = 0; i < 2; ++i) {
                    const float z = d.pixel(2 * x + i, 2 * y + j)[0];
                    if (!std::isfinite(z)) {
                        ++sky;
                        continue;
                    }
                    for (int c = 0; c < 3; ++c) {
                        acc[c] += p.pixel(2 * x + i, 2 * y + j)[c] / 4.0f;
                    }
                    acc[3] += z / 4.0f;
                }
            }
            for (int c = 0; c < 3; ++c) {
                fp.at(x, y, c) = acc[c];
            }
            // Blender's convention: a part-sky pixel keeps a large finite depth mix.
            fd.at(x, y, 0) = sky == 4 ? std::numeric_limits<float>::infinity()
                                      : acc[3] + float(sky) * 1e3f / 4.0f;
        }
    }
    const Rect win{0, 0, 320, 180};
    CameraSolveOptions o;
    o.near_clip = sharp.camera.near_clip;
    const CameraSolve s = solve_camera(fp, fd, win, win, "t", o);
    EXPECT_LT(s.residual_px, 0.01);
    EXPECT_LT(s.pixels_kept, s.pixels_valid);  // the edges left
    // The 640x360 camera's NDC is the 320x180 frame's: the same matrix.
    EXPECT_LT(relative_difference(s.world_to_ndc, *sharp.camera.world_to_ndc), 1e-3);
}

TEST(CameraSolve, WindowsPlaceTheDataInsideTheDisplay)
{
    const Frame f = rendered(10);
    // The right half of the frame as a data window inside the full display window.
    Image p(160, 180, 3), d(160, 180, 1);
    for (int y = 0; y < 180; ++y) {
        for (int x = 0; x < 160; ++x) {
            for (int c = 0; c < 3; ++c) {
                p.at(x, y, c) = f.image("position").pixel(160 + x, y)[c];
            }
            d.at(x, y, 0) = f.image("depth").pixel(160 + x, y)[0];
        }
    }
    const CameraSolve s = solve_camera(p, d, {0, 0, 320, 180}, {160, 0, 320, 180}, "t");
    EXPECT_LT(relative_difference(s.world_to_camera, *f.camera.world_to_camera), 1e-4);
}

void expect_refused(const Image &p, const Image &d, const std::string &words)
{
    const Rect win{0, 0, p.width(), p.height()};
    try {
        solve_camera(p, d, win, win, "shot.0001.exr");
        FAIL() << "expected a refusal mentioning " << words;
    } catch (const Error &e) {
        const std::string m = e.what();
        EXPECT_EQ(m.find('\n'), std::string::npos) << m;
        EXPECT_NE(m.find("shot.0001.exr"), std::string::npos) << m;
        EXPECT_NE(m.find(words), std::string::npos) << m;
        EXPECT_NE(m.find("\"camera\" parameter"), std::string::npos) << m;
    }
}

TEST(CameraSolve, RefusesWhatNoPinholeCameraExplains)
{
    const Frame f = rendered(20);
    // Orthographic: depth as it is, the positions moved so that x and y are linear in pixels.
    Image ortho = f.image("position");
    for (int y = 0; y < ortho.height(); ++y) {
        for (int x = 0; x < ortho.width(); ++x) {
            ortho.at(x, y, 0) = 0.05f * x;
            ortho.at(x, y, 1) = -0.05f * y;
            ortho.at(x, y, 2) = f.image("depth").pixel(x, y)[0];
        }
    }
    expect_refused(ortho, f.image("depth"), "no pinhole camera fits");
    // A depth in other units than the positions (centimetres).
    Image cm = f.image("depth");
    for (std::size_t i = 0; i < cm.pixel_count(); ++i) {
        cm.data()[i] *= 100.0f;
    }
    expect_refused(f.image("position"), cm, "not 1");
    // Every surface on one plane: many cameras fit.
    Image plane = f.image("position");
    for (std::size_t i = 0; i < plane.pixel_count(); ++i) {
        plane.data()[i * 3 + 1] = 0.0f;
    }
    expect_refused(plane, f.image("depth"), "one plane");
    // Sky everywhere.
    Image sky(32, 32, 1);
    for (std::size_t i = 0; i < sky.pixel_count(); ++i) {
        sky.data()[i] = std::numeric_limits<float>::infinity();
    }
    expect_refused(Image(32, 32, 3), sky, "surface pixels");
}

TEST(CameraSolve, SameBitsEveryRun)
{
    const Frame f = rendered(5);
    const CameraSolve a =
        solve_camera(f.image("position"), f.image("depth"), f.display_window, f.data_window, "t");
    const CameraSolve b =
        solve_camera(f.image("position"), f.image("depth"), f.display_window, f.data_window, "t");
    EXPECT_EQ(0, std::memcmp(&a.world_to_ndc, &b.world_to_ndc, sizeof(glm::mat4)));
    EXPECT_EQ(a.residual_px, b.residual_px);
}

/// The rendered frame written without its camera matrices, as Blender writes its files.
std::string write_without_camera(const std::string &dir, Frame f, bool keep_lens)
{
    f.camera.world_to_camera.reset();
    f.camera.world_to_ndc.reset();
    f.camera.prev_world_to_camera.reset();
    f.camera.prev_world_to_ndc.reset();
    if (!keep_lens) {
        f.camera = Camera{};
    }
    const std::string path = dir + "/nocam.exr";
    write_exr(f, path, {});
    return path;
}

TEST(CameraSolve, ReadSolvesAFileWithoutMatricesAndInfoSaysSo)
{
    const std::string dir = test::scratch_dir("camera_solve_read");
    static const raster::Scene scene = raster::load_scene(test::scene_path("minecrappy.json"));
    const Frame f = raster::render_frame(
        scene, 20, test::render_options(320, 180, {"position", "depth", "normal"}));
    const std::string path = write_without_camera(dir, f, true);
    // A read feeding ao, which reads the camera and asks for depth and normal only.
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "ao", "type": "ao", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "ao"},
         "params": {"path": "out.exr", "passes": "depth"}}]})";
    std::string log;
    ASSERT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_NE(log.find("camera solved from position + depth"), std::string::npos) << log;
    const FileInfo out = read_file_info(dir + "/out.exr");
    ASSERT_TRUE(out.camera.world_to_ndc.has_value());
    EXPECT_LT(relative_difference(*out.camera.world_to_ndc, *f.camera.world_to_ndc), 1e-4);
    // The solve's position pass was read for the solve only: the output has no position.
    for (const PassSource &ps : out.passes) {
        EXPECT_NE(ps.pass, "position");
    }
    // Without a node that reads the camera, the read neither reads position for it nor solves:
    // the output is the depth pass alone, without matrices.
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "in"},
         "params": {"path": "plain.exr", "passes": "depth"}}]})";
    ASSERT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_EQ(log.find("camera solved"), std::string::npos) << log;
    const FileInfo plain = read_file_info(dir + "/plain.exr");
    EXPECT_FALSE(plain.camera.world_to_ndc.has_value());
    EXPECT_FALSE(plain.camera.world_to_camera.has_value());
    ASSERT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " info " + path, &log));
    EXPECT_NE(log.find("camera             solved from position + depth, residual"),
              std::string::npos)
        << log;
}

// A read -> write of a whole file asks for every pass, the camera among them, and solves it where
// it can; an all-sky frame (a sequence's first frames, say) has no surface to solve from, and
// the write goes on without matrices instead of stopping the run. A node that reads the camera
// still refuses the frame, naming why the solve failed.
TEST(CameraSolve, AWholeFileWriteGoesOnWhereTheSolveFails)
{
    const std::string dir = test::scratch_dir("camera_solve_sky");
    Frame f = test::make_sample_frame(32, 18, 1);
    Image depth = f.image("depth");
    depth.fill(std::numeric_limits<float>::infinity());
    f.set("depth", std::move(depth));
    write_without_camera(dir, f, true);
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": "o.exr"}}]})";
    std::string log;
    ASSERT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_FALSE(read_file_info(dir + "/o.exr").camera.world_to_ndc.has_value());
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "ao", "type": "ao", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "ao"}, "params": {"path": "o.exr"}}]})";
    EXPECT_NE(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_NE(log.find("surface pixels"), std::string::npos) << log;
}

TEST(CameraSolve, AoRunsOnAFileWithoutMatrices)
{
    const std::string dir = test::scratch_dir("camera_solve_ao");
    const raster::Scene scene = raster::load_scene(test::scene_path("minecrappy.json"));
    const Frame f = raster::render_frame(
        scene, 12, test::render_options(160, 90, {"position", "depth", "normal", "color"}));
    write_without_camera(dir, f, true);
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "ao", "type": "ao", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "ao"}, "params": {"path": "ao.exr"}}]})";
    std::string log;
    EXPECT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    // Without the solve, the message names the node, the file and the three ways.
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr", "solve_camera": "never"}},
        {"id": "ao", "type": "ao", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "ao"}, "params": {"path": "ao.exr"}}]})";
    EXPECT_EQ(1, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_NE(log.find("node \"ao\""), std::string::npos) << log;
    EXPECT_NE(log.find("nocam.exr has no camera matrices (read's solve_camera is never)"),
              std::string::npos)
        << log;
    EXPECT_NE(log.find("worldToCamera"), std::string::npos) << log;
    EXPECT_NE(log.find("read's \"camera\" parameter"), std::string::npos) << log;
    EXPECT_NE(log.find("position and depth passes"), std::string::npos) << log;
    // A file with neither matrices nor a position pass: the same line says so.
    Frame no_position = f;
    no_position.erase("position");
    write_without_camera(dir, no_position, true);
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr"}},
        {"id": "ao", "type": "ao", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "ao"}, "params": {"path": "ao.exr"}}]})";
    EXPECT_EQ(1, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_NE(log.find("nocam.exr has no camera matrices and no position and depth passes"),
              std::string::npos)
        << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
}

TEST(CameraSolve, TheGraphsCameraReplacesTheHeaders)
{
    const std::string dir = test::scratch_dir("camera_solve_graph");
    const Frame f = rendered(20, 64, 36);
    write_without_camera(dir, f, false);
    // camera_to_world with a lens: the matrices make_camera_matrices gives.
    const glm::mat4 c2w = glm::translate(glm::mat4(1.0f), glm::vec3(1.0f, 2.0f, -3.0f));
    std::string m = "[";
    for (int i = 0; i < 16; ++i) {
        m += (i ? ", " : "") + std::to_string((&c2w[0][0])[i]);
    }
    m += "]";
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr", "camera":
          {"camera_to_world": )" +
                                m +
                                R"(, "focal_length": 50, "sensor_width": 24}}},
        {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": "o.exr"}}]})";
    std::string log;
    ASSERT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    const FileInfo out = read_file_info(dir + "/o.exr");
    const CameraMatrices want = make_camera_matrices(c2w, 50.0f, 24.0f, 64.0f / 36.0f, 0.1f);
    ASSERT_TRUE(out.camera.world_to_ndc.has_value());
    EXPECT_LT(relative_difference(*out.camera.world_to_ndc, want.world_to_ndc), 1e-6);
    EXPECT_LT(relative_difference(*out.camera.world_to_camera, want.world_to_camera), 1e-6);
    // A singular matrix is a graph error naming the parameter.
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "nocam.exr", "camera":
          {"world_to_camera": [1,0,0,0, 0,1,0,0, 0,0,0,0, 0,0,0,1],
           "world_to_ndc": [1,0,0,0, 0,1,0,0, 0,0,1,0, 0,0,0,1]}}},
        {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": "o.exr"}}]})";
    EXPECT_EQ(2, test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph, &log)) << log;
    EXPECT_NE(
        log.find("/params/camera/world_to_camera: node \"in\" (read): the matrix is singular"),
        std::string::npos)
        << log;
}

// A header's matrices can hold NaNs or zeros. Every node that projects through the camera
// refuses them with one line naming the attribute (they once ran on them: ao gave 0 on every
// surface, ssr and fog changed nothing), as read's camera parameter refuses the same matrices.
TEST(CameraSolve, UnusableHeaderMatricesAreRefusedByTheNodesThatNeedThem)
{
    const Frame good = test::make_sample_frame(32, 18, 1);
    glm::mat4 nan_m = *good.camera.world_to_ndc;
    nan_m[1][2] = std::numeric_limits<float>::quiet_NaN();
    const glm::mat4 zero(0.0f);
    EXPECT_EQ(projection_matrix_problem(*good.camera.world_to_ndc), "");
    EXPECT_EQ(camera_matrix_problem(*good.camera.world_to_camera), "");
    EXPECT_EQ(projection_matrix_problem(nan_m), "has an entry that is not finite");
    EXPECT_EQ(projection_matrix_problem(zero).rfind("projects onto less than a plane", 0), 0u);
    EXPECT_EQ(camera_matrix_problem(zero).rfind("is singular", 0), 0u);
    // A camera in millimetres and 5000 km from the origin, whose float depth row collapses,
    // still projects: only the x, y and w rows' directions are judged.
    const glm::mat4 far_c2w = glm::translate(glm::mat4(1.0f), glm::vec3(5e6f, 0.0f, 0.0f));
    const CameraMatrices far = make_camera_matrices(far_c2w, 35.0f, 36.0f, 16.0f / 9.0f, 0.01f);
    EXPECT_EQ(projection_matrix_problem(far.world_to_ndc), "");
    const CameraMatrices mm = make_camera_matrices(
        glm::scale(glm::mat4(1.0f), glm::vec3(1000.0f)), 35.0f, 36.0f, 16.0f / 9.0f, 100.0f);
    EXPECT_EQ(projection_matrix_problem(mm.world_to_ndc), "");
    const std::pair<const char *, const char *> nodes[] = {
        {"ao", "{}"},
        {"ssr", "{}"},
        {"ssgi", "{}"},
        {"relight", R"({"lights": [{"type": "point", "position": [0, 2, 0]}]})"},
        {"fog", R"({"model": "height"})"},
        {"motion_blur", R"({"source": "camera"})"}};
    for (const auto &[type, params] : nodes) {
        for (const bool use_nan : {true, false}) {
            Frame f = good;
            const glm::mat4 &bad = use_nan ? nan_m : zero;
            // relight projects only through worldToCamera (without screen-space shadows).
            const std::string t = type, attribute = t == "relight"       ? "worldToCamera\" "
                                                    : t == "motion_blur" ? "prevWorldToNDC\" "
                                                                         : "worldToNDC\" ";
            if (t == "motion_blur") {
                f.camera.prev_world_to_camera = f.camera.world_to_camera;
                f.camera.prev_world_to_ndc = bad;
            } else if (t == "relight") {
                f.camera.world_to_camera = bad;
            } else {
                f.camera.world_to_ndc = bad;
            }
            try {
                test::run_node(type, f, params);
                ADD_FAILURE() << type << " ran on a broken camera";
            } catch (const Error &e) {
                const std::string m = e.what();
                EXPECT_NE(m.find(attribute), std::string::npos) << m;
                EXPECT_NE(m.find(use_nan          ? "not finite"
                                 : t == "relight" ? "is singular"
                                                  : "projects onto less than a plane"),
                          std::string::npos)
                    << m;
            }
        }
    }
}

}  // namespace
}  // namespace posthaste
