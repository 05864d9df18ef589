// Overscan: render's data window beyond the display window (the display pixels as without it,
// the camera the display window's, truths over the data window), the parameter's two forms and
// its refusals, write's crop to the display window, a read frame's crop reaching the file, the
// ao node using the margin (closer to the truth at the frame's edge), and bench measuring the
// display window of an overscan render against a truth without one.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <limits>

#include "core/error.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "raster/ray_cast.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;

const raster::Scene &scene()
{
    static const raster::Scene s = raster::load_scene(test::scene_path("minecrappy.json"));
    return s;
}

/// `img` (over the data window `from`) cut to `to`.
Image cut(const Image &img, const Rect &from, const Rect &to)
{
    return place_in_window(img, from, to);
}

TEST(Overscan, DisplayPixelsAreTheFramesWithout)
{
    raster::RenderOptions o = test::render_options(160, 90, {"color", "depth", "normal", "motion"});
    const Frame plain = raster::render_frame(scene(), 8, o);
    o.overscan_x = 12;
    o.overscan_y = 7;
    const Frame wide = raster::render_frame(scene(), 8, o);
    EXPECT_EQ(wide.display_window, (Rect{0, 0, 160, 90}));
    EXPECT_EQ(wide.data_window, (Rect{-12, -7, 172, 97}));
    EXPECT_EQ(wide.image("color").width(), 184);
    EXPECT_EQ(wide.image("depth").height(), 104);
    // The header's camera is the display window's: the same matrices as without overscan.
    EXPECT_EQ(*wide.camera.world_to_ndc, *plain.camera.world_to_ndc);
    EXPECT_EQ(*wide.camera.world_to_camera, *plain.camera.world_to_camera);
    EXPECT_EQ(wide.camera.sensor_width_mm, plain.camera.sensor_width_mm);
    // The display pixels: what the frame without overscan shows (the wider view's rays round
    // differently: depth within 1e-4 relative, a few edge pixels may flip between surfaces).
    const Rect d = wide.display_window;
    const Image z = cut(wide.image("depth"), wide.data_window, d);
    const Image &z0 = plain.image("depth");
    int flips = 0;
    for (int y = 0; y < 90; ++y) {
        for (int x = 0; x < 160; ++x) {
            const float a = z.at(x, y, 0), b = z0.at(x, y, 0);
            if (std::isinf(a) || std::isinf(b)) {
                flips += a != b;
                continue;
            }
            flips += std::abs(a - b) > 1e-4f * b;
        }
    }
    EXPECT_LE(flips, 30);  // of 14400
    const Image c = cut(wide.image("color"), wide.data_window, d);
    EXPECT_LT(test::rms_rgb(c, plain.image("color")), 0.01);
    const Image m = cut(wide.image("motion"), wide.data_window, d);
    double motion_err = 0.0;
    for (int y = 0; y < 90; ++y) {
        for (int x = 0; x < 160; ++x) {
            for (int k = 0; k < 2; ++k) {
                motion_err += std::abs(m.at(x, y, k) - plain.image("motion").at(x, y, k));
            }
        }
    }
    EXPECT_LT(motion_err / (160 * 90 * 2), 0.01);  // pixels
    // The camera as the pixels see it projects a surface point onto the pixel that shows it,
    // in the margin too.
    const Camera pc = wide.pixel_camera();
    raster::RenderOptions po = o;
    po.passes = {"position", "depth"};
    const Frame pos = raster::render_frame(scene(), 8, po);
    const Image &p = pos.image("position"), &pz = pos.image("depth");
    int checked = 0;
    for (int y = 0; y < 104; y += 13) {
        for (int x = 0; x < 184; x += 9) {
            if (!std::isfinite(pz.at(x, y, 0))) {
                continue;
            }
            const glm::vec4 ndc =
                *pc.world_to_ndc * glm::vec4(p.at(x, y, 0), p.at(x, y, 1), p.at(x, y, 2), 1.0f);
            EXPECT_NEAR(ndc.x / ndc.w * 184.0f, x + 0.5f, 0.01f);
            EXPECT_NEAR(ndc.y / ndc.w * 104.0f, y + 0.5f, 0.01f);
            ++checked;
        }
    }
    EXPECT_GT(checked, 60);
}

TEST(Overscan, TruthsCoverTheDataWindow)
{
    raster::RenderOptions o = test::render_options(64, 36, {"color"});
    o.overscan_x = o.overscan_y = 4;
    raster::TruthOptions t;
    t.samples = 2;
    const Frame f = raster::render_truth(scene(), 8, o, t);
    EXPECT_EQ(f.data_window, (Rect{-4, -4, 68, 40}));
    EXPECT_EQ(f.image("color").width(), 72);
    const Image ao = raster::render_ao_truth(scene(), 8, o, 1.0f, 4, 0);
    EXPECT_EQ(ao.width(), 72);
    EXPECT_EQ(ao.height(), 44);
}

/// Run a graph's JSON text at frame 8 (files under `dir`).
Frame run_graph(const std::string &json, const std::string &capture = "")
{
    Graph g = Graph::parse(json, "overscan test", nodes::catalog());
    g.check({8});
    if (!capture.empty()) {
        g.set_capture(capture);
    }
    return g.evaluate(8);
}

std::string render_node(const std::string &extra)
{
    return R"({"id": "r", "type": "render", "params": {"scene": ")" +
           test::scene_path("minecrappy.json") + R"(", "width": 200, "height": 100)" + extra + "}}";
}

TEST(Overscan, TheParameterTakesAFractionOrWholePixels)
{
    const std::string dir = test::scratch_dir("overscan_param");
    auto window = [&](const std::string &extra) {
        const Frame f = run_graph(R"({"nodes": [)" + render_node(extra) +
                                      R"(, {"id": "w", "type": "write", "inputs": {"image": "r"},
                                  "params": {"path": ")" +
                                      dir + R"(/o.####.exr", "passes": "depth"}}]})",
                                  "r");
        return f.data_window;
    };
    // 0.1: each dimension 10 % larger, split over both sides (Unreal's overscan percentage).
    EXPECT_EQ(window(R"(, "overscan": 0.1)"), (Rect{-10, -5, 210, 105}));
    EXPECT_EQ(window(R"(, "overscan": 3)"), (Rect{-3, -3, 203, 103}));
    EXPECT_EQ(window(""), (Rect{0, 0, 200, 100}));
    try {
        window(R"(, "overscan": 2.5)");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("overscan"), std::string::npos) << e.what();
    }
    try {
        run_graph(R"({"nodes": [{"id": "r", "type": "render", "params": {"scene": ")" +
                  test::scene_path("minecrappy.json") +
                  R"(", "width": 64, "height": 32, "projection": "latlong", "overscan": 4}},
                  {"id": "w", "type": "write", "inputs": {"image": "r"},
                   "params": {"path": ")" +
                  dir + R"(/p.####.exr"}}]})");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("overscan"), std::string::npos) << e.what();
    }
}

TEST(Overscan, WriteKeepsOrCropsTheMarginAndACropReachesTheFile)
{
    const std::string dir = test::scratch_dir("overscan_write");
    run_graph(R"({"nodes": [)" + render_node(R"(, "overscan": 8)") +
              R"(, {"id": "keep", "type": "write", "inputs": {"image": "r"},
                   "params": {"path": ")" +
              dir + R"(/keep.####.exr", "passes": "color,depth"}},
                 {"id": "cut", "type": "write", "inputs": {"image": "r"},
                   "params": {"path": ")" +
              dir + R"(/cut.####.exr", "passes": "color,depth", "crop": "display"}}]})");
    const Frame keep = read_frame(dir + "/keep.0008.exr", nullptr, 8);
    const Frame crop = read_frame(dir + "/cut.0008.exr", nullptr, 8);
    EXPECT_EQ(keep.data_window, (Rect{-8, -8, 208, 108}));
    EXPECT_EQ(keep.display_window, (Rect{0, 0, 200, 100}));
    EXPECT_EQ(crop.data_window, (Rect{0, 0, 200, 100}));
    EXPECT_EQ(crop.display_window, (Rect{0, 0, 200, 100}));
    const Image inner = cut(keep.image("depth"), keep.data_window, crop.data_window);
    EXPECT_TRUE(inner.bit_equal(crop.image("depth")));
    // A read frame through crop: the file's part is cut too (it kept its old window once).
    run_graph(R"({"nodes": [{"id": "rd", "type": "read", "params": {"path": ")" + dir +
              R"(/keep.####.exr"}},
                 {"id": "c", "type": "crop", "inputs": {"image": "rd"}},
                 {"id": "w", "type": "write", "inputs": {"image": "c"},
                   "params": {"path": ")" +
              dir + R"(/recut.####.exr"}}]})");
    const Frame recut = read_frame(dir + "/recut.0008.exr", nullptr, 8);
    EXPECT_EQ(recut.data_window, (Rect{0, 0, 200, 100}));
    EXPECT_TRUE(recut.image("depth").bit_equal(crop.image("depth")));
    EXPECT_TRUE(recut.image("color").bit_equal(crop.image("color")));
}

// crop's reformat on a read frame moves the file's parts with the pixels: a box reaching past
// the data window keeps all of it, shifted (the write once cut it at the file's old window), and
// a box inside it keeps the box's pixels at the origin. Likewise transform and reformat.
TEST(Overscan, GeometryNodesMoveTheFilesPartsWithThePixels)
{
    const std::string dir = test::scratch_dir("overscan_reformat");
    run_graph(R"({"nodes": [)" + render_node(R"(, "overscan": 8)") +
              R"(, {"id": "w", "type": "write", "inputs": {"image": "r"},
                   "params": {"path": ")" +
              dir + R"(/in.####.exr", "passes": "color,depth"}}]})");
    const Frame in = read_frame(dir + "/in.0008.exr", nullptr, 8);
    ASSERT_EQ(in.data_window, (Rect{-8, -8, 208, 108}));
    for (const auto &[box, name] :
         {std::pair{"[-50, -30, 250, 120]", "past"}, std::pair{"[20, 10, 100, 70]", "inside"}}) {
        run_graph(R"({"nodes": [{"id": "rd", "type": "read", "params": {"path": ")" + dir +
                  R"(/in.####.exr"}},
                 {"id": "c", "type": "crop", "inputs": {"image": "rd"},
                   "params": {"box": )" +
                  std::string(box) + R"(, "reformat": true}},
                 {"id": "w", "type": "write", "inputs": {"image": "c"},
                   "params": {"path": ")" +
                  dir + "/" + name + R"(.####.exr"}}]})");
        const Frame out = read_frame(dir + "/" + name + ".0008.exr", nullptr, 8);
        const bool past = std::string(name) == "past";
        // The box's corner goes to (0, 0): the data window moves by (50, 30) or (-20, -10).
        const Rect want = past ? Rect{42, 22, 258, 138} : Rect{0, 0, 80, 60};
        EXPECT_EQ(out.data_window, want) << name;
        const Rect from = want.offset(past ? -50 : 20, past ? -30 : 10);
        for (const char *pass : {"color", "depth"}) {
            EXPECT_TRUE(out.image(pass).bit_equal(cut(in.image(pass), in.data_window, from)))
                << name << " " << pass;
        }
    }
    // transform and reformat put the pixels on a new grid: the file's parts follow it (the
    // write once cut a whole-pixel move and a doubling back to the file's old window).
    for (const auto &[node, params] :
         {std::pair{"transform", R"({"translate_x": 3, "translate_y": 2, "filter": "nearest"})"},
          std::pair{"reformat", R"({"scale": 2})"}}) {
        run_graph(R"({"nodes": [{"id": "rd", "type": "read", "params": {"path": ")" + dir +
                  R"(/in.####.exr"}},
                 {"id": "g", "type": ")" +
                  std::string(node) + R"(", "inputs": {"image": "rd"}, "params": )" + params +
                  R"(},
                 {"id": "w", "type": "write", "inputs": {"image": "g"},
                   "params": {"path": ")" +
                  dir + "/" + node + R"(.####.exr"}}]})");
        const Frame out = read_frame(dir + "/" + node + ".0008.exr", nullptr, 8);
        if (std::string(node) == "transform") {
            EXPECT_EQ(out.data_window, in.data_window.offset(3, 2));
            for (const char *pass : {"color", "depth"}) {
                EXPECT_TRUE(out.image(pass).bit_equal(in.image(pass))) << pass;
            }
        } else {
            EXPECT_EQ(out.display_window, (Rect{0, 0, 400, 200}));
            EXPECT_EQ(out.data_window, (Rect{-16, -16, 416, 216}));
        }
    }
}

TEST(Overscan, AoUsesTheMarginAndComesCloserToTheTruth)
{
    // The floor below the frame occludes what stands near the bottom edge: with a margin the
    // ao node sees it. Error against the exact AO over the display window.
    raster::RenderOptions o = test::render_options(320, 180, {"depth", "normal"});
    const Frame plain = raster::render_frame(scene(), 8, o);
    o.overscan_x = 32;
    o.overscan_y = 18;
    const Frame wide = raster::render_frame(scene(), 8, o);
    raster::RenderOptions to = test::render_options(320, 180, {});
    const Image truth = raster::render_ao_truth(scene(), 8, to, 1.0f, 64, 0);
    const char *params = R"({"resolution": "full", "slices": 4, "steps": 8})";
    const Frame a = test::run_node("ao", plain, params);
    const Frame b = test::run_node("ao", wide, params);
    const Image bd = cut(b.image("ao"), wide.data_window, wide.display_window);
    auto rmse = [&](const Image &x) {
        double s = 0.0;
        for (int y = 0; y < 180; ++y) {
            for (int xx = 0; xx < 320; ++xx) {
                const double d = double(x.at(xx, y, 0)) - truth.at(xx, y, 0);
                s += d * d;
            }
        }
        return std::sqrt(s / (320.0 * 180.0));
    };
    EXPECT_LT(rmse(bd), rmse(a.image("ao"))) << rmse(bd) << " vs " << rmse(a.image("ao"));
}

}  // namespace
}  // namespace posthaste
