// Depth of field against the rasterizer's thin-lens ground truth (render_truth, dof only): RMSE
// and PSNR (RGB) of the dof node's gather, of doing nothing (the pinhole image) and of the simple
// baseline (a disc of each pixel's own CoC), on the default scene's close-up frames and on the
// analytic scenes with a wide-open lens. Each truth is also rendered with twice the samples to
// show it has converged well below the errors measured. Then the failure cases: each asserts
// finite, bounded output and records its error. Numbers go to docs/nodes/dof.md.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <string>

#include "io/image_file.h"
#include "metrics/metrics.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/dof/dof_gather.h"

namespace posthaste {
namespace {

using raster::CameraKey;
using raster::Scene;

std::string scene_path(const std::string &name)
{
    return std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/" + name;
}

Image rgb(const Image &c)
{
    Image o(c.width(), c.height(), 3);
    for (int y = 0; y < c.height(); ++y) {
        for (int x = 0; x < c.width(); ++x) {
            for (int k = 0; k < 3; ++k) {
                o.at(x, y, k) = c.at(x, y, k);
            }
        }
    }
    return o;
}

double rmse(const Image &a, const Image &b)
{
    return metrics::compare(rgb(a), rgb(b)).all.rms_error;
}

double psnr(const Image &a, const Image &b)
{
    return metrics::compare(rgb(a), rgb(b)).all.psnr;
}

shading::DofLens lens_of(const Camera &c)
{
    return {*c.fstop, *c.focus_distance, *c.focal_length_mm, *c.sensor_width_mm};
}

struct Rendered {
    Frame frame;   // pinhole color + depth
    Image truth;   // N lens samples
    Image truth2;  // 2N lens samples (0x0 when not asked)
};

Rendered render_case(const Scene &s, int frame, int w, int h, int samples, bool convergence)
{
    raster::RenderOptions o;
    o.width = w;
    o.height = h;
    o.passes = {"color", "depth"};
    Rendered r;
    r.frame = raster::render_frame(s, frame, o);
    raster::TruthOptions t;
    t.motion = false;
    t.dof = true;
    t.samples = samples;
    r.truth = raster::render_truth(s, frame, o, t).image("color");
    if (convergence) {
        t.samples = 2 * samples;
        r.truth2 = raster::render_truth(s, frame, o, t).image("color");
    }
    return r;
}

Scene scene_with_lens(const std::string &file, const std::function<void(CameraKey &)> &edit)
{
    Scene s = raster::load_scene(scene_path(file));
    for (CameraKey &k : s.camera_keys) {
        edit(k);
    }
    return s;
}

// Finite everywhere and within the range of the (sanitised) input: the gather is a convex
// combination of input pixels.
void expect_finite_bounded(const Image &out, const Image &in, const std::string &what)
{
    float lo = std::numeric_limits<float>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < in.value_count(); ++i) {
        const float v = in.data()[i];
        if (std::isfinite(v)) {
            lo = std::min(lo, v);
            hi = std::max(hi, v);
        }
    }
    lo = std::min(lo, 0.0f);
    for (std::size_t i = 0; i < out.value_count(); ++i) {
        const float v = out.data()[i];
        ASSERT_TRUE(std::isfinite(v)) << what << " value " << i;
        ASSERT_GE(v, lo - 1e-4f) << what;
        ASSERT_LE(v, hi * 1.0001f + 1e-4f) << what;
    }
}

struct Errors {
    double none, simple, node, node_psnr, simple_psnr, none_psnr, truth_conv;
    float max_coc_px;
};

// POSTHASTE_DOF_DUMP=dir: write PNG previews (clamped, gamma 2.2) of each case's images there.
void dump(const std::string &name, const std::string &what, const Image &img)
{
    const char *dir = std::getenv("POSTHASTE_DOF_DUMP");
    if (!dir) {
        return;
    }
    Image d(img.width(), img.height(), 3);
    for (int y = 0; y < img.height(); ++y) {
        for (int x = 0; x < img.width(); ++x) {
            for (int k = 0; k < 3; ++k) {
                d.at(x, y, k) = std::pow(std::clamp(img.at(x, y, k), 0.0f, 1.0f), 1.0f / 2.2f);
            }
        }
    }
    std::string file = name;
    std::replace(file.begin(), file.end(), ' ', '_');
    std::replace(file.begin(), file.end(), ',', '_');
    write_preview(d, std::string(dir) + "/" + file + "_" + what + ".png", false);
}

Errors measure(const Rendered &r, const shading::DofSettings &settings, const std::string &name)
{
    const Image &color = r.frame.image("color");
    const Image &depth = r.frame.image("depth");
    const shading::DofLens lens = lens_of(r.frame.camera);
    Errors e{};
    shading::DofSettings simple = settings;
    simple.method = shading::DofMethod::Simple;
    Image out_node, out_simple;
    shading::DofTimes tn;
    if (!shading::apply_dof(color, depth, lens, settings, out_node, &tn)) {
        out_node = color;
    }
    if (!shading::apply_dof(color, depth, lens, simple, out_simple)) {
        out_simple = color;
    }
    expect_finite_bounded(out_node, color, name);
    dump(name, "node", out_node);
    dump(name, "simple", out_simple);
    dump(name, "truth", r.truth);
    dump(name, "none", color);
    if (std::getenv("POSTHASTE_DOF_DUMP")) {
        Image err(color.width(), color.height(), 3);
        double sum_sq = 0.0, sum_sq_hot = 0.0;
        for (int y = 0; y < color.height(); ++y) {
            for (int x = 0; x < color.width(); ++x) {
                for (int k = 0; k < 3; ++k) {
                    const float d = out_node.at(x, y, k) - r.truth.at(x, y, k);
                    err.at(x, y, k) = std::fabs(d) * 8.0f;
                    sum_sq += double(d) * d;
                    if (r.truth.at(x, y, k) > 2.0f || color.at(x, y, k) > 2.0f) {
                        sum_sq_hot += double(d) * d;
                    }
                }
            }
        }
        std::printf("  %s: share of squared error at values > 2: %.1f %%\n",
                    name.c_str(),
                    100.0 * sum_sq_hot / sum_sq);
        dump(name, "err8", err);
        for (int y = 0; y < color.height(); ++y) {
            for (int x = 0; x < color.width(); ++x) {
                for (int k = 0; k < 3; ++k) {
                    err.at(x, y, k) =
                        std::fabs(out_simple.at(x, y, k) - r.truth.at(x, y, k)) * 8.0f;
                }
            }
        }
        dump(name, "err8_simple", err);
    }
    e.none = rmse(color, r.truth);
    e.simple = rmse(out_simple, r.truth);
    e.node = rmse(out_node, r.truth);
    e.none_psnr = psnr(color, r.truth);
    e.simple_psnr = psnr(out_simple, r.truth);
    e.node_psnr = psnr(out_node, r.truth);
    e.truth_conv = r.truth2.empty() ? -1.0 : rmse(r.truth, r.truth2);
    const shading::CocField f = shading::compute_coc(depth, lens, 0.5f * settings.max_coc_px);
    float mx = 0.0f;
    for (float v : f.radius) {
        mx = std::max(mx, std::fabs(v));
    }
    e.max_coc_px = 2.0f * mx;
    std::printf(
        "| %-28s | %5.1f | %.5f (%5.2f dB) | %.5f (%5.2f dB) | %.5f (%5.2f dB) | %5.1f %% "
        "| %5.1f %% | %.5f |\n",
        name.c_str(),
        e.max_coc_px,
        e.none,
        e.none_psnr,
        e.simple,
        e.simple_psnr,
        e.node,
        e.node_psnr,
        100.0 * (1.0 - e.simple / e.none),
        100.0 * (1.0 - e.node / e.none),
        e.truth_conv);
    std::fflush(stdout);
    return e;
}

void print_header()
{
    std::printf(
        "| case | max CoC px | none RMSE (PSNR) | simple | dof node | simple removes | "
        "node removes | truth N vs 2N |\n");
}

// 960x540; POSTHASTE_DOF_WIDTH overrides the width (16:9) for quick local runs.
const int kW =
    std::getenv("POSTHASTE_DOF_WIDTH") ? std::atoi(std::getenv("POSTHASTE_DOF_WIDTH")) : 960;
const int kH = kW * 9 / 16;

// The default scene's close-up (frames 36-48: 50-55 mm, f/1.8-f/1.4, focus 6-6.5 m).
TEST(DofAccuracySlow, DefaultSceneCloseUp)
{
    print_header();
    const Scene s = raster::load_scene(scene_path("minecrappy.json"));
    // Measured at 960x540 (docs/nodes/dof.md): frame 40 removes 80.3 % (simple 77.4 %), frame
    // 48 86.3 % (simple 87.1 %: the node does not beat the simple method on this frame).
    struct Frame_ {
        int frame;
        double max_vs_none, max_vs_simple;
    };
    for (const Frame_ f : {Frame_{40, 0.25, 0.95}, Frame_{48, 0.17, 1.10}}) {
        const Rendered r = render_case(s, f.frame, kW, kH, 64, true);
        const Errors e = measure(r, {}, "minecrappy frame " + std::to_string(f.frame));
        EXPECT_LT(e.truth_conv, 0.25 * e.node);
        EXPECT_LT(e.node, 0.40 * e.none);  // the target: at least 60 % of the error removed
        EXPECT_LT(e.node, f.max_vs_none * e.none);
        EXPECT_LT(e.node, f.max_vs_simple * e.simple);
    }
}

// Analytic scenes with a wide-open 50 mm lens (their own f/8 barely blurs at this size); 128
// truth samples (these scenes converge fast), checked against 256.
struct AnalyticCase {
    const char *name, *file;
    std::function<void(CameraKey &)> edit;
    double max_vs_none;  // node RMSE / none RMSE asserted (measured, plus a margin)
};

void run_analytic(const AnalyticCase &c)
{
    const Scene s = scene_with_lens(c.file, c.edit);
    const Rendered r = render_case(s, 1, kW, kH, 128, true);
    const Errors e = measure(r, {}, c.name);
    EXPECT_LT(e.truth_conv, 0.35 * e.node) << c.name;
    EXPECT_LT(e.node, e.simple) << c.name;
    EXPECT_LT(e.node, c.max_vs_none * e.none) << c.name;
}

void near_over_sharp(CameraKey &k)
{
    k.position.z = 17.0f;
    k.focal_length_mm = 50.0f;
    k.fstop = 1.4f;
    k.focus_distance = 23.0f;
}

TEST(DofAccuracyPlanesSlow, TwoPlanes)
{
    print_header();
    // Near wall 3 m away blurred over the sharp far wall (23 m) at the screen centre: 81 %.
    run_analytic({"two_planes near over sharp", "two_planes.json", near_over_sharp, 0.30});
    // Sharp near wall, far wall blurred: the far field must not bleed over it. The far wall is
    // nearly uniform, so blurring it changes little: the node matches doing nothing (0.0 %).
    run_analytic({"two_planes far behind sharp",
                  "two_planes.json",
                  [](CameraKey &k) {
                      near_over_sharp(k);
                      k.focus_distance = 3.0f;
                  },
                  1.02});
}

TEST(DofAccuracyEdgesSlow, CubeAndThinSky)
{
    print_header();
    // Cube in focus at 10 m against a sky that blurs to itself: both errors are tiny; the node
    // adds 0.00003 at the silhouette (the hidden sky behind the cube is unknown).
    run_analytic({"cube sharp, sky blurred",
                  "cube.json",
                  [](CameraKey &k) {
                      k.focal_length_mm = 50.0f;
                      k.fstop = 0.7f;
                      k.focus_distance = 10.0f;
                  },
                  1.6});
    // Thin pillars, beam and fence blurred against the sky; ground in focus at 6 m: 88 %.
    run_analytic({"thin_sky focus 6 m",
                  "thin_sky.json",
                  [](CameraKey &k) {
                      k.focal_length_mm = 50.0f;
                      k.fstop = 1.0f;
                      k.focus_distance = 6.0f;
                  },
                  0.20});
}

// Failure cases at 480x270 (64 truth samples): each asserts finite output within the input's
// range and records the error beside doing nothing.
struct FailureCase {
    const char *name, *file;
    std::function<void(CameraKey &)> edit;
    std::function<void(shading::DofSettings &)> settings;
    bool corrupt = false;  // NaN / Inf written into color and depth
};

TEST(DofFailureSlow, FiniteBoundedAndRecorded)
{
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const auto keep = [](shading::DofSettings &) {};
    const FailureCase cases[] = {
        {"near field over sharp bg", "two_planes.json", near_over_sharp, keep},
        {"depth edge: sharp cube, sky",
         "cube.json",
         [](CameraKey &k) {
             k.focal_length_mm = 50.0f;
             k.fstop = 0.7f;
             k.focus_distance = 10.0f;
         },
         keep},
        {"sky (Z = +inf), thin pillars",
         "thin_sky.json",
         [](CameraKey &k) {
             k.focal_length_mm = 50.0f;
             k.fstop = 1.0f;
             k.focus_distance = 6.0f;
         },
         keep},
        {"NaN/Inf in color and depth", "two_planes.json", near_over_sharp, keep, true},
        {"focus at the near plane",
         "two_planes.json",
         [](CameraKey &k) { k.focus_distance = 0.05f; },
         keep},
        {"f/0.5",
         "two_planes.json",
         [](CameraKey &k) {
             near_over_sharp(k);
             k.fstop = 0.5f;
         },
         keep},
        {"f/1e6",
         "two_planes.json",
         [](CameraKey &k) {
             near_over_sharp(k);
             k.fstop = 1e6f;
         },
         keep},
        {"max CoC 0",
         "two_planes.json",
         near_over_sharp,
         [](shading::DofSettings &s) { s.max_coc_px = 0.0f; }},
        {"max CoC 4096 at f/0.5",
         "two_planes.json",
         [](CameraKey &k) {
             near_over_sharp(k);
             k.fstop = 0.5f;
         },
         [](shading::DofSettings &s) { s.max_coc_px = 4096.0f; }},
    };
    std::printf("| case | max CoC px | none RMSE | dof node RMSE | node removes |\n");
    for (const FailureCase &c : cases) {
        const Scene s = scene_with_lens(c.file, c.edit);
        Rendered r = render_case(s, 1, 480, 270, 64, false);
        Image color = r.frame.image("color");
        Image depth = r.frame.image("depth");
        if (c.corrupt) {
            color.at(100, 100, 0) = nan;
            color.at(300, 50, 1) = inf;
            color.at(301, 50, 2) = -inf;
            depth.at(240, 135, 0) = nan;
            depth.at(200, 200, 0) = -inf;
            depth.at(201, 200, 0) = 0.0f;
            depth.at(400, 100, 0) = inf;
        }
        shading::DofSettings settings;
        c.settings(settings);
        const shading::DofLens lens = lens_of(r.frame.camera);
        Image out;
        const bool changed = shading::apply_dof(color, depth, lens, settings, out);
        if (!changed) {
            out = color;  // the node passes its input on
        }
        expect_finite_bounded(out, color, c.name);
        const shading::CocField f = shading::compute_coc(depth, lens, 0.5f * settings.max_coc_px);
        float mx = 0.0f;
        for (float v : f.radius) {
            mx = std::max(mx, std::fabs(v));
        }
        Image clean = color;  // the error of doing nothing, with the corrupt values zeroed
        for (std::size_t i = 0; i < clean.value_count(); ++i) {
            if (!std::isfinite(clean.data()[i])) {
                clean.data()[i] = 0.0f;
            }
        }
        const double none = rmse(clean, r.truth), node = rmse(out, r.truth);
        std::printf("| %-30s | %6.1f | %.5f | %.5f | %6.1f %% |\n",
                    c.name,
                    2.0f * mx,
                    none,
                    node,
                    100.0 * (1.0 - node / none));
        std::fflush(stdout);
        EXPECT_TRUE(std::isfinite(node)) << c.name;
        if (std::string(c.name) == "f/1e6" || std::string(c.name) == "max CoC 0") {
            EXPECT_FALSE(changed) << c.name;  // the input comes back bit for bit
        }
    }
}

}  // namespace
}  // namespace posthaste
