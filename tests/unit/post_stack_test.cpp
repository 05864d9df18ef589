// graphs/post_stack.json, the whole post stack in Unity's order, run on a small frame: it loads
// and checks, every node runs, and the display-referred result is finite, within the display
// range and neither black nor a flat field; the graded scene-linear EXR is written beside it;
// a frame from a later chunk (its auto exposure warmed up from history) equals the same frame
// of a run from the start.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "graph/graph.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

Graph post_stack(const std::string &dir)
{
    Graph g = Graph::load(std::string(POSTHASTE_SOURCE_DIR) + "/graphs/post_stack.json",
                          nodes::catalog(),
                          {"scene.width=96",
                           "scene.height=54",
                           "exposure.adaptation_frames=3",
                           "exr.path=" + dir + "/post.####.exr",
                           "png.path=" + dir + "/post.####.png"});
    g.set_capture("grain");
    return g;
}

TEST(PostStack, RunsEveryNodeOnASmallFrame)
{
    const std::string dir = test::scratch_dir("post_stack");
    const Graph g = post_stack(dir);
    g.check({5, 6});
    for (const char *type : {"ao",
                             "fog",
                             "dof",
                             "motion_blur",
                             "bloom",
                             "exposure",
                             "lens",
                             "grade",
                             "tonemap",
                             "grain"}) {
        bool found = false;
        for (const GraphNode &n : g.nodes()) {
            found = found || n.identity.type == type;
        }
        EXPECT_TRUE(found) << type;
    }
    const Frame out = g.evaluate(6);
    const Image &c = out.image("color");
    double sum = 0.0, sum2 = 0.0;
    for (int y = 0; y < c.height(); ++y) {
        for (int x = 0; x < c.width(); ++x) {
            for (int k = 0; k < 3; ++k) {
                const float v = c.at(x, y, k);
                ASSERT_TRUE(std::isfinite(v));
                ASSERT_GE(v, -0.01f);
                ASSERT_LE(v, 1.05f);  // display-linear; grain may lift a highlight a little
                sum += v;
                sum2 += double(v) * v;
            }
        }
    }
    const double n = double(c.pixel_count()) * 3.0;
    const double mean = sum / n, sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
    EXPECT_GT(mean, 0.05);
    EXPECT_LT(mean, 0.95);
    EXPECT_GT(sd, 0.02);
    EXPECT_TRUE(std::filesystem::exists(dir + "/post.0006.exr"));
    EXPECT_TRUE(std::filesystem::exists(dir + "/post.0006.png"));

    // Frame 6 again in a fresh graph, as a farm chunk starting there would run it.
    const Graph chunk = post_stack(test::scratch_dir("post_stack_chunk"));
    EXPECT_TRUE(chunk.evaluate(6).image("color").bit_equal(c));
}

}  // namespace
}  // namespace posthaste
