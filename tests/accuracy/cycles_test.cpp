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

#include <algorithm>
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
        // 64 % (f/1.4) and 27 % (f/4) of the do-nothing error, at 0.81 and 0.76 of Blender's
        // calibrated Defocus. On the wide yard shot the error is the sun's glint on the chrome
        // ball (value 142, a circle of confusion of 0.49 px at f/1.4, 0.25 at f/2.8): the
        // stencil under 3/4 px takes f/1.4 to 0.0391 (64 % removed, 1.15 of Defocus's error;
        // the gather's seam between 0.5 and 0.75 px had cost 0.0402), f/2.8 stays at 0.0258
        // (41 %, 0.59). The glint's render noise is of the size of these differences
        // (ErrorsNetOfTheRendersOwnNoise, GlintAtThirtyTwoTimesTheSamples).
        EXPECT_LT(r.node, r.nothing) << r.what;
        if (shot == "closeup") {
            EXPECT_LT(r.node, r.blender) << r.what;
        } else if (std::string(c.fstop) == "1.4") {
            EXPECT_GT(r.removed(), 0.60) << r.what;
        } else {
            EXPECT_GT(r.removed(), 0.35) << r.what;
            EXPECT_LT(r.node, 0.61 * r.blender) << r.what;
        }
    }
}

/// RMSE over RGB outside a box (pixels x0..x1-1, y0..y1-1 of the frame).
double rmse_rgb_outside(const Image &a, const Image &b, const Rect &box)
{
    double sum = 0.0;
    std::size_t n = 0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            if (x >= box.x0 && x < box.x1 && y >= box.y0 && y < box.y1) {
                continue;
            }
            for (int c = 0; c < 3; ++c) {
                const double d = double(a.pixel(x, y)[c]) - double(b.pixel(x, y)[c]);
                sum += d * d;
                ++n;
            }
        }
    }
    return std::sqrt(sum / double(n));
}

TEST(CyclesAccuracySlow, FogAgainstCyclesMedium)
{
    // The yard through an absorbing, emitting medium that camera rays alone meet (Cycles'
    // truths, tests/cycles/make_cycles_set.py --fog): the models' own composite, so the error
    // is what the passes hold (filtered edges, the solved camera, the sky) and the renders'
    // noise. Beside it Blender's Mist pass mixed toward the fog colour, calibrated on the truth,
    // and the node fogging each pixel by its own depth alone (pixel_filter 0).
    struct Case {
        const char *kind, *model;
    };
    const Rect glint{170, 58, 186, 74};  // the chrome ball's sun glint (GlintAtThirtyTwo...)
    for (const Case &c : {Case{"exp", R"("model": "exp", "density": 0.08)"},
                          Case{"height",
                               R"("model": "height", "density": 0.3, "falloff": 1.0,
                                  "base_height": 0, "up": [0, 0, 1], "sky": "ray")"}}) {
        const std::string kind = c.kind;
        const std::string params =
            std::string("{") + c.model + R"(, "color": [0.75, 0.78, 0.82], "pixel_filter": )";
        const Row r = measure("yard fog " + kind,
                              "yard",
                              "fog",
                              params + "0.6}",
                              "yard.fog_" + kind + ".exr",
                              "yard.blender_mist_" + kind + ".exr");
        print(r);
        const Frame f = shot_frame("yard");
        const Frame truth = read_color("yard.fog_" + kind + ".exr");
        const Image &t = truth.image("color");
        auto outside = [&](const std::string &p) {
            return rmse_rgb_outside(test::run_node("fog", f, p, kFrame).image("color"), t, glint);
        };
        const double node = outside(params + "0.6}"), own_depth = outside(params + "0}");
        const double nothing = rmse_rgb_outside(f.image("color"), t, glint);
        const double blender = rmse_rgb_outside(
            read_color("yard.blender_mist_" + kind + ".exr").image("color"), t, glint);
        std::printf(
            "%-30s outside the glint: nothing %.4f  node %.4f  own depth alone %.4f  blender "
            "%.4f\n",
            r.what.c_str(),
            nothing,
            node,
            own_depth,
            blender);
        // Measured on 2026-11-30: exp 0.0124 (98 % of the do-nothing error removed), 0.52 of
        // the calibrated Mist's error; height 0.0128 (97 %), 0.19 (the Mist has no height).
        // Most of it is the sun's glint on the chrome ball, noise of the renders; outside it
        // exp 0.0030 (own depth alone 0.0043, Mist 0.0089), height 0.0067 (0.0083, 0.0571),
        // the rest noise and what is left at the edges.
        EXPECT_GT(r.removed(), 0.95) << r.what;
        EXPECT_LT(r.node, 0.6 * r.blender) << r.what;
        EXPECT_LT(node, 0.6 * blender) << r.what;
        EXPECT_LT(node, 0.85 * own_depth) << r.what;
    }
}

/// Errors net of the renders' own noise, from second renders with another seed
/// (samples/cycles/noise/): the sharp frame and every motion-blur and depth-of-field truth. For
/// truths t1, t2 of noise variance v each (v = mean (t1 - t2)^2 / 2) and a result a1 made from
/// the sharp frame of t1's seed, the mean square of a1 - t2 (independent noises) is the error
/// against the noise-free truth plus v; the node and doing nothing are also made from the
/// second sharp frame (a2, against t1) and the two averaged. A result carries its sharp frame's
/// noise too, of variance mean (a1 - a2)^2 / 2: "net of both" takes it out as well. Blender's
/// results are net of the truth's noise only (its nodes cannot be run on the second frame
/// here), which leaves them the larger.
struct NetRow {
    std::string what;
    double truth_noise;              ///< RMS, one truth render
    double nothing, node, blender;   ///< against the noise-free truth
    double nothing_both, node_both;  ///< and net of the sharp frame's noise
};

double mean_square(const Image &a, const Image &b)
{
    double sum = 0.0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                const double d = double(a.pixel(x, y)[c]) - double(b.pixel(x, y)[c]);
                sum += d * d;
            }
        }
    }
    return sum / (3.0 * double(a.width()) * double(a.height()));
}

NetRow measure_net(const std::string &what,
                   const std::string &shot,
                   const std::string &type,
                   const std::string &params,
                   const std::string &truth,
                   const std::string &blender)
{
    const Frame f = shot_frame(shot);
    // The second sharp frame in the passes' place.
    Frame f2 = f;
    const Frame sharp2 = read_color("noise/" + shot + ".sharp_seed8.exr");
    f2.set_pass("color", sharp2.pass("color"));
    const Frame t1f = read_color(truth + ".exr"), t2f = read_color("noise/" + truth + "_seed8.exr");
    const Image &t1 = t1f.image("color"), &t2 = t2f.image("color");
    const double v = mean_square(t1, t2) / 2.0;
    // A result is compared with the truth of the other seed only: the set's sharp frame and
    // its truths share a seed, and their noise is correlated (a result that passes the sharp
    // frame's noise on would look closer to the same seed's truth than it is).
    const auto net = [&](const Image &a1, const Image *a2) {
        const double m =
            a2 ? 0.5 * (mean_square(a1, t2) + mean_square(*a2, t1)) : mean_square(a1, t2);
        return std::sqrt(std::max(m - v, 0.0));
    };
    const Image node = test::run_node(type, f, params, kFrame).image("color");
    const Image node2 = test::run_node(type, f2, params, kFrame).image("color");
    const Image &sharp = f.image("color");
    const double node_noise = mean_square(node, node2) / 2.0,
                 sharp_noise = mean_square(sharp, sharp2.image("color")) / 2.0;
    NetRow r{what,
             std::sqrt(v),
             net(sharp, &sharp2.image("color")),
             net(node, &node2),
             net(read_color(blender).image("color"), nullptr),
             0.0,
             0.0};
    r.nothing_both = std::sqrt(std::max(r.nothing * r.nothing - sharp_noise, 0.0));
    // 0 where the node's error is no larger than the noise it carries from the sharp frame.
    r.node_both = std::sqrt(std::max(r.node * r.node - node_noise, 0.0));
    std::printf(
        "%-28s truth noise %.4f | net of the truth's noise: nothing %.4f node %.4f (%2.0f %%) "
        "blender %.4f node/blender %.2f | net of both: nothing %.4f node %.4f (%2.0f %%)\n",
        what.c_str(),
        r.truth_noise,
        r.nothing,
        r.node,
        100.0 * (1.0 - r.node / r.nothing),
        r.blender,
        r.node / r.blender,
        r.nothing_both,
        r.node_both,
        100.0 * (1.0 - r.node_both / r.nothing_both));
    return r;
}

TEST(CyclesAccuracySlow, ErrorsNetOfTheRendersOwnNoise)
{
    // Measured on 2026-11-29. The yard's dof truths (2048 samples) are noisy where the sun's
    // glint is (0.023 RMS at f/1.4), and so is the sharp frame: net of both, the node is level
    // with Defocus at f/1.4 (0.99; 1.15 against the set's truth alone, whose noise shares the
    // sharp frame's seed) and at 0.82 at f/2.8 (0.59). The close-up (8192 samples): 0.78 and
    // 0.74 of Defocus's error, motion_blur at shutter 1 0.63 of Vector Blur's (the chrome
    // ball's reflections, not noise).
    struct Case {
        const char *shot, *type, *params, *truth, *blender;
        double max_ratio;  ///< node / blender, net of the truth's noise (measured + 0.03)
    };
    const Case cases[] = {
        {"yard",
         "dof",
         R"({"fstop": 1.4, "focus_distance": 4})",
         "yard.dof_f1.4",
         "yard.blender_defocus_f1.4.exr",
         1.03},
        {"yard",
         "dof",
         R"({"fstop": 2.8, "focus_distance": 4})",
         "yard.dof_f2.8",
         "yard.blender_defocus_f2.8.exr",
         0.86},
        {"closeup",
         "dof",
         R"({"fstop": 1.4, "focus_distance": 2.6})",
         "closeup.dof_f1.4",
         "closeup.blender_defocus_f1.4.exr",
         0.81},
        {"closeup",
         "dof",
         R"({"fstop": 4, "focus_distance": 2.6})",
         "closeup.dof_f4",
         "closeup.blender_defocus_f4.exr",
         0.77},
        {"yard",
         "motion_blur",
         R"({"shutter": 0.5})",
         "yard.mb_s050",
         "yard.blender_vblur_s050.exr",
         0.34},
        {"yard",
         "motion_blur",
         R"({"shutter": 1.0})",
         "yard.mb_s100",
         "yard.blender_vblur_s100.exr",
         0.61},
        {"closeup",
         "motion_blur",
         R"({"shutter": 0.5})",
         "closeup.mb_s050",
         "closeup.blender_vblur_s050.exr",
         0.45},
        {"closeup",
         "motion_blur",
         R"({"shutter": 1.0})",
         "closeup.mb_s100",
         "closeup.blender_vblur_s100.exr",
         0.66},
    };
    for (const Case &c : cases) {
        const NetRow r =
            measure_net(std::string(c.truth), c.shot, c.type, c.params, c.truth, c.blender);
        EXPECT_LT(r.node, r.nothing) << r.what;
        EXPECT_LT(r.node_both, r.nothing_both) << r.what;
        EXPECT_LT(r.node / r.blender, c.max_ratio) << r.what;
        EXPECT_GT(r.truth_noise, 0.0) << r.what;  // two renders, not one file twice
    }
}

TEST(CyclesAccuracySlow, GlintAtThirtyTwoTimesTheSamples)
{
    // The yard's sun glint, whose render noise is of the size of the differences between
    // methods at the set's counts, rendered again in a 16x16 border at 32x the samples (the
    // sharp frame 32768, the truths 32768; samples/cycles/glint/, make_cycles_set.py --glint):
    // the node on the shot with the glint's pixels from the finer render, against the finer
    // truths, over the inner 12x12 pixels (the border's own edge is one pixel from the blur).
    constexpr int kX0 = 170, kY0 = 58, kSize = 16;
    Frame f = shot_frame("yard");
    const Frame sharp = read_color("glint/yard.glint_sharp.exr");
    const Image &hi = sharp.image("color");
    ASSERT_EQ(hi.width(), kSize);
    Image color = f.image("color");
    for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            for (int c = 0; c < 3; ++c) {
                color.at(kX0 + x, kY0 + y, c) = hi.pixel(x, y)[c];
            }
        }
    }
    f.set("color", std::move(color));
    const auto rmse_inner = [&](const Image &a, int ax0, int ay0, const Image &t) {
        double sum = 0.0;
        for (int y = 2; y < kSize - 2; ++y) {
            for (int x = 2; x < kSize - 2; ++x) {
                for (int c = 0; c < 3; ++c) {
                    const double d =
                        double(a.pixel(ax0 + x, ay0 + y)[c]) - double(t.pixel(x, y)[c]);
                    sum += d * d;
                }
            }
        }
        return std::sqrt(sum / (3.0 * (kSize - 4) * (kSize - 4)));
    };
    for (const char *fstop : {"1.4", "2.8"}) {
        const Frame truth = read_color(std::string("glint/yard.glint_dof_f") + fstop + ".exr");
        const Image &t = truth.image("color");
        const Image out =
            test::run_node("dof",
                           f,
                           std::string(R"({"fstop": )") + fstop + R"(, "focus_distance": 4})",
                           kFrame)
                .image("color");
        const double nothing = rmse_inner(hi, 0, 0, t), node = rmse_inner(out, kX0, kY0, t);
        std::printf("glint f/%s: nothing %.4f node %.4f (%.0f %% removed)\n",
                    fstop,
                    nothing,
                    node,
                    100.0 * (1.0 - node / nothing));
        // Measured: f/1.4 2.163 -> 0.775 (64 %), f/2.8 0.543 -> 0.193 (64 %). The best
        // stencil weight on these pixels is 1.4 times the disc's r^2 / 8 at both f-stops
        // (the glint is smaller than the pixel filter, docs/ACCURACY.md).
        EXPECT_LT(node, 0.40 * nothing) << fstop;
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
            const double extent = ao(f, R"(, "method": "trace", "occluders": "extent")");
            const double bitmask = ao(f, R"(, "method": "bitmask", "occluders": "extent")");
            const double all = ao(f, R"(, "crossings": "all")");
            std::printf(
                "%-8s ao radius %s m: nothing %.4f  node %.4f (%.0f %%)  unfiltered "
                "passes %.4f (%.0f %%)  traced reference %.4f (%.0f %%), occluders as deep as "
                "wide %.4f (%.0f %%)  bitmask so %.4f (%.0f %%)  every crossing %.4f "
                "(%.1f %%)\n",
                shot,
                dist,
                nothing,
                node,
                100.0 * (1.0 - node / nothing),
                unfiltered,
                100.0 * (1.0 - unfiltered / nothing),
                bound,
                100.0 * (1.0 - bound / nothing),
                extent,
                100.0 * (1.0 - extent / nothing),
                bitmask,
                100.0 * (1.0 - bitmask / nothing),
                all,
                100.0 * (1.0 - all / nothing));
            // Measured on 2026-11-28: the yard 53 % (1 m) and 64 % (2 m) removed, the traced
            // reference through the same passes 46 and 60 %; the close-up 3 and 8 %, its
            // reference 4 and 3 % (docs/ACCURACY.md, "Against Cycles"). Unfiltered passes: the
            // same to four digits (Cycles' depth pass is not filtered at all). On 2026-11-30,
            // with occluders as deep as they are wide on screen, the yard's traced reference
            // removes 68 and 72 %: every surface 1 m deep had made the poles in front of the
            // steps occlude them; the bitmask so 59 and 57 % (its 4 steps miss thin occluders
            // at 2 m). GTAO with reachable crossings (the jump from the wall to the box standing
            // 1.3 m in front of it is not a surface): 60.1 and 64.0 %. Later that day with
            // each surface reaching back as far as its widest run (ground whose column runs
            // steps cut reaches back by its rows), read on the half-resolution grid, as the
            // default: 63.1 and 71.5 %, every crossing (the old default) 53 and 64 %; the
            // close-up 4.8 and 5.3 % (every crossing 3 and 8 %). On 2026-12-01, with each
            // sample's elevation above the tangent plane kept where the pixel grid rounds it off
            // the slice: the yard 63.5 and 71.5 %, 4.8 and 0.2 points below the traced bound
            // with occluders as deep as wide (68.4 and 71.7 %); the close-up 4.1 and 4.8 %.
            EXPECT_LT(node, nothing) << shot << " radius " << dist;
            if (std::string(shot) == "yard") {
                EXPECT_LT(extent, 0.8 * bound) << "radius " << dist;
                // The issue's goal: 60 % of the do-nothing error removed at both distances.
                EXPECT_LT(node, 0.4 * nothing) << "radius " << dist;
                EXPECT_LT(node, 0.9 * all) << "radius " << dist;
                // The issue's goal for the default: within 5 points of that bound.
                EXPECT_LT(node - extent, 0.05 * nothing) << "radius " << dist;
            }
        }
    }
}

}  // namespace
}  // namespace posthaste
