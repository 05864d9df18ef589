// The dof node and its helpers (src/shading/dof_*): the thin-lens CoC on hand-computed values,
// tile dilation, the in-focus pass-through (same bits), thread-count independence, the near
// field spreading over a sharp background but the far field not over a sharp foreground, and
// finite, bounded output for NaN / Inf / extreme parameters.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "shading/dof/dof_coc.h"
#include "shading/dof/dof_gather.h"
#include "test_util.h"

namespace posthaste {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

shading::DofLens lens_50mm_f2()
{
    return {2.0f, 5.0f, 50.0f, 36.0f};
}

TEST(Dof, CocFormulaHandValues)
{
    const shading::DofLens l = lens_50mm_f2();
    // A = 25 mm, f = 50 mm, s = 5000 mm, 1000 px over 36 mm.
    // z = 10 m: 25 * 50 * 5000 / (10000 * 4950) mm = 0.126263 mm = 3.50730 px.
    EXPECT_NEAR(shading::coc_diameter_px(l, 10.0f, 1000), 3.50730f, 1e-4f);
    // z = 2.5 m: -25 * 50 * 2500 / (2500 * 4950) mm = -0.252525 mm = -7.01459 px.
    EXPECT_NEAR(shading::coc_diameter_px(l, 2.5f, 1000), -7.01459f, 1e-4f);
    EXPECT_NEAR(shading::coc_diameter_px(l, kInf, 1000), 7.01459f, 1e-4f);
    EXPECT_EQ(shading::coc_diameter_px(l, 5.0f, 1000), 0.0f);
    // Scales with the image width and the square of the focal length over N.
    EXPECT_NEAR(shading::coc_diameter_px(l, 10.0f, 2000), 2.0f * 3.50730f, 2e-4f);
}

TEST(Dof, CocFieldMatchesFormulaAndClamps)
{
    const shading::DofLens l = lens_50mm_f2();
    Image depth(4, 1, 1);
    depth.at(0, 0, 0) = 10.0f;
    depth.at(1, 0, 0) = kInf;
    depth.at(2, 0, 0) = kNaN;
    depth.at(3, 0, 0) = -1.0f;
    // 4 px wide: the z = 10 m radius is 3.5073 / 250 / 2 = 0.0070146 px, the far limit 0.014029.
    shading::CocField c = shading::compute_coc(depth, l, 0.01f);
    EXPECT_NEAR(c.radius[0], 0.5f * 3.50730f / 250.0f, 1e-6f);
    EXPECT_EQ(c.radius[1], 0.01f);  // far limit, clamped
    EXPECT_EQ(c.radius[2], 0.0f);   // NaN depth: left sharp
    EXPECT_EQ(c.radius[3], 0.0f);   // negative depth: not a depth, left sharp
}

TEST(Dof, TileDilationReachesNeighbours)
{
    shading::CocField c;
    c.width = 64;
    c.height = 16;
    c.tiles_x = 4;
    c.tiles_y = 1;
    c.radius.assign(64 * 16, 0.0f);
    c.radius[20] = -20.0f;  // tile 1 holds a 20 px near radius
    shading::reduce_tiles(c);
    EXPECT_EQ(c.tile_max[1], 20.0f);
    EXPECT_EQ(c.gather[0], 20.0f);
    EXPECT_EQ(c.gather[2], 20.0f);
    EXPECT_EQ(c.gather[3], 20.0f);  // one tile between: 20 >= 16
    c.radius[20] = -10.0f;
    shading::reduce_tiles(c);
    EXPECT_EQ(c.gather[2], 10.0f);
    EXPECT_EQ(c.gather[3], 0.0f);  // 10 px cannot cross a whole 16 px tile
}

// Left half: near wall (2 m), right half: far wall (20 m); every row the same. Colors differ.
void two_walls(int w, int h, Image &color, Image &depth)
{
    color = Image(w, h, 4);
    depth = Image(w, h, 1);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const bool near = x < w / 2;
            color.at(x, y, 0) = near ? 1.0f : 0.0f;
            color.at(x, y, 1) = near ? 0.0f : ((x / 3) % 2 ? 1.0f : 0.2f);  // far texture
            color.at(x, y, 2) = 0.0f;
            color.at(x, y, 3) = 1.0f;
            depth.at(x, y, 0) = near ? 2.0f : 20.0f;
        }
    }
}

TEST(Dof, NearFieldSpreadsOverSharpBackground)
{
    Image color, depth, out;
    two_walls(256, 48, color, depth);
    shading::DofLens l = lens_50mm_f2();
    l.fstop = 1.0f;
    l.focus_m = 20.0f;  // background sharp, near wall blurred
    const float r = 0.5f * std::fabs(shading::coc_diameter_px(l, 2.0f, 256));
    ASSERT_GT(r, 3.5f);
    for (bool half : {true, false}) {
        shading::DofSettings s;
        s.half_res = half;
        ASSERT_TRUE(shading::apply_dof(color, depth, l, s, out));
        // 1.5 px right of the edge the red near wall covers ~27 % of the lens (disc segment).
        float red = 0.0f;
        for (int y = 0; y < 48; ++y) {
            red += out.at(128 + 1, y, 0) / 48.0f;
        }
        EXPECT_GT(red, 0.15f) << half;
        EXPECT_LT(red, 0.45f) << half;
        // Far from the edge the sharp background is unchanged.
        EXPECT_FLOAT_EQ(out.at(240, 10, 1), color.at(240, 10, 1)) << half;
    }
}

TEST(Dof, FarFieldDoesNotBleedOverSharpForeground)
{
    Image color, depth, out;
    two_walls(256, 48, color, depth);
    shading::DofLens l = lens_50mm_f2();
    l.fstop = 1.0f;
    l.focus_m = 2.0f;  // near wall sharp, background blurred
    for (bool half : {true, false}) {
        shading::DofSettings s;
        s.half_res = half;
        ASSERT_TRUE(shading::apply_dof(color, depth, l, s, out));
        for (int y = 0; y < 48; ++y) {
            for (int x = 0; x < 128; ++x) {
                ASSERT_FLOAT_EQ(out.at(x, y, 0), 1.0f) << x << "," << y << " half " << half;
                ASSERT_FLOAT_EQ(out.at(x, y, 1), 0.0f) << x << "," << y << " half " << half;
            }
        }
        // The far side is blurred: its stripes (0.2 / 1.0) lose contrast.
        EXPECT_LT(std::fabs(out.at(200, 5, 1) - out.at(203, 5, 1)), 0.6f) << half;
    }
}

TEST(Dof, ThreadCountIndependent)
{
    Image color, depth, a, b;
    two_walls(200, 90, color, depth);
    shading::DofLens l = lens_50mm_f2();
    l.focus_m = 6.0f;
    for (int blades : {0, 6, -1}) {
        shading::DofSettings s;
        s.blades = std::max(blades, 0);
        s.half_res = blades >= 0;
        s.rotation_deg = 15.0f;
        set_thread_count(1);
        ASSERT_TRUE(shading::apply_dof(color, depth, l, s, a));
        set_thread_count(2);
        ASSERT_TRUE(shading::apply_dof(color, depth, l, s, b));
        set_thread_count(0);
        EXPECT_TRUE(a.bit_equal(b)) << "blades " << blades;
    }
}

// The AVX2 gather and its scalar twin sum the same taps in the same order per pixel; they differ
// only in rounding (fused multiply-adds), on a real frame: the default scene's close-up (frame
// 48, near field, far field and sky), at full and half resolution, disc and hexagon.
TEST(Dof, VectorAndScalarPathsAgree)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    const raster::Scene scene =
        raster::load_scene(std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/minecrappy.json");
    raster::RenderOptions o;
    o.width = 480;
    o.height = 270;
    o.passes = {"color", "depth"};
    const Frame f = raster::render_frame(scene, 48, o);
    const Camera &c = f.camera;
    const shading::DofLens lens{
        *c.fstop, *c.focus_distance, *c.focal_length_mm, *c.sensor_width_mm};
    for (int variant = 0; variant < 3; ++variant) {
        shading::DofSettings s;
        s.half_res = variant == 1;
        s.blades = variant == 2 ? 6 : 0;
        Image vec, sca;
        ASSERT_TRUE(shading::apply_dof(f.image("color"), f.image("depth"), lens, s, vec));
        {
            simd::ScopedLevel scalar(simd::Level::Scalar);
            ASSERT_TRUE(shading::apply_dof(f.image("color"), f.image("depth"), lens, s, sca));
        }
        double worst = 0.0;
        for (std::size_t i = 0; i < vec.value_count(); ++i) {
            const double a = vec.data()[i], b = sca.data()[i];
            worst = std::max(worst, std::fabs(a - b) / std::max(1.0, std::fabs(b)));
        }
        // The best Highway target against the portable one-lane target of the same source: float
        // rounding of sums of up to 2 x 64 taps (fused or not).
        EXPECT_LT(worst, 1e-5) << "variant " << variant;
        std::printf("[ measured ] dof variant %d: vector vs scalar target %.2g\n", variant, worst);
    }
}

/// An opaque black RGBA image with one pixel of red `value` at (x, y).
Image one_bright_pixel(int w, int h, int x, int y, float value)
{
    Image color(w, h, 4);
    color.fill(0.0f);
    for (int j = 0; j < h; ++j) {
        for (int i = 0; i < w; ++i) {
            color.at(i, j, 3) = 1.0f;
        }
    }
    color.at(x, y, 0) = value;
    return color;
}

TEST(Dof, FlatFieldStaysFlatAndConservesEnergy)
{
    // A uniform image at one depth is unchanged by any blur; a single bright pixel keeps its
    // energy (sum over the image) to within sampling noise.
    const int w = 96, h = 96;
    const Image color = one_bright_pixel(w, h, 48, 48, 1000.0f);
    Image depth(w, h, 1), out;
    depth.fill(1000.0f);
    shading::DofLens l{1.0f, 1.0f, 50.0f, 36.0f};  // 7 px CoC at 96 px
    shading::DofSettings s;
    s.half_res = false;
    ASSERT_TRUE(shading::apply_dof(color, depth, l, s, out));
    double sum = 0.0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            sum += out.at(x, y, 0);
            ASSERT_FLOAT_EQ(out.at(x, y, 3), 1.0f);
        }
    }
    EXPECT_NEAR(sum, 1000.0, 150.0);
    EXPECT_LT(out.at(48, 48, 0), 100.0f);  // spread, not left as a spike
}

TEST(Dof, SubPixelCocSpreadsByTheDiscsVariance)
{
    // A CoC radius r under half a pixel reaches no neighbour's centre, but the lens spreads the
    // pixel by a disc of variance r^2 / 4 per axis: one bright pixel becomes the 4-neighbour
    // stencil a = r^2 / 8 around it, energy kept, nothing beyond.
    const int w = 16, h = 16;
    const Image color = one_bright_pixel(w, h, 8, 8, 100.0f);
    Image depth(w, h, 1), out;
    depth.fill(2.0f);
    // 50 mm at f/1 focused at 1 m: 50 * 50 * 1000 / (2000 * 950) mm = 1.3158 mm over 36 mm at
    // 16 px, a radius of 0.29240 px.
    const shading::DofLens l{1.0f, 1.0f, 50.0f, 36.0f};
    const float r = 0.5f * shading::coc_diameter_px(l, 2.0f, w);
    ASSERT_NEAR(r, 0.29240f, 1e-4f);
    shading::DofSettings s;
    ASSERT_TRUE(shading::apply_dof(color, depth, l, s, out));
    const float a = r * r / 8.0f;
    EXPECT_NEAR(out.at(8, 8, 0), 100.0f * (1.0f - 4.0f * a), 1e-4f);
    for (auto [x, y] : {std::pair{7, 8}, std::pair{9, 8}, std::pair{8, 7}, std::pair{8, 9}}) {
        EXPECT_NEAR(out.at(x, y, 0), 100.0f * a, 1e-5f) << x << "," << y;
    }
    double sum = 0.0, second = 0.0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const double v = out.at(x, y, 0);
            sum += v;
            second += v * double((x - 8) * (x - 8));
            EXPECT_EQ(out.at(x, y, 3), 1.0f);
            if (std::abs(x - 8) + std::abs(y - 8) > 1) {
                EXPECT_EQ(v, 0.0) << x << "," << y;
            }
        }
    }
    EXPECT_NEAR(sum, 100.0, 1e-3);
    EXPECT_NEAR(second / sum, double(r) * r / 4.0, 1e-5);  // the disc's variance along x
    // The simple method (the seeds' baseline) leaves it alone.
    s.method = shading::DofMethod::Simple;
    EXPECT_FALSE(shading::apply_dof(color, depth, l, s, out));
    // Under 1/16 px the pixel is left as it is: the input back, bit for bit.
    s.method = shading::DofMethod::Gather;
    const shading::DofLens nearly{1.0f, 1.0f, 50.0f, 36.0f * 6.0f};  // r = 0.0487 px
    EXPECT_FALSE(shading::apply_dof(color, depth, nearly, s, out));
}

/// The added variance along x of one bright pixel at (8, 8) of a 16x16 image blurred with a
/// constant CoC of signed radius r (behind the focus plane for r > 0, in front for r < 0).
double impulse_variance(float r, Image *result = nullptr)
{
    const int w = 16, h = 16;
    const Image color = one_bright_pixel(w, h, 8, 8, 100.0f);
    Image depth(w, h, 1), out;
    // 50 mm focused at 1 m: at depth 2 m the radius is 0.29240 px at f/1 (16 px over 36 mm),
    // at 0.8 m -0.18275 px.
    const float z = r > 0.0f ? 2.0f : 0.8f;
    depth.fill(z);
    const float r1 = 0.5f * shading::coc_diameter_px({1.0f, 1.0f, 50.0f, 36.0f}, z, w);
    const shading::DofLens l{std::fabs(r1 / r), 1.0f, 50.0f, 36.0f};
    EXPECT_TRUE(shading::apply_dof(color, depth, l, shading::DofSettings{}, out));
    double sum = 0.0, second = 0.0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            sum += out.at(x, y, 0);
            second += out.at(x, y, 0) * double((x - 8) * (x - 8));
        }
    }
    if (r > 0.0f && r < 0.75f) {
        EXPECT_NEAR(sum, 100.0, 1e-3) << r;  // the stencil keeps the energy
    }
    if (result) {
        *result = out;
    }
    return second / sum;
}

TEST(Dof, TheStencilTakesBackgroundsUnderThreeQuartersOfAPixel)
{
    // The gather weighs a neighbour by the disc's overlap with a pixel-wide edge: at r = 0.52 it
    // spread an impulse by 0.15 of the disc's variance, at 0.7 by 0.68. Behind the focus plane
    // the stencil now takes every radius under 0.75: exactly the disc's variance, the 4
    // neighbours only.
    for (float r : {0.3f, 0.52f, 0.6f, 0.74f}) {
        Image out;
        EXPECT_NEAR(impulse_variance(r, &out), double(r) * r / 4.0, 1e-5) << r;
        EXPECT_NEAR(out.at(8, 8, 0), 100.0f * (1.0f - r * r / 2.0f), 1e-3f) << r;
        EXPECT_NEAR(out.at(9, 8, 0), 100.0f * r * r / 8.0f, 1e-4f) << r;
        EXPECT_EQ(out.at(9, 9, 0), 0.0f) << r;
        EXPECT_EQ(out.at(10, 8, 0), 0.0f) << r;
    }
    // From 0.75 on the gather (its taps' pattern then spreads the pixel).
    Image out;
    impulse_variance(0.8f, &out);
    EXPECT_NE(out.at(8, 8, 0), 100.0f * (1.0f - 0.32f));
    // In front of the focus plane a pixel from r = 0.5 on is in the near field, whose layer the
    // gather makes: not the stencil.
    EXPECT_GT(std::fabs(impulse_variance(-0.6f) - 0.09), 0.01);
}

std::string render_dof_graph(const std::string &dof_params)
{
    return std::string(R"({"nodes": [
        {"id": "src", "type": "render", "params": {"scene": ")") +
           POSTHASTE_TEST_DIR +
           R"(/../samples/scenes/cube.json", "width": 64, "height": 36}},
        {"id": "d", "type": "dof", "inputs": {"image": "src"}, "params": )" +
           dof_params + R"(},
        {"id": "o", "type": "write", "inputs": {"image": "d"}, "params": {"path": ")" +
           test::scratch_dir("dof_node") + R"(/o.exr"}}]})";
}

TEST(Dof, NodeLargeFstopGivesInputBack)
{
    Graph src = Graph::parse(render_dof_graph("{}"), "g.json", nodes::catalog());
    src.set_capture("src");
    const Frame in = src.evaluate(1);
    Graph g = Graph::parse(
        render_dof_graph(R"({"fstop": 1e6, "focus_distance": 3})"), "g.json", nodes::catalog());
    g.set_capture("d");
    const Frame out = g.evaluate(1);
    EXPECT_TRUE(out.image("color").bit_equal(in.image("color")));
    // A wide aperture on the same frame does change it.
    Graph open = Graph::parse(
        render_dof_graph(R"({"fstop": 1, "focus_distance": 3, "focal_length_mm": 200})"),
        "g.json",
        nodes::catalog());
    open.set_capture("d");
    EXPECT_FALSE(open.evaluate(1).image("color").bit_equal(in.image("color")));
}

TEST(Dof, NodeReportsMissingLensAttributeAndUsesOverride)
{
    // A frame whose header lacks focalLength: the node names the attribute; giving the
    // parameter instead makes it run.
    const std::string dir = test::scratch_dir("dof_missing");
    Frame f = test::make_sample_frame(32, 16, 1);
    f.camera.focal_length_mm.reset();
    write_exr(f, dir + "/in.1.exr", WriteOptions{});
    const auto graph = [&](const std::string &params) {
        return R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": ")" +
               dir + R"(/in.#.exr"}},
            {"id": "d", "type": "dof", "inputs": {"image": "src"}, "params": )" +
               params + R"(},
            {"id": "o", "type": "write", "inputs": {"image": "d"}, "params": {"path": ")" +
               dir + R"(/o.exr"}}]})";
    };
    Graph g = Graph::parse(graph("{}"), "g.json", nodes::catalog());
    g.set_capture("d");
    try {
        g.evaluate(1);
        FAIL() << "expected an error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("focalLength"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("dof"), std::string::npos) << e.what();
    }
    Graph ok = Graph::parse(graph(R"({"focal_length_mm": 35})"), "g.json", nodes::catalog());
    ok.set_capture("d");
    const Frame out = ok.evaluate(1);
    EXPECT_EQ(out.image("color").width(), 32);
}

TEST(Dof, LensValuesComeFromTheHeaderUnlessGiven)
{
    // The declaration says where an ungiven lens value comes from, and posthaste nodes prints it.
    const NodeType *dof = nodes::catalog().find("dof");
    ASSERT_NE(dof, nullptr);
    int from_header = 0;
    for (const ParamSpec &p : dof->spec.params) {
        if (!p.header.empty()) {
            ++from_header;
            if (p.name == "fstop") {
                // Blender writes no aperture: the default stands in, with a note.
                EXPECT_FALSE(p.header_only);
                EXPECT_EQ(describe_default(p), "the header's aperture, else 5.6");
                continue;
            }
            EXPECT_TRUE(p.header_only) << p.name;
            EXPECT_EQ(describe_default(p),
                      "the header's " + std::string(p.header) + " (required there)");
        }
    }
    EXPECT_EQ(from_header, 4);  // aperture, focus, focalLength, sensorWidth
    // 0 once meant "the header's"; given now, it is refused before any pixel work, naming what
    // leaving it out does.
    const std::string dir = test::scratch_dir("dof_zero");
    write_exr(test::make_sample_frame(32, 16, 1), dir + "/in.1.exr", WriteOptions{});
    const std::string graph = R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                              dir + R"(/in.#.exr"}},
        {"id": "d", "type": "dof", "inputs": {"image": "src"}, "params": {"fstop": 0}},
        {"id": "o", "type": "write", "inputs": {"image": "d"}, "params": {"path": ")" +
                              dir + R"(/o.exr"}}]})";
    const Graph g = Graph::parse(graph, "g.json", nodes::catalog());
    try {
        g.check({1});
        FAIL() << "expected an error";
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Usage);
        EXPECT_NE(
            std::string(e.what()).find(
                "g.json:/nodes/1/params/fstop: node \"d\" (dof): param \"fstop\": must be > 0 "
                "(leave it out for the header's aperture)"),
            std::string::npos)
            << e.what();
    }
}

TEST(Dof, ExtremeInputsStayFiniteAndBounded)
{
    Image color, depth, out;
    two_walls(96, 64, color, depth);
    color.at(10, 10, 0) = kNaN;
    color.at(70, 20, 1) = kInf;
    color.at(71, 20, 1) = -kInf;
    depth.at(30, 30, 0) = kNaN;
    depth.at(80, 40, 0) = kInf;
    depth.at(81, 40, 0) = -kInf;
    depth.at(82, 40, 0) = 0.0f;
    struct Case {
        float fstop, focus, max_coc;
        int samples;
    };
    for (const Case &c : {Case{0.5f, 5.0f, 64.0f, 64},
                          Case{1e6f, 5.0f, 64.0f, 64},
                          Case{2.0f, 0.05f, 64.0f, 64},
                          Case{2.0f, 5.0f, 0.0f, 64},
                          Case{2.0f, 5.0f, 4096.0f, 16},
                          Case{2.0f, 5.0f, 64.0f, 1}}) {
        shading::DofLens l{c.fstop, c.focus, 50.0f, 36.0f};
        shading::DofSettings s;
        s.max_coc_px = c.max_coc;
        s.samples = c.samples;
        if (!shading::apply_dof(color, depth, l, s, out)) {
            continue;  // pass-through of the input
        }
        for (std::size_t i = 0; i < out.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(out.data()[i])) << "fstop " << c.fstop << " i " << i;
            ASSERT_LE(std::fabs(out.data()[i]), 1.0f);  // the finite input lies in [0, 1]
        }
    }
}

}  // namespace
}  // namespace posthaste
