// Hatching with tonal art maps: the TAM's nesting property and determinism, the tone ramp
// (monotonic mean ink, bounded steps), finite and sensible output on sky, NaN normals and
// grazing faces, the id mask, bit-identical output for 1 and N threads, and the node in a graph.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include "core/disk_cache.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "shading/hatching/hatch.h"
#include "shading/hatching/tam.h"
#include "test_util.h"

namespace posthaste::shading {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

TamParams small_params()
{
    TamParams p;
    p.size = 64;
    p.stroke_levels = 3;
    return p;
}

TEST(HatchingTam, NestingAcrossTonesAndLevels)
{
    const TamParams p = small_params();
    const Tam tam = build_tam(p);
    ASSERT_EQ(tam.levels(), 7);  // 64 .. 1
    // Every texel of a darker tone holds at least the ink of the lighter one (its strokes are a
    // superset, composited by 1 - (1 - c)(1 - a)).
    for (int t = 1; t < kTamTones; ++t) {
        for (int l = 0; l < tam.stroke_levels(); ++l) {
            const int n = tam.level_size(l) * tam.level_size(l);
            int violations = 0;
            for (int i = 0; i < n; ++i) {
                violations += tam.texels(t, l)[i] < tam.texels(t - 1, l)[i] ? 1 : 0;
            }
            EXPECT_EQ(violations, 0) << "tone " << t << " level " << l;
        }
    }
    // Each stroke is inked in its own level, every finer level, and every darker tone: the texel
    // under the middle of its arc is covered there. Strokes stay out of coarser levels of their
    // tone: those levels were finished before the stroke existed, and a later stroke of a coarse
    // level is added to it first.
    ASSERT_FALSE(tam.strokes().empty());
    int checked = 0;
    for (const TamStroke &st : tam.strokes()) {
        const float mx = st.cx - st.bend * st.dy, my = st.cy + st.bend * st.dx;
        for (int t = st.tone; t < kTamTones; ++t) {
            for (int l = st.level; l >= 0; --l) {
                const int s = tam.level_size(l);
                const int x = (int(std::floor(mx * float(s))) % s + s) % s;
                const int y = (int(std::floor(my * float(s))) % s + s) % s;
                ASSERT_GE(tam.texels(t, l)[y * s + x], 0.5f)
                    << "stroke of tone " << st.tone << " level " << st.level << " missing in tone "
                    << t << " level " << l;
                ++checked;
            }
        }
        EXPECT_GE(st.level, 0);
        EXPECT_LT(st.level, tam.stroke_levels());
    }
    EXPECT_GT(checked, 500);
    // Tones reach their targets at every stroke level and get darker tone by tone.
    for (int l = 0; l < tam.stroke_levels(); ++l) {
        for (int t = 0; t < kTamTones; ++t) {
            const float target = p.darkest * float(t + 1) / float(kTamTones);
            EXPECT_GE(tam.mean(t, l), target) << "tone " << t << " level " << l;
            EXPECT_LT(tam.mean(t, l), target + 0.06f) << "tone " << t << " level " << l;
        }
    }
    // Filtered levels are box averages: the 1 x 1 level is the mean of the coarsest stroke level.
    EXPECT_NEAR(tam.texels(3, tam.levels() - 1)[0], tam.mean(3, tam.stroke_levels() - 1), 1e-5f);
}

TEST(HatchingTam, DeterministicFromSeedAndFast)
{
    disk_cache::set_enabled(false);  // the builder itself, not the disk cache's copy
    TamParams p;                     // the node's default: 256, 4 stroke levels
    const Tam a = build_tam(p);
    const Tam b = build_tam(p);
    std::printf("TAM 256 build: %.1f ms wall, %.1f ms CPU, %zu strokes\n",
                a.build_ms(),
                a.build_cpu_ms(),
                a.strokes().size());
    ASSERT_EQ(a.strokes().size(), b.strokes().size());
    bool same = true;
    for (int t = 0; t < kTamTones; ++t) {
        for (int l = 0; l < a.levels(); ++l) {
            const int n = a.level_size(l) * a.level_size(l);
            same = same && std::equal(a.texels(t, l), a.texels(t, l) + n, b.texels(t, l));
        }
    }
    EXPECT_TRUE(same);
    p.seed = 2;
    const Tam c = build_tam(p);
    EXPECT_FALSE(std::equal(a.texels(0, 0), a.texels(0, 0) + 256 * 256, c.texels(0, 0)));
    // Start-up cost: tens of milliseconds on an idle core; loose bound for a loaded machine.
    EXPECT_LT(a.build_cpu_ms(), 1000.0);
    disk_cache::set_enabled(true);
}

TEST(HatchingTam, RejectsBadParams)
{
    TamParams p;
    p.size = 100;
    EXPECT_THROW(build_tam(p), Error);
    p = TamParams{};
    p.stroke_levels = 8;
    EXPECT_THROW(build_tam(p), Error);
}

/// A flat, upward-facing plane seen from above, `tone` uniform (luminance = tone^gamma).
struct FlatScene {
    Image color, depth, normal, position, id;
    FlatScene(int w, int h, float tone, float gamma = 2.2f)
        : color(w, h, 4), depth(w, h, 1), normal(w, h, 3), position(w, h, 3), id(w, h, 1)
    {
        const float lum = std::pow(tone, gamma);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < 3; ++c) {
                    color.at(x, y, c) = lum;
                }
                color.at(x, y, 3) = 1.0f;
                depth.at(x, y, 0) = 5.0f;
                normal.at(x, y, 1) = 1.0f;
                position.at(x, y, 0) = 0.01f * float(x);  // 1 cm per pixel
                position.at(x, y, 2) = 0.01f * float(y);
                id.at(x, y, 0) = 3.0f;
            }
        }
    }
    HatchInputs inputs() const { return {&color, &depth, &normal, &position, &id}; }
};

/// Mean ink coverage recovered from the output's red channel (paper -> 0, ink -> 1).
double mean_ink(const Image &out, const HatchSettings &s)
{
    double sum = 0.0;
    for (int y = 0; y < out.height(); ++y) {
        for (int x = 0; x < out.width(); ++x) {
            sum += (s.paper.x - out.at(x, y, 0)) / (s.paper.x - s.ink.x);
        }
    }
    return sum / double(out.pixel_count());
}

TEST(HatchingTone, RampIsMonotonicWithBoundedSteps)
{
    const Tam tam = build_tam(TamParams{});
    HatchSettings s;
    s.outline_width = 0.0f;
    const int steps = 48;
    // Ideal step: the darkest tone's coverage spread over the ramp. Bound: twice that.
    const double ideal = double(TamParams{}.darkest) / steps, bound = 2.0 * ideal;
    double prev = -1.0, max_step = 0.0;
    for (int i = 0; i <= steps; ++i) {
        const float tone = 1.0f - float(i) / float(steps);
        const FlatScene flat(192, 192, tone);
        const double ink = mean_ink(hatch(flat.inputs(), s, tam), s);
        if (i == 0) {
            EXPECT_NEAR(ink, 0.0, 1e-6);  // white paper
        } else {
            EXPECT_GE(ink, prev - 1e-4) << "ramp goes back at step " << i;
            max_step = std::max(max_step, ink - prev);
        }
        prev = ink;
    }
    std::printf("tone ramp: %d steps, max step %.4f (ideal %.4f, bound %.4f), darkest %.3f\n",
                steps,
                max_step,
                ideal,
                bound,
                prev);
    EXPECT_LE(max_step, bound);
    EXPECT_NEAR(prev, TamParams{}.darkest, 0.08);
}

TEST(HatchingRobust, SkyNanNormalsGrazingAndBadColor)
{
    const Tam tam = build_tam(small_params());
    const int w = 64, h = 48;
    FlatScene f(w, h, 0.5f);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            if (y < 12) {  // sky
                f.depth.at(x, y, 0) = kInf;
                for (int c = 0; c < 3; ++c) {
                    f.position.at(x, y, c) = 0.0f;
                    f.normal.at(x, y, c) = 0.0f;
                }
            } else if (y < 24 && x < 32) {  // NaN normals on a surface
                f.normal.at(x, y, 0) = kNaN;
            } else if (y < 24) {  // grazing: 1 m between pixels along the view
                f.position.at(x, y, 2) = float(y) * 1.0f;
                f.position.at(x, y, 0) = float(x) * 1.0f;
            } else if (y < 30 && x < 8) {  // broken color and position
                f.color.at(x, y, 0) = kNaN;
                f.color.at(x, y, 1) = kInf;
                f.position.at(x, y, 1) = kNaN;
            }
        }
    }
    for (int mode = 0; mode < 3; ++mode) {
        HatchSettings s;
        s.screen_space = mode == 1;
        s.triplanar = mode == 2;
        s.outline_width = 2.0f;
        const Image out = hatch(f.inputs(), s, tam);
        for (std::size_t i = 0; i < out.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(out.data()[i])) << "mode " << mode << " value " << i;
        }
        if (mode != 1) {
            // Sky away from the horizon is blank paper.
            EXPECT_FLOAT_EQ(out.at(5, 3, 0), s.paper.x);
            EXPECT_FLOAT_EQ(out.at(5, 3, 2), s.paper.z);
            // NaN normals: the flat (1 x 1 level) tone of the 7-level ramp, no strokes.
            const float level = (1.0f - hatch_tone(f.color.pixel(10, 18), 4, s)) * kTamTones;
            const int k = std::min(int(level), kTamTones - 1);
            auto flat_of = [&](int j) {
                return j == 0 ? 0.0f : tam.texels(j - 1, tam.levels() - 1)[0];
            };
            const float flat = flat_of(k) + (level - float(k)) * (flat_of(k + 1) - flat_of(k));
            const float expect = s.paper.x + flat * (s.ink.x - s.paper.x);
            EXPECT_NEAR(out.at(10, 18, 0), expect, 1e-4f);
            // Grazing: the footprint spans many tiles, so the tone is flat as well.
            EXPECT_NEAR(out.at(50, 18, 0), expect, 0.02f);
        }
    }
}

TEST(HatchingRobust, IdMaskAndMix)
{
    const Tam tam = build_tam(small_params());
    const FlatScene f(32, 32, 0.3f);
    HatchSettings s;
    s.ids = {7};  // the plane is id 3: untouched
    const Image kept = hatch(f.inputs(), s, tam);
    EXPECT_TRUE(kept.bit_equal(f.color));
    s.ids = {1, 3};
    const Image drawn = hatch(f.inputs(), s, tam);
    EXPECT_FALSE(drawn.bit_equal(f.color));
    s.mix = 0.25f;
    const Image quarter = hatch(f.inputs(), s, tam);
    EXPECT_NEAR(quarter.at(4, 4, 1),
                f.color.at(4, 4, 1) + 0.25f * (drawn.at(4, 4, 1) - f.color.at(4, 4, 1)),
                1e-6f);
}

const raster::Scene &scene()
{
    static const raster::Scene s =
        raster::load_scene(std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/minecrappy.json");
    return s;
}

TEST(HatchingRobust, SameBitsForAnyThreadCount)
{
    raster::RenderOptions o;
    o.width = 240;
    o.height = 136;
    o.passes = {"color", "depth", "normal", "position"};
    const Frame f = raster::render_frame(scene(), 20, o);
    const Tam tam = build_tam(TamParams{});
    const HatchInputs in{
        &f.image("color"), &f.image("depth"), &f.image("normal"), &f.image("position")};
    for (int mode = 0; mode < 2; ++mode) {
        HatchSettings s;
        s.triplanar = mode == 1;
        set_thread_count(1);
        const Image one = hatch(in, s, tam);
        set_thread_count(4);
        const Image four = hatch(in, s, tam);
        set_thread_count(0);
        EXPECT_TRUE(one.bit_equal(four)) << "mode " << mode;
    }
}

// The kernel is one Highway source compiled without FP contraction, so each Highway target this
// CPU has (the best, AVX-512, AVX2 with its own loads and stores, SSE4, one lane) and the portable
// path must agree to within 1e-6 on every value of a rendered frame (in practice bit for bit), in
// every mode. Triplanar weights go through exp(y log x), whose
// per-target implementations may differ by a few ulp: there the tolerance is 2e-5. An odd width
// exercises the row tails, a 3-channel color the generic load and store, ids the per-lane mask.
TEST(HatchingSimd, BestTargetMatchesPortableTarget)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    raster::RenderOptions o;
    o.width = 333;
    o.height = 190;
    o.passes = {"color", "depth", "normal", "position", "id"};
    const Frame f = raster::render_frame(scene(), 20, o);
    const Tam tam = build_tam(TamParams{});
    Image rgb(o.width, o.height, 3);
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            for (int c = 0; c < 3; ++c) {
                rgb.at(x, y, c) = f.image("color").at(x, y, c);
            }
        }
    }
    for (int mode = 0; mode < 12; ++mode) {
        HatchSettings s;
        HatchInputs in{&f.image("color"),
                       &f.image("depth"),
                       &f.image("normal"),
                       &f.image("position"),
                       &f.image("id")};
        s.screen_space = mode == 1 || mode == 2;
        s.outline_width = mode == 2 || mode == 3 ? 0.0f : (mode == 4 ? 4.0f : 1.5f);
        s.tone_from_light = mode == 5;
        s.mix = mode == 6 ? 0.4f : 1.0f;
        if (mode == 7) {
            in.color = &rgb;
        }
        s.triplanar = mode == 8 || mode == 9;
        s.screen_space = s.screen_space || mode == 9;  // triplanar is ignored in screen mode
        if (mode >= 10) {
            s.ids = {1, 3};  // the other materials keep their input colour
            s.mix = mode == 11 ? 0.5f : 1.0f;
            in.color = mode == 11 ? &rgb : in.color;
        }
        Image scalar;
        {
            simd::ScopedLevel level(simd::Level::Scalar);
            scalar = hatch(in, s, tam);
        }
        test::for_each_highway_target([&](const char *target) {
            const Image vec = hatch(in, s, tam);
            ASSERT_EQ(vec.value_count(), scalar.value_count());
            float max_diff = 0.0f;
            std::size_t differ = 0;
            for (std::size_t i = 0; i < vec.value_count(); ++i) {
                const float d = std::abs(vec.data()[i] - scalar.data()[i]);
                max_diff = std::max(max_diff, d);
                differ += d > 0.0f ? 1 : 0;
            }
            std::printf("mode %d, %s: against the portable path max |diff| %g, %zu values differ\n",
                        mode,
                        target,
                        double(max_diff),
                        differ);
            EXPECT_LE(max_diff, mode == 8 ? 2e-5f : 1e-6f) << "mode " << mode << ", " << target;
            if (mode == 10) {  // the mask takes some pixels and leaves others
                std::size_t kept = 0;
                for (int y = 0; y < o.height; ++y) {
                    for (int x = 0; x < o.width; ++x) {
                        kept +=
                            std::equal(vec.pixel(x, y), vec.pixel(x, y) + 4, in.color->pixel(x, y))
                                ? 1
                                : 0;
                    }
                }
                EXPECT_GT(kept, 0u);
                EXPECT_LT(kept, vec.pixel_count());
            }
        });
    }
}

TEST(HatchingNode, RenderHatchGraph)
{
    const std::string out = test::scratch_dir("hatching_node") + "/x.exr";
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "scene", "type": "render", "params": {"width": 96, "height": 54,
         "scene": ")" + std::string(POSTHASTE_SOURCE_DIR) +
                               R"(/samples/scenes/minecrappy.json"}},
        {"id": "ink", "type": "hatching", "inputs": {"image": "scene"},
         "params": {"ids": "1, 2,3", "tam_size": "128"}},
        {"id": "o", "type": "write", "inputs": {"image": "ink"}, "params": {"path": ")" +
                               out + R"("}}]})",
                           "g.json",
                           nodes::catalog());
    g.set_capture("ink");
    const Frame f = g.evaluate(3);
    ASSERT_TRUE(f.has("color"));
    EXPECT_TRUE(f.has("id"));  // asked of the render because `ids` is given
    const Image &c = f.image("color");
    EXPECT_EQ(c.width(), 96);
    for (std::size_t i = 0; i < c.value_count(); ++i) {
        ASSERT_TRUE(std::isfinite(c.data()[i]));
    }
    try {
        Graph bad = Graph::parse(R"({"nodes": [
            {"id": "scene", "type": "render", "params": {"width": 8, "height": 8,
             "scene": ")" + std::string(POSTHASTE_SOURCE_DIR) +
                                     R"(/samples/scenes/cube.json"}},
            {"id": "ink", "type": "hatching", "inputs": {"image": "scene"},
             "params": {"ids": "1,x"}},
            {"id": "o", "type": "write", "inputs": {"image": "ink"}, "params": {"path": ")" +
                                     out + R"("}}]})",
                                 "g.json",
                                 nodes::catalog());
        bad.check({1});
        ADD_FAILURE() << "bad ids accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("param \"ids\": expected comma-separated integers"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace posthaste::shading
