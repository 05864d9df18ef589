// The nodes on frames the project did not render: Blender 3.4 / Cycles renders of two shots
// (samples/cycles/, made by tests/cycles/make_cycles_set.py; docs/ACCURACY.md, "Against
// Cycles"). Their passes are filtered at edges (Blackman-Harris 1.5 px), noisy where Cycles
// sampled them, in a right-handed Z-up world, and without camera matrices: the read node solves
// the camera from position + depth. Each node's error against Cycles' own truth (motion blur,
// depth of field, the AO pass) is held beside doing nothing and beside Blender's compositor
// nodes on the same frames (Vector Blur, Defocus).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "core/camera_solve.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "metrics/metrics.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

const std::string kDir = std::string(POSTHASTE_SOURCE_DIR) + "/samples/cycles/";
constexpr int kFrame = 2;  // the set's shot frame

Frame read_color(const std::string &file)
{
    const std::set<std::string> color = {"color"};
    return read_frame(kDir + file, &color, kFrame);
}

/// The node `node` of graphs/cycles/GRAPH.json, evaluated through the engine (read solves the
/// camera), its write redirected to a scratch folder.
Frame run_graph(const std::string &graph,
                const std::string &node,
                std::vector<std::string> overrides = {})
{
    overrides.push_back("out.path=" + test::scratch_dir("cycles_" + graph) + "/out.exr");
    Graph g = Graph::load(std::string(POSTHASTE_SOURCE_DIR) + "/graphs/cycles/" + graph + ".json",
                          nodes::catalog(),
                          overrides);
    g.set_capture(node);
    return g.evaluate(kFrame);
}

double rmse_rgb(const Image &a, const Image &b)
{
    // RGB of RGBA: the alpha of a defocused or blurred frame is 1 on both sides in these shots.
    Image ra(a.width(), a.height(), 3), rb(b.width(), b.height(), 3);
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                ra.at(x, y, c) = a.pixel(x, y)[c];
                rb.at(x, y, c) = b.pixel(x, y)[c];
            }
        }
    }
    return metrics::compare(ra, rb).all.rms_error;
}

struct Row {
    std::string what;
    double nothing, node, blender;
};

void print(const Row &r)
{
    std::printf(
        "%-32s nothing %.4f  node %.4f (%.0f %% removed)  blender %.4f  node/blender %.2f\n",
        r.what.c_str(),
        r.nothing,
        r.node,
        100.0 * (1.0 - r.node / r.nothing),
        r.blender,
        r.node / r.blender);
}

TEST(CyclesAccuracySlow, CameraSolvesOnEveryShot)
{
    for (const char *shot : {"yard", "closeup"}) {
        const std::set<std::string> wanted = {"position", "depth"};
        const Frame f = read_frame(kDir + shot + ".passes.exr", &wanted, kFrame);
        EXPECT_FALSE(f.camera.world_to_ndc.has_value()) << "Blender writes no camera";
        const CameraSolve s = solve_camera(
            f.image("position"), f.image("depth"), f.display_window, f.data_window, shot);
        std::printf("%s: %s\n", shot, s.describe().c_str());
        EXPECT_LT(s.residual_px, 0.01) << shot;
        EXPECT_TRUE(s.right_handed_world) << shot;
    }
}

TEST(CyclesAccuracySlow, MotionBlurBeatsBlendersVectorBlur)
{
    for (const char *shot : {"yard", "closeup"}) {
        const Frame sharp = read_color(std::string(shot) + ".passes.exr");
        for (const char *shutter : {"050", "100"}) {
            const Frame truth = read_color(std::string(shot) + ".mb_s" + shutter + ".exr");
            const Frame blender =
                read_color(std::string(shot) + ".blender_vblur_s" + shutter + ".exr");
            const Frame out = run_graph(
                std::string(shot) + "_motion_blur",
                "motion_blur",
                {std::string("motion_blur.shutter=") + (shutter[0] == '0' ? "0.5" : "1.0")});
            const Row r{std::string(shot) + " motion_blur shutter " + shutter,
                        rmse_rgb(sharp.image("color"), truth.image("color")),
                        rmse_rgb(out.image("color"), truth.image("color")),
                        rmse_rgb(blender.image("color"), truth.image("color"))};
            print(r);
            // Measured on 2026-11-28: 85 / 77 % removed on the yard, 36 / 43 % on the close-up;
            // node / Blender's Vector Blur 0.49, 0.97, 0.78, 0.89.
            EXPECT_LT(r.node, r.nothing) << r.what;
            EXPECT_LT(r.node, r.blender) << r.what;
        }
    }
}

TEST(CyclesAccuracySlow, DofBeatsBlendersDefocus)
{
    struct Case {
        const char *shot, *fstop, *focus;
    };
    for (const Case &c : {Case{"yard", "1.4", "4"},
                          Case{"yard", "2.8", "4"},
                          Case{"closeup", "1.4", "2.6"},
                          Case{"closeup", "4", "2.6"}}) {
        const std::string shot = c.shot;
        const Frame sharp = read_color(shot + ".passes.exr");
        const Frame truth = read_color(shot + ".dof_f" + c.fstop + ".exr");
        const Frame blender = read_color(shot + ".blender_defocus_f" + c.fstop + ".exr");
        const Frame out = run_graph(shot + "_dof", "dof", {std::string("dof.fstop=") + c.fstop});
        const Row r{shot + " dof f/" + c.fstop,
                    rmse_rgb(sharp.image("color"), truth.image("color")),
                    rmse_rgb(out.image("color"), truth.image("color")),
                    rmse_rgb(blender.image("color"), truth.image("color"))};
        print(r);
        // Measured on 2026-11-28: the close-up removes 43 % (f/1.4) and 6 % (f/4) of the
        // do-nothing error; on the wide yard shot (35 mm, circles of confusion of 1-2 px) the
        // node changes next to nothing (0.0847 against 0.0848 at f/1.4) where Cycles' truth
        // differs from the sharp frame by 0.085: it must at least not make it worse. Blender's
        // Defocus, as set here (f-stop, Z buffer, the scene camera), blurs the whole frame
        // (0.05-0.91): its row is printed, not held.
        if (shot == "closeup") {
            EXPECT_LT(r.node, r.nothing) << r.what;
        } else {
            EXPECT_LE(r.node, r.nothing * 1.001) << r.what;
        }
    }
}

/// RMSE over the surface pixels (finite depth: Cycles writes AO 0 on the sky).
double rmse_surface(const Image &ao, const Image &truth, const Image &depth)
{
    std::vector<float> a, b;
    for (int y = 0; y < ao.height(); ++y) {
        for (int x = 0; x < ao.width(); ++x) {
            if (std::isfinite(depth.pixel(x, y)[0])) {
                a.push_back(ao.pixel(x, y)[0]);
                b.push_back(truth.pixel(x, y)[0]);
            }
        }
    }
    Image ia(int(a.size()), 1, 1), ib(int(b.size()), 1, 1);
    std::copy(a.begin(), a.end(), ia.data());
    std::copy(b.begin(), b.end(), ib.data());
    return metrics::compare(ia, ib).all.rms_error;
}

TEST(CyclesAccuracySlow, AoAgainstCyclesAoPass)
{
    for (const char *shot : {"yard", "closeup"}) {
        const std::set<std::string> wanted = {"depth"};
        const Frame passes = read_frame(kDir + shot + ".passes.exr", &wanted, kFrame);
        const Image &depth = passes.image("depth");
        Image one(depth.width(), depth.height(), 1);
        one.fill(1.0f);
        for (const char *dist : {"1", "2"}) {
            const Frame truth = read_frame(kDir + shot + ".ao_d" + dist + ".exr", nullptr, kFrame);
            const Image &t = truth.image("ViewLayer.AO");
            const std::string radius = std::string("ao.radius=") + dist;
            const Frame gtao = run_graph(std::string(shot) + "_ao", "ao", {radius});
            const Frame trace =
                run_graph(std::string(shot) + "_ao", "ao", {radius, "ao.method=trace"});
            const double nothing = rmse_surface(one, t, depth);
            const double node = rmse_surface(gtao.image("ao"), t, depth);
            const double bound = rmse_surface(trace.image("ao"), t, depth);
            std::printf(
                "%-8s ao radius %s m: nothing %.4f  node %.4f (%.0f %% removed)  traced "
                "reference %.4f (%.0f %%)\n",
                shot,
                dist,
                nothing,
                node,
                100.0 * (1.0 - node / nothing),
                bound,
                100.0 * (1.0 - bound / nothing));
            // Measured on 2026-11-28: the yard 53 % (1 m) and 64 % (2 m) removed, the traced
            // reference through the same passes 46 and 60 %; the close-up 3 and 8 %, its
            // reference 4 and 3 % (docs/ACCURACY.md, "Against Cycles").
            EXPECT_LT(node, nothing) << shot << " radius " << dist;
        }
    }
}

}  // namespace
}  // namespace posthaste
