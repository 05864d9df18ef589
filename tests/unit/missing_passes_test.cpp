// Passes a renderer rarely writes (Blender writes no material, tangent or aperture): the nodes
// stand a parameter's constant in, say so once, and give the bits of a frame that had it.

#include <gtest/gtest.h>

#include <cstring>
#include <fstream>

#include "core/error.h"
#include "io/image_file.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame glossy_frame(int w, int h)
{
    static const raster::Scene scene = raster::load_scene(test::scene_path("glossy.json"));
    return raster::render_frame(
        scene,
        1,
        test::render_options(
            w, h, {"color", "depth", "normal", "position", "albedo", "material", "tangent"}));
}

// A frame without a material pass (Blender writes none by default) is shaded with the
// roughness and metallic parameters: the same bits as the frame given that constant material.
TEST(MissingPasses, AMissingMaterialIsTheParametersConstant)
{
    const Frame f = glossy_frame(96, 54);
    for (const char *node : {"ssr", "relight"}) {
        const std::string params =
            std::string(node) == "ssr"
                ? R"({"roughness": 0.2, "metallic": 1})"
                : R"({"roughness": 0.2, "metallic": 1, "anisotropic": false, "lights": [{"type": "point", "position": [0, 3, 0]}]})";
        Frame without = f;
        without.erase("material");
        Frame constant = f;
        Image m(96, 54, 3);
        for (std::size_t i = 0; i < m.pixel_count(); ++i) {
            m.data()[3 * i] = 0.2f;
            m.data()[3 * i + 1] = 1.0f;
        }
        constant.set("material", std::move(m), f.pass("material").channels);
        const Image a = test::run_node(node, without, params).image("color");
        const Image b = test::run_node(node, constant, params).image("color");
        EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.pixel_count() * 4 * sizeof(float))) << node;
        // ... and differs from the frame's own material (the test can fail).
        const Image c = test::run_node(node, f, params).image("color");
        EXPECT_NE(0, std::memcmp(a.data(), c.data(), a.pixel_count() * 4 * sizeof(float))) << node;
    }
}

// Without a tangent pass, relight's anisotropic shading is the isotropic one, not an error.
TEST(MissingPasses, AMissingTangentShadesIsotropic)
{
    Frame f = glossy_frame(96, 54);
    Image m = f.image("material");
    for (std::size_t i = 0; i < m.pixel_count(); ++i) {
        m.data()[3 * i + 2] = 0.8f;  // every surface anisotropic
    }
    f.set("material", std::move(m), f.pass("material").channels);
    Frame without = f;
    without.erase("tangent");
    const std::string lights = R"("lights": [{"type": "point", "position": [0, 3, 0]}])";
    const Image a = test::run_node("relight", without, "{" + lights + "}").image("color");
    const Image b =
        test::run_node("relight", f, R"({"anisotropic": false, )" + lights + "}").image("color");
    EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.pixel_count() * 4 * sizeof(float)));
    // ... where the tangent, when there, changes the shading (the test can fail).
    const Image c = test::run_node("relight", f, "{" + lights + "}").image("color");
    EXPECT_NE(0, std::memcmp(a.data(), c.data(), a.pixel_count() * 4 * sizeof(float)));
}

// Without an aperture in the header, dof takes its fstop default, 5.6: the bits of the frame
// given f/5.6, and not those of another f-stop (the test can fail).
TEST(MissingPasses, AMissingApertureIsTheDefaultFstop)
{
    const raster::Scene scene = raster::load_scene(test::scene_path("minecrappy.json"));
    Frame f = raster::render_frame(scene, 40, test::render_options(96, 54, {"color", "depth"}));
    f.camera.fstop.reset();
    const std::string focus = R"("focus_distance": 3)";
    const Image a = test::run_node("dof", f, "{" + focus + "}", 40).image("color");
    const Image b = test::run_node("dof", f, R"({"fstop": 5.6, )" + focus + "}", 40).image("color");
    const Image c = test::run_node("dof", f, R"({"fstop": 2, )" + focus + "}", 40).image("color");
    EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.pixel_count() * 4 * sizeof(float)));
    EXPECT_NE(0, std::memcmp(a.data(), c.data(), a.pixel_count() * 4 * sizeof(float)));
}

// Without a motion pass, motion_blur reprojects depth through the header's camera, as its
// `source: camera` does (the pass was once required, so the documented fallback never ran). A
// motion pass the graph names is the one the rest of colour blurs along, also where the frame
// has diffuse_motion for the lighting split (it was ignored there, unchecked).
TEST(MissingPasses, AMissingMotionPassIsReprojectedAndANamedOneIsUsed)
{
    const raster::Scene scene = raster::load_scene(test::scene_path("minecrappy.json"));
    const Frame f =
        raster::render_frame(scene, 6, test::render_options(96, 54, {"color", "depth"}));
    const Image fallback = test::run_node("motion_blur", f, "{}", 6).image("color");
    const Image camera =
        test::run_node("motion_blur", f, R"({"source": "camera"})", 6).image("color");
    EXPECT_TRUE(fallback.bit_equal(camera));
    EXPECT_FALSE(fallback.bit_equal(f.image("color")));  // the camera moves: a blur
    // Through a graph, from a file without motion: the read no longer refuses it (the plan
    // asked for the pass as required, so the fallback above never ran on a file).
    const std::string dir = test::scratch_dir("missing_motion");
    write_exr(f, dir + "/in.exr", {});
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": "in.exr"}},
        {"id": "mb", "type": "motion_blur", "inputs": {"image": "in"}},
        {"id": "out", "type": "write", "inputs": {"image": "mb"},
         "params": {"path": "out.exr", "passes": "color"}}]})";
    std::string log;
    EXPECT_EQ(0, test::run_command(std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json", &log))
        << log;
    EXPECT_NE(log.find("motion reprojected from depth"), std::string::npos) << log;
    // A motion_pass the graph names and the frame lacks is a typo: an error naming it (it fell
    // back to the camera with a note, and the result changed silently).
    try {
        test::run_node("motion_blur", f, R"({"motion_pass": "motoin"})", 6);
        ADD_FAILURE() << "a misspelt motion_pass was taken";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("no pass \"motoin\""), std::string::npos) << e.what();
    }
    Frame nocam = f;
    nocam.camera.prev_world_to_ndc.reset();
    try {
        test::run_node("motion_blur", nocam, "{}", 6);
        ADD_FAILURE() << "no motion and no previous camera: refused";
    } catch (const Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("(no pass \"motion\": motion reprojected from depth)"), std::string::npos)
            << m;
        EXPECT_NE(m.find("prevWorldToNDC"), std::string::npos) << m;
    }

    Frame split = raster::render_frame(
        scene,
        6,
        test::render_options(
            96, 54, {"color", "depth", "motion", "specular", "specular_motion", "diffuse_motion"}));
    split.set("alt", split.pass("diffuse_motion").image);
    const Image by_default = test::run_node("motion_blur", split, "{}", 6).image("color");
    const Image named_alt =
        test::run_node("motion_blur", split, R"({"motion_pass": "alt"})", 6).image("color");
    Image doubled = split.image("diffuse_motion");
    for (std::size_t i = 0; i < doubled.value_count(); ++i) {
        doubled.data()[i] *= 2.0f;
    }
    split.set("doubled", std::move(doubled));
    const Image named_motion =
        test::run_node("motion_blur", split, R"({"motion_pass": "doubled"})", 6).image("color");
    EXPECT_TRUE(named_alt.bit_equal(by_default));
    EXPECT_FALSE(named_motion.bit_equal(by_default));
    split.set("one", Image(96, 54, 1));
    EXPECT_THROW(test::run_node("motion_blur", split, R"({"motion_pass": "one"})", 6), Error);
}

}  // namespace
}  // namespace posthaste
