// relight against Cycles (samples/cycles/, tests/cycles/make_cycles_set.py --relight;
// docs/ACCURACY.md, "Against Cycles"): a second, warm sun added to the yard from the camera's
// left. Cycles renders that light alone, direct light only; the truth is the input plus it. The
// node shades from the normal and position passes and the material Blender does not write, from
// the shader AOVs albedo, roughness and metallic; the camera is solved from the passes.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>
#include <string>

#include "graph/graph.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

const std::string kDir = std::string(POSTHASTE_SOURCE_DIR) + "/samples/cycles/";
constexpr int kFrame = 2;
// samples/cycles/relight_fill.txt: the light the script added.
const std::string kFill =
    R"({"type": "directional", "direction": [-0.551269, -0.6515, 0.5212], "color": [1.0, 0.8, 0.6], "intensity": 2.0})";

Image color_of(const std::string &file)
{
    const std::set<std::string> color = {"color"};
    return read_frame(kDir + file, &color, kFrame).image("color");
}

/// relight over `file` (a frame of the set) with the fill light and `params` (more keys).
Image relight(const std::string &file, const std::string &params)
{
    const std::string graph = R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")" +
                              kDir + file + R"("}},
        {"id": "relight", "type": "relight", "inputs": {"image": "in"}, "params": {"mode": "add", "lights": [)" +
                              kFill + "]" + params + R"(}},
        {"id": "out", "type": "write", "inputs": {"image": "relight"}, "params": {"path": "unused.exr"}}]})";
    Graph g = Graph::parse(graph, "cycles relight", nodes::catalog());
    g.set_capture("relight");
    const Image out = g.evaluate(kFrame).image("color");
    for (int y = 0; y < out.height(); ++y) {
        for (int x = 0; x < out.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                EXPECT_TRUE(std::isfinite(out.at(x, y, c))) << params;
            }
        }
    }
    return out;
}

/// a + b over RGB (alpha a's).
Image sum(const Image &a, const Image &b)
{
    Image s = a;
    for (int y = 0; y < s.height(); ++y) {
        for (int x = 0; x < s.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                s.at(x, y, c) += b.at(x, y, c);
            }
        }
    }
    return s;
}

TEST(CyclesRelightSlow, AFillLightAgainstCycles)
{
    const Image truth = color_of("yard.relight_truth.exr");
    const Image input = color_of("yard.ssr_sky.exr");
    const double nothing = test::rms_rgb(input, truth);
    const double node = test::rms_rgb(
        relight("yard.ssr_sky.exr", R"(, "diffuse": "burley", "shadows": true)"), truth);
    const double unshadowed =
        test::rms_rgb(relight("yard.ssr_sky.exr", R"(, "diffuse": "burley")"), truth);
    const double lambert = test::rms_rgb(
        relight("yard.ssr_sky.exr", R"(, "diffuse": "lambert", "shadows": true)"), truth);
    // Without the AOVs: the set's passes, whose albedo is DiffCol (black on the metals) and
    // whose material is the node's constants; against their own Combined plus the same light.
    const Image fill = color_of("yard.relight_fill.exr");
    const Image plain_truth = sum(color_of("yard.passes.exr"), fill);
    const double plain = test::rms_rgb(
        relight("yard.passes.exr", R"(, "diffuse": "burley", "shadows": true)"), plain_truth);
    const double plain_nothing = test::rms_rgb(color_of("yard.passes.exr"), plain_truth);
    std::printf(
        "relight  nothing %.4f  burley + shadows %.4f (%2.0f %%)  without shadows %.4f  lambert "
        "%.4f  without the AOVs %.4f (nothing %.4f)\n",
        nothing,
        node,
        100.0 * (1.0 - node / nothing),
        unshadowed,
        lambert,
        plain,
        plain_nothing);
    // Measured on 2026-11-30: nothing 0.1729, the graph's setting 0.0589 (66 %), without
    // shadows 0.0576, Lambert 0.0605; most of what is left is the fill's glints on the metal
    // balls (docs/ACCURACY.md).
    EXPECT_LT(node, 0.4 * nothing);
    EXPECT_LT(node, lambert);
    EXPECT_LT(node, 0.9 * plain);
}

}  // namespace
}  // namespace posthaste
