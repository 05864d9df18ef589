// Either handedness: the nodes that read world-space data (normals, positions, tangents, the
// camera) give the same result for a mirrored world, world x negated in every pass and in the
// camera, as Blender's right-handed world is to the rasterizer's left-handed one. Not here: ssr,
// whose sky fallback and probe are world-space data of the scene that the frame does not carry
// (a mirrored frame would need a mirrored sky), and fog's height and atmosphere models, whose
// "up" is the world's +Y.

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>

#include "metrics/metrics.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame mirrored(const Frame &f)
{
    Frame m = f;
    for (const char *name : {"normal", "position", "tangent"}) {
        if (!f.has(name)) {
            continue;
        }
        Image img = f.image(name);
        for (std::size_t i = 0; i < img.pixel_count(); ++i) {
            img.data()[i * std::size_t(img.channels())] *= -1.0f;
        }
        m.set(name, std::move(img), f.pass(name).channels);
    }
    const glm::mat4 mirror = glm::scale(glm::mat4(1.0f), glm::vec3(-1.0f, 1.0f, 1.0f));
    for (auto *mat : {&m.camera.world_to_camera,
                      &m.camera.world_to_ndc,
                      &m.camera.prev_world_to_camera,
                      &m.camera.prev_world_to_ndc}) {
        if (*mat) {
            **mat = **mat * mirror;
        }
    }
    return m;
}

TEST(Handedness, NodesGiveTheSameResultForAMirroredWorld)
{
    const raster::Scene scene = raster::load_scene(test::scene_path("glossy.json"));
    const Frame f = raster::render_frame(scene,
                                         8,
                                         test::render_options(240,
                                                              136,
                                                              {"color",
                                                               "depth",
                                                               "normal",
                                                               "position",
                                                               "albedo",
                                                               "material",
                                                               "motion",
                                                               "tangent",
                                                               "id"}));
    const Frame m = mirrored(f);
    struct Case {
        const char *type, *params, *pass;
    };
    for (const Case &c : {Case{"ao", "{}", "ao"},
                          Case{"fog", R"({"model": "exp", "density": 0.05})", "color"},
                          Case{"motion_blur", R"({"source": "camera"})", "color"},
                          Case{"dof", R"({"fstop": 2, "focus_distance": 5})", "color"}}) {
        const Frame a = test::run_node(c.type, f, c.params, 8);
        const Frame b = test::run_node(c.type, m, c.params, 8);
        const double rms = metrics::compare(a.image(c.pass), b.image(c.pass)).all.rms_error;
        EXPECT_LT(rms, 1e-4) << c.type;
    }
    // relight's lights are world-space too: the mirrored world's light is the mirrored light.
    const Frame a = test::run_node(
        "relight", f, R"({"lights": [{"type": "point", "position": [1.5, 2.0, 0.5]}]})", 8);
    const Frame b = test::run_node(
        "relight", m, R"({"lights": [{"type": "point", "position": [-1.5, 2.0, 0.5]}]})", 8);
    EXPECT_LT(metrics::compare(a.image("color"), b.image("color")).all.rms_error, 1e-4);
}

}  // namespace
}  // namespace posthaste
