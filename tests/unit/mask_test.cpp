// The mask on colour nodes (graph/mask.h): the engine blends what a node replaced with its input,
// out = in + (node - in) * m, by a channel or the luminance of a pass on the "mask" port.

#include "graph/mask.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "core/error.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// A 4x2 frame: color 0.5 (alpha 1), and a "matte" pass of 0, 0.25, 0.5, 1 ... (and NaN, -1, 2).
Frame input_frame()
{
    Frame f;
    f.set_size(4, 2);
    Image color(4, 2, 4);
    for (int i = 0; i < 8; ++i) {
        float *p = color.data() + 4 * i;
        p[0] = 0.5f;
        p[1] = 0.25f;
        p[2] = 0.125f;
        p[3] = 1.0f;
    }
    f.set("color", std::move(color));
    return f;
}

const float kMatte[8] = {
    0.0f, 0.25f, 0.5f, 1.0f, std::numeric_limits<float>::quiet_NaN(), -1.0f, 2.0f, 0.75f};

Frame mask_frame()
{
    Frame f;
    f.set_size(4, 2);
    Image m(4, 2, 1);
    Image rgb(4, 2, 3);
    for (int i = 0; i < 8; ++i) {
        m.data()[i] = kMatte[i];
        rgb.data()[3 * i] = rgb.data()[3 * i + 1] = rgb.data()[3 * i + 2] = kMatte[i];
    }
    f.set("matte", std::move(m), {"A"});
    f.set("grey", std::move(rgb), {"R", "G", "B"});
    return f;
}

Frame run(const std::string &type, const std::string &params, bool connect_mask = true)
{
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "unused.exr"}},
        {"id": "n", "type": ")" +
                               type + R"(", "inputs": {"image": "src")" +
                               (connect_mask ? R"(, "mask": "src")" : "") + R"(}, "params": )" +
                               params + R"(},
        {"id": "out", "type": "write", "inputs": {"image": "n"}, "params": {"path": "x.exr"}}]})",
                           "mask test",
                           nodes::catalog());
    std::vector<std::shared_ptr<const Frame>> in = {std::make_shared<const Frame>(input_frame())};
    std::vector<std::string> ports = {"image"};
    if (connect_mask) {
        in.push_back(std::make_shared<const Frame>(mask_frame()));
        ports.emplace_back("mask");
    }
    return g.run_node(g.find("n"), in, ports, 1);
}

// A grade of +1 stop doubles RGB; through the mask each pixel gets in + (2 in - in) m, m clamped
// to [0, 1] (NaN: 0): exactly the input at 0 and the graded value at 1.
TEST(Mask, BlendsTheNodesResultWithItsInput)
{
    const Image out = run("grade", R"({"exposure": 1, "mask_pass": "matte"})").image("color");
    const Image inv = run("grade", R"({"exposure": 1, "mask_pass": "matte", "mask_invert": true})")
                          .image("color");
    const float in[3] = {0.5f, 0.25f, 0.125f};
    for (int i = 0; i < 8; ++i) {
        const float m = std::isnan(kMatte[i]) ? 0.0f : std::clamp(kMatte[i], 0.0f, 1.0f);
        for (int c = 0; c < 3; ++c) {
            const float graded = 2.0f * in[c];
            const auto blend = [&](float t) {
                return t == 0.0f ? in[c] : t == 1.0f ? graded : in[c] + (graded - in[c]) * t;
            };
            EXPECT_EQ(out.data()[4 * i + c], blend(m)) << i << " " << c;
            EXPECT_EQ(inv.data()[4 * i + c], blend(1.0f - m)) << i << " " << c;
        }
        EXPECT_EQ(out.data()[4 * i + 3], 1.0f);
    }
}

// Another view's pass is masked by that view's mask pass where the mask frame has one
// (color@right by matte@right; it took matte), and by the mask as named where it has none.
TEST(Mask, AnotherViewsPassTakesThatViewsMask)
{
    Frame in = input_frame();
    Image ramp(4, 2, 4);
    for (int i = 0; i < 32; ++i) {
        ramp.data()[i] = float(i) / 8.0f;
    }
    in.set("color@right", ramp);
    in.set("color@left", ramp);
    Frame mask = mask_frame();
    Image right(4, 2, 1);
    for (int i = 0; i < 8; ++i) {
        right.data()[i] = 1.0f - float(i) / 7.0f;
    }
    mask.set("matte@right", right, {"A"});
    const auto blur = [&](bool masked) {
        Graph g = Graph::parse(R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": "unused.exr"}},
            {"id": "n", "type": "blur", "inputs": {"image": "src", "mask": "src"},
             "params": {"sigma": 1, "passes": "color@right,color@left", "mask_pass": "matte"}},
            {"id": "out", "type": "write", "inputs": {"image": "n"}, "params": {"path": "x.exr"}}]})",
                               "mask test",
                               nodes::catalog());
        std::vector<std::shared_ptr<const Frame>> inputs = {std::make_shared<const Frame>(in)};
        std::vector<std::string> ports = {"image"};
        if (masked) {
            inputs.push_back(std::make_shared<const Frame>(mask));
            ports.emplace_back("mask");
        }
        return g.run_node(g.find("n"), inputs, ports, 1);
    };
    const Frame plain = blur(false), masked = blur(true);
    for (const char *view : {"right", "left"}) {
        const std::string name = std::string("color@") + view;
        const Image &a = in.image(name), &b = plain.image(name), &out = masked.image(name);
        ASSERT_FALSE(a.bit_equal(b));
        for (int i = 0; i < 8; ++i) {
            const float m =
                view == std::string("right")
                    ? right.data()[i]
                    : (std::isnan(kMatte[i]) ? 0.0f : std::clamp(kMatte[i], 0.0f, 1.0f));
            for (int c = 0; c < 4; ++c) {
                EXPECT_EQ(out.data()[4 * i + c],
                          mask_mix(a.data()[4 * i + c], b.data()[4 * i + c], m))
                    << view << " " << i << " " << c;
            }
        }
    }
}

// A read feeding the mask is asked for each view's mask pass (optionally, as the file may not
// have it): it loaded only "matte", so color@right took the chosen view's mask.
TEST(Mask, AMaskReadIsAskedForTheOtherViewsMasks)
{
    const Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "unused.exr"}},
        {"id": "m", "type": "read", "params": {"path": "mask.exr"}},
        {"id": "n", "type": "exposure", "inputs": {"image": "src", "mask": "m"},
         "params": {"exposure": 1, "pass": "color@right", "mask_pass": "matte"}},
        {"id": "out", "type": "write", "inputs": {"image": "n"}, "params": {"path": "x.exr"}}]})",
                                 "mask test",
                                 nodes::catalog());
    const PassSet &asked = g.nodes()[std::size_t(g.find("m"))].requested;
    EXPECT_TRUE(asked.contains("matte"));
    EXPECT_FALSE(asked.contains("matte@right"));
    EXPECT_TRUE(asked.wants("matte@right"));
}

// Unconnected, the mask changes nothing: the node's own bits.
// A fractional mask keeps infinities: the sky's +inf depth blurred under a half mask stayed
// +inf on both sides and came out NaN (inf - inf in the lerp); finite values keep the lerp's bits.
TEST(Mask, AFractionalMaskKeepsInfinities)
{
    constexpr float kInf = std::numeric_limits<float>::infinity();
    EXPECT_EQ(mask_mix(kInf, kInf, 0.5f), kInf);
    EXPECT_EQ(mask_mix(kInf, 2.0f, 0.25f), kInf);
    EXPECT_EQ(mask_mix(3.0f, -kInf, 0.25f), -kInf);
    EXPECT_EQ(mask_mix(0.1f, 0.7f, 0.3f), 0.1f + (0.7f - 0.1f) * 0.3f);
    EXPECT_EQ(mask_mix(kInf, 2.0f, 1.0f), 2.0f);
    EXPECT_EQ(mask_mix(kInf, 2.0f, 0.0f), kInf);
    // merge's mask takes the same convention: NaN is 0, the rest within [0, 1] (a NaN mask made
    // its pixel NaN), and a one-channel matte is the mask under any mask_channel (the default,
    // a, was refused). Pixel 4's matte is NaN: B's colour; pixel 6's is 2: A added once.
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "b", "type": "read", "params": {"path": "b.exr"}},
        {"id": "a", "type": "read", "params": {"path": "a.exr"}},
        {"id": "m", "type": "read", "params": {"path": "m.exr"}},
        {"id": "n", "type": "merge", "inputs": {"b": "b", "a": "a", "mask": "m"},
         "params": {"operation": "add", "mask_pass": "matte"}},
        {"id": "out", "type": "write", "inputs": {"image": "n"}, "params": {"path": "x.exr"}}]})",
                           "merge mask",
                           nodes::catalog());
    const auto in = std::make_shared<const Frame>(input_frame());
    const Frame out = g.run_node(
        g.find("n"), {in, in, std::make_shared<const Frame>(mask_frame())}, {"b", "a", "mask"}, 1);
    const Image &c = out.image("color");
    EXPECT_EQ(c.at(0, 1, 0), 0.5f);  // NaN mask: B
    EXPECT_EQ(c.at(2, 1, 0), 1.0f);  // mask 2: B + A once
    EXPECT_EQ(c.at(1, 1, 0), 0.5f);  // mask -1: B
}

TEST(Mask, WithoutAMaskTheNodeIsUnchanged)
{
    const Image masked = run("grade", R"({"exposure": 1})", false).image("color");
    const Image plain = run("grade", R"({"exposure": 1})", false).image("color");
    EXPECT_EQ(std::vector<float>(masked.data(), masked.data() + masked.value_count()),
              std::vector<float>(plain.data(), plain.data() + plain.value_count()));
    EXPECT_EQ(masked.at(0, 0, 0), 1.0f);
}

TEST(Mask, LuminanceAndChannelErrors)
{
    const Image lum =
        run("exposure", R"({"exposure": 1, "mask_pass": "grey", "mask_channel": "luminance"})")
            .image("color");
    // Grey R = G = B: the luminance is the value (to rounding of the Rec.709 weights).
    EXPECT_NEAR(lum.at(1, 0, 0), 0.5f + 0.5f * 0.25f, 1e-6f);
    try {
        run("exposure", R"({"exposure": 1, "mask_pass": "grey", "mask_channel": "a"})");
        FAIL() << "a missing channel was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("mask pass \"grey\" has 3 channels, no a"),
                  std::string::npos)
            << e.what();
    }
    try {
        run("grade", R"({"mask_pass": "nope"})");  // an identity grade: the mask is not needed
        FAIL() << "a missing mask pass was accepted where the node changed nothing";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos) << e.what();
    }
    try {
        run("blur", R"({"sigma": 1, "mask_pass": "nope"})");
        FAIL() << "a missing pass was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("nope"), std::string::npos) << e.what();
    }
}

// Every node that changes colour declares the mask, once, the same way.
TEST(Mask, EveryColourNodeTakesIt)
{
    int maskable = 0;
    for (const NodeType *t : nodes::catalog().all()) {
        if (!t->spec.maskable) {
            continue;
        }
        ++maskable;
        bool port = false;
        for (const PortSpec &p : t->spec.inputs) {
            port = port || (p.name == kMaskPort.name && p.optional);
        }
        EXPECT_TRUE(port) << t->spec.type;
        for (const ParamSpec *m : {&kMaskPass, &kMaskChannel, &kMaskInvert}) {
            bool found = false;
            for (const ParamSpec &p : t->spec.params) {
                found = found || p.name == m->name;
            }
            EXPECT_TRUE(found) << t->spec.type << " lacks " << m->name;
        }
    }
    EXPECT_GE(maskable, 15);
    for (const char *type : {"grade",
                             "exposure",
                             "tonemap",
                             "blur",
                             "sharpen",
                             "bloom",
                             "grain",
                             "fog",
                             "relight",
                             "dof",
                             "motion_blur",
                             "ocio",
                             "ssr",
                             "hatching"}) {
        EXPECT_TRUE(nodes::catalog().find(type)->spec.maskable) << type;
    }
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

// Every graph the repository ships loads and passes its checks (files exist, parameters apply).
TEST(ShippedGraphs, LoadAndCheck)
{
    namespace fs = std::filesystem;
    int n = 0;
    for (const char *dir : {"graphs", "graphs/cycles"}) {
        for (const auto &e : fs::directory_iterator(fs::path(POSTHASTE_SOURCE_DIR) / dir)) {
            if (e.path().extension() != ".json") {
                continue;
            }
            SCOPED_TRACE(e.path().string());
            const Graph g = Graph::load(e.path().string(), nodes::catalog());
            g.check({g.default_frames().front()});
            ++n;
        }
    }
    EXPECT_GE(n, 14);
}

// The shot graph keys the balls and the ground, and its masks confine each node to its matte:
// outside the balls' matte the grade leaves the render's colour alone.
TEST(ShippedGraphs, ShotKeysAndMasks)
{
    const std::string dir = test::scratch_dir("shot_graph");
    Graph g = Graph::load(std::string(POSTHASTE_SOURCE_DIR) + "/graphs/shot.json",
                          nodes::catalog(),
                          {"scene.width=160",
                           "scene.height=90",
                           "exr.path=" + dir + "/s.####.exr",
                           "png.path=" + dir + "/s.####.png"});
    g.set_capture("grade_balls");
    const Frame f = g.evaluate(12);
    Graph plain = Graph::load(std::string(POSTHASTE_SOURCE_DIR) + "/graphs/shot.json",
                              nodes::catalog(),
                              {"scene.width=160",
                               "scene.height=90",
                               "exr.path=" + dir + "/p.####.exr",
                               "png.path=" + dir + "/p.####.png"});
    plain.set_capture("terrain");
    const Frame before = plain.evaluate(12);
    const Image &balls = f.image("balls"), &after = f.image("color"), &in = before.image("color");
    int inside = 0, changed_inside = 0;
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            const bool same = std::equal(after.pixel(x, y), after.pixel(x, y) + 3, in.pixel(x, y));
            if (balls.at(x, y, 0) == 0.0f) {
                ASSERT_TRUE(same) << x << "," << y;
            } else if (balls.at(x, y, 0) == 1.0f) {
                ++inside;
                changed_inside += same ? 0 : 1;
            }
        }
    }
    EXPECT_GT(inside, 20);
    EXPECT_EQ(changed_inside, inside);
}

}  // namespace
}  // namespace posthaste
