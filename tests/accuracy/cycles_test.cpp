// The nodes on frames the project did not render: Blender 3.4 / Cycles renders of two shots
// (samples/cycles/, made by tests/cycles/make_cycles_set.py; docs/ACCURACY.md, "Against
// Cycles"). Their passes are filtered at edges (Blackman-Harris 1.5 px), noisy where Cycles
// sampled them, in a right-handed Z-up world, and without camera matrices: the read node solves
// the camera from position + depth. Each node's error against Cycles' own truth (motion blur,
// depth of field, the AO pass) is held beside doing nothing and beside Blender's compositor
// nodes on the same frames (Vector Blur; Defocus with its f-stop calibrated on the truth), and
// measured again with the data passes rendered without the pixel filter, which shows what the
// filtered passes cost.

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

/// The shot's passes as a read node gives them (the camera solved), through the engine; with
/// `unfiltered`, depth, normal, position and motion replaced by the passes rendered without the
/// pixel filter (the camera stays the filtered passes' solve).
Frame shot_frame(const std::string &shot, bool unfiltered = false)
{
    const std::string graph = R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")" +
                              kDir + shot + R"(.passes.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": "unused.exr"}}]})";
    Graph g = Graph::parse(graph, "cycles " + shot, nodes::catalog());
    g.set_capture("in");
    Frame f = g.evaluate(kFrame);
    if (unfiltered) {
        const Frame u = read_frame(kDir + shot + ".passes_unfiltered.exr", nullptr, kFrame);
        for (const char *name : {"depth", "normal", "position", "motion", "motion_next"}) {
            f.set_pass(name, u.pass(name));
        }
    }
    return f;
}

double rmse_rgb(const Image &a, const Image &b)
{
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
    double nothing, node, unfiltered, blender;
    double removed() const { return 1.0 - node / nothing; }
};

void print(const Row &r)
{
    std::printf(
        "%-30s nothing %.4f  node %.4f (%2.0f %%)  unfiltered passes %.4f (%2.0f %%)  blender "
        "%.4f  node/blender %.2f\n",
        r.what.c_str(),
        r.nothing,
        r.node,
        100.0 * r.removed(),
        r.unfiltered,
        100.0 * (1.0 - r.unfiltered / r.nothing),
        r.blender,
        r.node / r.blender);
}

/// A node on the shot with filtered and unfiltered passes, against `truth`, beside `blender`.
Row measure(const std::string &what,
            const std::string &shot,
            const std::string &type,
            const std::string &params,
            const std::string &truth,
            const std::string &blender)
{
    const Frame f = shot_frame(shot), u = shot_frame(shot, true);
    const Frame truth_frame = read_color(truth);
    const Image &t = truth_frame.image("color");
    return {what,
            rmse_rgb(f.image("color"), t),
            rmse_rgb(test::run_node(type, f, params, kFrame).image("color"), t),
            rmse_rgb(test::run_node(type, u, params, kFrame).image("color"), t),
            rmse_rgb(read_color(blender).image("color"), t)};
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
        for (const char *shutter : {"050", "100"}) {
            const std::string s = shot;
            const Row r =
                measure(s + " motion_blur shutter " + shutter,
                        s,
                        "motion_blur",
                        std::string(R"({"shutter": )") + (shutter[0] == '0' ? "0.5" : "1.0") + "}",
                        s + ".mb_s" + shutter + ".exr",
                        s + ".blender_vblur_s" + shutter + ".exr");
            print(r);
            // Measured on 2026-11-29 (32 samples at two per pixel of the path; the close-up at
            // 4x the samples): 91 / 85 % of the do-nothing error removed on the yard, 61 / 61 %
            // on the close-up; 0.31, 0.60, 0.45, 0.64 of Blender's Vector Blur's RMSE (the last
            // is the chrome ball's reflections of moving objects, which no pass Blender writes
            // moves). The data passes without the pixel filter give the same errors to four
            // digits.
            EXPECT_GT(r.removed(), 0.60) << r.what;
            EXPECT_LT(r.node, r.blender * (s == "closeup" && shutter[0] == '1' ? 0.7 : 0.61))
                << r.what;
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
        const Row r = measure(
            shot + " dof f/" + c.fstop,
            shot,
            "dof",
            std::string(R"({"fstop": )") + c.fstop + R"(, "focus_distance": )" + c.focus + "}",
            shot + ".dof_f" + c.fstop + ".exr",
            shot + ".blender_defocus_f" + c.fstop + ".exr");
        print(r);
        // Measured on 2026-11-29 (RMSE; the close-up at 4x the samples): the close-up removes
        // 64 % (f/1.4) and 25 % (f/4) of the do-nothing error, at 0.81 and 0.78 of Blender's
        // calibrated Defocus. On the wide yard
        // shot the error is the sun's glint on the chrome ball (value 142, a circle of confusion
        // of 0.49 px at f/1.4) whose peak Cycles' lens lowers by 12 %: the sub-pixel blur (the
        // disc's variance, r^2 / 4) takes the yard from 0.1087 (the node left such discs alone)
        // to 0.0402 at f/1.4, 63 % removed (Blender's calibrated Defocus: 0.0338), and to 0.0258
        // at f/2.8, 41 % removed and 0.59 of Defocus's error. docs/ACCURACY.md has the rest.
        EXPECT_LT(r.node, r.nothing) << r.what;
        if (shot == "closeup" || std::string(c.fstop) == "2.8") {
            EXPECT_LT(r.node, r.blender) << r.what;
        }
        if (shot == "yard") {
            EXPECT_GT(r.removed(), std::string(c.fstop) == "1.4" ? 0.60 : 0.35) << r.what;
        }
    }
}

TEST(CyclesAccuracySlow, AoAgainstCyclesAoPass)
{
    for (const char *shot : {"yard", "closeup"}) {
        const Frame f = shot_frame(shot), u = shot_frame(shot, true);
        const Image &depth = f.image("depth");
        Image one(depth.width(), depth.height(), 1);
        one.fill(1.0f);
        for (const char *dist : {"1", "2"}) {
            const Frame truth = read_frame(kDir + shot + ".ao_d" + dist + ".exr", nullptr, kFrame);
            const Image &t = truth.image("ViewLayer.AO");
            const std::string radius = std::string(R"("radius": )") + dist;
            auto ao = [&](const Frame &in, const std::string &more) {
                const Frame out = test::run_node("ao", in, "{" + radius + more + "}", kFrame);
                return metrics::compare_surface(out.image("ao"), t, depth, 1).all.rms_error;
            };
            const double nothing = metrics::compare_surface(one, t, depth, 1).all.rms_error;
            const double node = ao(f, ""), unfiltered = ao(u, "");
            const double bound = ao(f, R"(, "method": "trace")");
            std::printf(
                "%-8s ao radius %s m: nothing %.4f  node %.4f (%.0f %%)  unfiltered "
                "passes %.4f (%.0f %%)  traced reference %.4f (%.0f %%)\n",
                shot,
                dist,
                nothing,
                node,
                100.0 * (1.0 - node / nothing),
                unfiltered,
                100.0 * (1.0 - unfiltered / nothing),
                bound,
                100.0 * (1.0 - bound / nothing));
            // Measured on 2026-11-28: the yard 53 % (1 m) and 64 % (2 m) removed, the traced
            // reference through the same passes 46 and 60 %; the close-up 3 and 8 %, its
            // reference 4 and 3 % (docs/ACCURACY.md, "Against Cycles"). Unfiltered passes: the
            // same to four digits (Cycles' depth pass is not filtered at all).
            EXPECT_LT(node, nothing) << shot << " radius " << dist;
        }
    }
}

}  // namespace
}  // namespace posthaste
