// Reflections at a size where the ssr node's default traces every fourth pixel (docs/ACCURACY.md,
// "Reflections"): the glossy scene at 1280x720, frames 1 and 16, against the exactly traced
// reflections (32 rays a glossy pixel: its own noise is a few thousandths, the errors compared
// are tenths and hundredths). The default is quarter resolution there, removes at least half of
// the do-nothing error (the goal), and keeps most of what half resolution removes.

#include <gtest/gtest.h>

#include "raster/ray_cast.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame glossy_frame(const raster::Scene &s, int w, int h, int frame)
{
    Frame f = raster::render_frame(
        s,
        frame,
        test::render_options(
            w, h, {"color", "depth", "normal", "albedo", "material", "position", "shadow"}));
    const glm::vec3 d = s.sun.direction;
    f.attributes.push_back(OIIO::ParamValue("posthaste:sunDirection", OIIO::TypeVector, 1, &d));
    f.attributes.push_back(OIIO::ParamValue("posthaste:skyAmbient", s.sky_ambient));
    const glm::vec3 sun = s.sun.color * s.sun.illuminance;
    f.attributes.push_back(OIIO::ParamValue("posthaste:sunIrradiance", OIIO::TypeVector, 1, &sun));
    return f;
}

TEST(SsrAccuracySlow, QuarterResolutionByDefaultAt720pRemovesMostOfTheError)
{
    const raster::Scene s = raster::load_scene(test::scene_path("glossy.json"));
    constexpr int w = 1280, h = 720;
    double none = 0.0, def = 0.0, quarter = 0.0, half = 0.0;
    for (const int frame : {1, 16}) {
        const Frame f = glossy_frame(s, w, h, frame);
        const Image truth =
            raster::render_reflection_truth(s, frame, test::render_options(w, h, {"color"}), 32, 7);
        const Frame d = test::run_node("ssr", f, "{}", frame);
        const Frame q = test::run_node("ssr", f, R"({"resolution": "quarter"})", frame);
        const Frame hf = test::run_node("ssr", f, R"({"resolution": "half"})", frame);
        // auto is quarter from 1280 pixels wide.
        EXPECT_TRUE(d.image("color").bit_equal(q.image("color"))) << "frame " << frame;
        EXPECT_FALSE(d.image("color").bit_equal(hf.image("color"))) << "frame " << frame;
        none += 0.5 * test::rms_rgb(f.image("color"), truth);
        def += 0.5 * test::rms_rgb(d.image("color"), truth);
        quarter += 0.5 * test::rms_rgb(q.image("color"), truth);
        half += 0.5 * test::rms_rgb(hf.image("color"), truth);
    }
    const double removed = 1.0 - def / none, removed_half = 1.0 - half / none;
    EXPECT_GT(removed, 0.5) << "default " << def << " nothing " << none;
    EXPECT_GT(removed, 0.85 * removed_half) << "quarter " << quarter << " half " << half;
    EXPECT_LT(half, quarter);  // half traces four times the pixels: closer still
}

}  // namespace
}  // namespace posthaste
