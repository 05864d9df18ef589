// The renderer's Cryptomatte (src/raster/render_cryptomatte.cpp): coverage from the beauty's
// samples sums to 1 on every pixel no sky sample reaches, the ranks are ordered, every ID is in
// the manifest, and a matte keyed from the written file equals the one keyed from the render.

#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>

#include "core/cryptomatte_id.h"
#include "graph/graph.h"
#include "io/cryptomatte.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

const std::string kScene = std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/minecrappy.json";

/// The render's frame with every rank layer (and color), captured at the render node.
Frame render(int supersample, const std::string &extra = "")
{
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "r", "type": "render", "params": {"scene": ")" +
                               kScene + R"(", "width": 96, "height": 54, "supersample": )" +
                               std::to_string(supersample) + extra + R"(}},
        {"id": "k", "type": "cryptomatte", "inputs": {"image": "r"},
         "params": {"layer": "CryptoObject", "matte": ["grass"]}},
        {"id": "k2", "type": "cryptomatte", "inputs": {"image": "k"},
         "params": {"layer": "CryptoMaterial", "matte": ["stone"], "pass": "stone"}},
        {"id": "o", "type": "write", "inputs": {"image": "k2"},
         "params": {"path": "/tmp/unused_crypto_render.exr", "passes": "matte,stone"}}]})",
                           "render cryptomatte",
                           nodes::catalog());
    g.set_capture("k2");
    return g.evaluate(12);
}

TEST(CryptomatteRender, CoverageSumsToOneAndRanksAreOrdered)
{
    for (int ss : {1, 2, 4}) {
        const Frame f = render(ss);
        const std::vector<cryptomatte::Layer> layers = cryptomatte::find_layers(f.attributes, "r");
        ASSERT_EQ(layers.size(), 2u);
        for (const cryptomatte::Layer &l : layers) {
            SCOPED_TRACE(l.name + " supersample " + std::to_string(ss));
            const std::vector<std::string> ranks = cryptomatte::rank_passes(l, f.pass_names(), "r");
            ASSERT_EQ(ranks.size(), 3u);
            std::map<std::uint32_t, bool> in_manifest;
            for (const auto &[name, id] : l.manifest) {
                in_manifest[cryptomatte::bits_of(id)] = true;
            }
            const Image &depth = f.image("depth");
            int covered = 0, partial = 0;
            for (int y = 0; y < f.height(); ++y) {
                for (int x = 0; x < f.width(); ++x) {
                    float sum = 0.0f, last = 2.0f;
                    for (const std::string &r : ranks) {
                        const float *p = f.image(r).pixel(x, y);
                        for (int j = 0; j < 2; ++j) {
                            const float id = p[2 * j], cov = p[2 * j + 1];
                            if (cov == 0.0f) {
                                ASSERT_EQ(id, 0.0f);
                                last = 0.0f;
                                continue;
                            }
                            ASSERT_TRUE(in_manifest.count(cryptomatte::bits_of(id)));
                            ASSERT_LE(cov, last);  // most coverage first
                            last = cov;
                            sum += cov;
                        }
                    }
                    ASSERT_LE(sum, 1.0f);
                    if (sum > 0.0f && sum < 1.0f) {
                        ++partial;
                    }
                    // A pixel whose centre sees a surface and whose samples are all surfaces
                    // sums to exactly 1 (shares of 1/ss^2).
                    if (std::isfinite(depth.at(x, y, 0)) && sum == 1.0f) {
                        ++covered;
                    }
                }
            }
            EXPECT_GT(covered, f.width() * f.height() / 2);
            if (ss == 1) {
                EXPECT_EQ(partial, 0);  // one sample a pixel: all or nothing
            } else {
                EXPECT_GT(partial, 0);  // edges against the sky
            }
        }
    }
}

// The matte of a name is the coverage of its ID: keyed from the render and from the file written
// and read back, the same bits; the manifest names the scene's materials and moving objects.
TEST(CryptomatteRender, RoundTripThroughAFile)
{
    const std::string dir = test::scratch_dir("cryptomatte_render");
    Graph w = Graph::parse(
        R"({"nodes": [
        {"id": "r", "type": "render", "params": {"scene": ")" +
            kScene +
            R"(", "width": 96, "height": 54, "supersample": 2}},
        {"id": "o", "type": "write", "inputs": {"image": "r"},
         "params": {"path": ")" +
            dir +
            R"(/f.####.exr", "passes": "color,depth,CryptoObject00,CryptoObject01,CryptoObject02,CryptoMaterial00,CryptoMaterial01,CryptoMaterial02", "storage": "half"}}]})",
        "write",
        nodes::catalog());
    w.evaluate(12);
    Graph r = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               dir + R"(/f.####.exr"}},
        {"id": "k", "type": "cryptomatte", "inputs": {"image": "src"},
         "params": {"layer": "CryptoObject", "matte": ["grass"]}},
        {"id": "k2", "type": "cryptomatte", "inputs": {"image": "k"},
         "params": {"layer": "CryptoMaterial", "matte": ["stone"], "pass": "stone"}},
        {"id": "o", "type": "write", "inputs": {"image": "k2"},
         "params": {"path": ")" +
                               dir + R"(/m.exr", "passes": "matte,stone"}}]})",
                           "read",
                           nodes::catalog());
    r.set_capture("k2");
    const Frame from_file = r.evaluate(12);
    const Frame direct = render(2);
    for (const char *p : {"matte", "stone"}) {
        const Image &a = from_file.image(p), &b = direct.image(p);
        ASSERT_EQ(a.value_count(), b.value_count());
        EXPECT_TRUE(std::equal(a.data(), a.data() + a.value_count(), b.data())) << p;
        double sum = 0.0;
        for (std::size_t i = 0; i < a.value_count(); ++i) {
            sum += a.data()[i];
        }
        EXPECT_GT(sum, 10.0) << p;  // the scene has grass and stone in view
    }
    const auto layers = cryptomatte::find_layers(from_file.attributes, dir);
    ASSERT_EQ(layers.size(), 2u);
    const auto named = [](const cryptomatte::Layer &l, const std::string &n) {
        return std::any_of(
            l.manifest.begin(), l.manifest.end(), [&](const auto &e) { return e.first == n; });
    };
    EXPECT_TRUE(named(layers[1], "ball_0") && named(layers[1], "grass")) << layers[1].name;
    EXPECT_TRUE(named(layers[0], "stone") && !named(layers[0], "ball_0")) << layers[0].name;
}

}  // namespace
}  // namespace posthaste
