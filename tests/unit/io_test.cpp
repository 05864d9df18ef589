// EXR/PNG reading and writing: round trips of every pass in both part layouts and pixel types,
// metadata and matrices bit-exact, aliases for files written by another program (oiiotool with
// Blender, Nuke and Arnold channel names), data windows, integer channels, and bad input.

#include <Imath/half.h>
#include <OpenEXR/IlmThreadPool.h>
#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>

#include "core/error.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "io/color.h"
#include "io/image_file.h"
#include "io/mip_levels.h"
#include "io/sequence.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;
using test::make_sample_frame;
using test::run_command;
using test::scratch_dir;

float half_round(float v)
{
    return float(Imath::half(v));
}

void expect_pass_equal(const Frame &a, const Frame &b, const std::string &name, bool half)
{
    SCOPED_TRACE(name);
    const Image &x = a.image(name), &y = b.image(name);
    ASSERT_EQ(x.width(), y.width());
    ASSERT_EQ(x.channels(), y.channels());
    for (std::size_t i = 0; i < x.value_count(); ++i) {
        const float want = half ? half_round(x.data()[i]) : x.data()[i];
        ASSERT_EQ(want, y.data()[i]) << "value " << i;
    }
    EXPECT_EQ(a.pass(name).channels, b.pass(name).channels);
}

class RoundTrip : public ::testing::TestWithParam<std::tuple<bool, std::string>> {};

TEST_P(RoundTrip, EveryPassAndTheCameraComeBack)
{
    const auto [multipart, storage] = GetParam();
    const std::string dir = scratch_dir("roundtrip");
    Frame f = make_sample_frame(37, 21, 7);
    f.attributes.push_back(OIIO::ParamValue("scene", OIIO::ustring("unit test")));
    f.attributes.push_back(OIIO::ParamValue("exposureBias", 1.25f));
    f.camera.prev_world_to_camera = glm::mat4(1.0f);
    f.camera.prev_world_to_ndc = *f.camera.world_to_ndc * 1.5f;
    f.camera.near_clip = 0.1f;
    f.camera.far_clip = 1000.0f;
    WriteOptions o;
    o.multipart = multipart;
    if (storage != "auto") {
        for (const std::string &n : f.pass_names()) {
            o.storage[n] = storage == "half" ? PixelStorage::Half : PixelStorage::Float;
        }
    }
    const std::string path = dir + "/rt.exr";
    write_exr(f, path, o);
    const Frame g = read_frame(path, nullptr, 7);
    EXPECT_EQ(g.width(), 37);
    EXPECT_EQ(g.height(), 21);
    EXPECT_EQ(g.pass_names(), f.pass_names());
    for (const std::string &n : f.pass_names()) {
        const bool half =
            storage == "half" || (storage == "auto" && (n == "color" || n == "albedo"));
        expect_pass_equal(f, g, n, half);
    }
    EXPECT_EQ(g.camera, f.camera);  // matrices and lens, bit-exact
    const OIIO::ParamValue *scene = g.attributes.find_pv("scene");
    ASSERT_NE(scene, nullptr);
    EXPECT_EQ(scene->get_string(), "unit test");
    const OIIO::ParamValue *bias = g.attributes.find_pv("exposureBias");
    ASSERT_NE(bias, nullptr);
    EXPECT_EQ(bias->get_float(), 1.25f);
    // Written as asked: the file's own channel types, read by OIIO directly.
    const FileInfo info = read_file_info(path);
    EXPECT_EQ(info.parts.size(), multipart ? f.passes().size() : 1u);
    for (const FilePart &p : info.parts) {
        for (const FileChannel &c : p.channels) {
            const bool color_like = c.name.size() <= 1 || c.name.rfind("albedo.", 0) == 0;
            const std::string want =
                storage == "auto" ? (color_like && c.name != "Z" ? "half" : "float") : storage;
            EXPECT_EQ(c.type, want) << c.name;
        }
    }
    EXPECT_TRUE(fs::is_empty(dir) == false);
    for (const auto &e : fs::directory_iterator(dir)) {
        EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos)
            << "temporary left behind: " << e.path();
    }
}

INSTANTIATE_TEST_SUITE_P(Io,
                         RoundTrip,
                         ::testing::Combine(::testing::Bool(),
                                            ::testing::Values("auto", "half", "float")));

TEST(IoRead, OnlyRequestedPasses)
{
    const std::string dir = scratch_dir("requested");
    write_exr(make_sample_frame(8, 8, 1), dir + "/a.exr", {});
    const std::set<std::string> want = {"depth", "motion"};
    const Frame f = read_frame(dir + "/a.exr", &want, 1);
    EXPECT_EQ(f.pass_names(), (std::vector<std::string>{"depth", "motion"}));
    EXPECT_TRUE(std::isinf(f.image("depth").at(0, 0, 0)));
    EXPECT_EQ(f.image("motion").at(3, 3, 0), 2.0f);
    const std::set<std::string> missing = {"tangent"};
    try {
        read_frame(dir + "/a.exr", &missing, 1);
        FAIL();
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Runtime);
        EXPECT_NE(std::string(e.what()).find("no pass \"tangent\" in file (have: color, depth"),
                  std::string::npos)
            << e.what();
    }
}

TEST(IoRead, DataWindowIsKeptBesideTheDisplayWindow)
{
    const std::string dir = scratch_dir("datawindow");
    const std::string path = dir + "/dw.exr";
    ASSERT_EQ(run_command("oiiotool --pattern constant:color=1,0.5,0.25,1 16x8 4 --chnames R,G,B,A "
                          "--origin +4+2 --fullsize 32x16+0+0 -d float -o " +
                          path),
              0);
    const Frame f = read_frame(path, nullptr, 1);
    // The passes cover the data window; the display window is kept beside it.
    EXPECT_EQ(f.data_window, (Rect{4, 2, 20, 10}));
    EXPECT_EQ(f.display_window, (Rect{0, 0, 32, 16}));
    ASSERT_EQ(f.width(), 16);
    ASSERT_EQ(f.height(), 8);
    const Image &c = f.image("color");
    EXPECT_EQ(c.at(0, 0, 0), 1.0f);
    EXPECT_EQ(c.at(15, 7, 1), 0.5f);
    // Written back: the same windows (oiiotool's own reading as the independent check).
    write_exr(f, dir + "/dw_out.exr", {});
    std::string info;
    ASSERT_EQ(run_command("oiiotool --info -v " + dir + "/dw_out.exr", &info), 0);
    EXPECT_NE(info.find("16 x    8"), std::string::npos) << info;
    EXPECT_NE(info.find("pixel data origin: x=4, y=2"), std::string::npos) << info;
    EXPECT_NE(info.find("full/display size: 32 x 16"), std::string::npos) << info;
}

TEST(IoRead, UnsignedIntegerChannelsStayIntegers)
{
    const std::string dir = scratch_dir("uint");
    const std::string path = dir + "/id.exr";
    OIIO::ImageSpec spec(4, 2, 2, OIIO::TypeDesc::FLOAT);
    spec.channelnames = {"R", "id"};
    spec.channelformats = {OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::UINT};
    const std::vector<std::uint32_t> ids = {0, 1, 7, 255, 65536, 123456, 16777215, 3};
    // Native per-channel data (float R, uint id), exact.
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out->open(path, spec));
    struct Px {
        float r;
        std::uint32_t id;
    };
    std::vector<Px> px(8);
    for (int i = 0; i < 8; ++i) {
        px[std::size_t(i)] = {0.5f, ids[std::size_t(i)]};
    }
    ASSERT_TRUE(out->write_image(OIIO::TypeUnknown, px.data()));
    ASSERT_TRUE(out->close());
    const Frame f = read_frame(path, nullptr, 1);
    const Image &id = f.image("id");
    for (int i = 0; i < 8; ++i) {
        EXPECT_EQ(id.data()[i], float(ids[std::size_t(i)]));
    }
}

/// Make a single-part float file with the given channel names and one value per channel.
std::string make_named_file(const std::string &dir,
                            const std::string &name,
                            const std::vector<std::string> &channels,
                            const std::vector<float> &values)
{
    std::string names, vals;
    for (std::size_t i = 0; i < channels.size(); ++i) {
        if (i > 0) {
            names += ",";
            vals += ",";
        }
        names += channels[i];
        vals += std::to_string(values[i]);
    }
    const std::string path = dir + "/" + name;
    const std::string cmd = "oiiotool --pattern constant:color=" + vals + " 6x4 " +
                            std::to_string(channels.size()) + " --chnames " + names +
                            " -d float -o " + path;
    EXPECT_EQ(run_command(cmd), 0) << cmd;
    return path;
}

TEST(IoAliases, BlenderMultilayerNames)
{
    const std::string dir = scratch_dir("blender");
    const std::string path = make_named_file(dir,
                                             "blender.exr",
                                             {"ViewLayer.Combined.R",
                                              "ViewLayer.Combined.G",
                                              "ViewLayer.Combined.B",
                                              "ViewLayer.Combined.A",
                                              "ViewLayer.Depth.Z",
                                              "ViewLayer.Vector.X",
                                              "ViewLayer.Vector.Y",
                                              "ViewLayer.Vector.Z",
                                              "ViewLayer.Vector.W",
                                              "ViewLayer.Normal.X",
                                              "ViewLayer.Normal.Y",
                                              "ViewLayer.Normal.Z",
                                              "ViewLayer.Position.X",
                                              "ViewLayer.Position.Y",
                                              "ViewLayer.Position.Z",
                                              "ViewLayer.DiffCol.R",
                                              "ViewLayer.DiffCol.G",
                                              "ViewLayer.DiffCol.B"},
                                             {0.1f,
                                              0.2f,
                                              0.3f,
                                              1.0f,
                                              5.5f,
                                              3.0f,
                                              4.0f,
                                              7.0f,
                                              8.0f,
                                              0.0f,
                                              1.0f,
                                              0.0f,
                                              1.0f,
                                              2.0f,
                                              3.0f,
                                              0.6f,
                                              0.5f,
                                              0.4f});
    const Frame f = read_frame(path, nullptr, 1);
    EXPECT_FLOAT_EQ(f.image("color").at(2, 2, 1), 0.2f);
    EXPECT_FLOAT_EQ(f.image("depth").at(2, 2, 0), 5.5f);
    // Blender: X,Y = previous - current with y up; posthaste: current - previous with y down.
    EXPECT_FLOAT_EQ(f.image("motion").at(2, 2, 0), -3.0f);
    EXPECT_FLOAT_EQ(f.image("motion").at(2, 2, 1), 4.0f);
    EXPECT_FLOAT_EQ(f.image("motion_next").at(2, 2, 0), -7.0f);
    EXPECT_FLOAT_EQ(f.image("motion_next").at(2, 2, 1), 8.0f);
    EXPECT_FLOAT_EQ(f.image("normal").at(2, 2, 1), 1.0f);
    EXPECT_FLOAT_EQ(f.image("position").at(2, 2, 2), 3.0f);
    EXPECT_FLOAT_EQ(f.image("albedo").at(2, 2, 0), 0.6f);
    EXPECT_EQ(f.pass("motion").channels, (std::vector<std::string>{"X", "Y"}));

    // Any view-layer name; Blender's sky depth 1e10 becomes +inf.
    const std::string sky = make_named_file(dir, "sky.exr", {"Foo.Depth.Z"}, {1e10f});
    EXPECT_TRUE(std::isinf(read_frame(sky, nullptr, 1).image("depth").at(0, 0, 0)));
}

TEST(IoAliases, BlenderShaderAovsAreAlbedoAndMaterial)
{
    // Blender writes no base colour, roughness or metallic: shader AOVs named albedo (colour),
    // roughness and metallic (values) are read as albedo and material (anisotropy 0), the AOV
    // albedo before DiffCol (black on a metal).
    const std::string dir = scratch_dir("blender_aovs");
    const std::string path =
        make_named_file(dir,
                        "aovs.exr",
                        {"ViewLayer.Combined.R",
                         "ViewLayer.Combined.G",
                         "ViewLayer.Combined.B",
                         "ViewLayer.DiffCol.R",
                         "ViewLayer.DiffCol.G",
                         "ViewLayer.DiffCol.B",
                         "ViewLayer.albedo.R",
                         "ViewLayer.albedo.G",
                         "ViewLayer.albedo.B",
                         "ViewLayer.albedo.A",
                         "ViewLayer.metallic.X",
                         "ViewLayer.roughness.X"},
                        {0.1f, 0.2f, 0.3f, 0.0f, 0.0f, 0.0f, 0.9f, 0.8f, 0.7f, 1.0f, 1.0f, 0.25f});
    const Frame f = read_frame(path, nullptr, 1);
    EXPECT_FLOAT_EQ(f.image("albedo").at(1, 1, 0), 0.9f);
    EXPECT_FLOAT_EQ(f.image("albedo").at(1, 1, 2), 0.7f);
    ASSERT_EQ(f.image("material").channels(), 3);
    EXPECT_FLOAT_EQ(f.image("material").at(1, 1, 0), 0.25f);
    EXPECT_FLOAT_EQ(f.image("material").at(1, 1, 1), 1.0f);
    EXPECT_FLOAT_EQ(f.image("material").at(1, 1, 2), 0.0f);
    // Without the AOVs DiffCol is the albedo, and there is no material pass.
    const std::string plain = make_named_file(dir,
                                              "plain.exr",
                                              {"ViewLayer.Combined.R",
                                               "ViewLayer.Combined.G",
                                               "ViewLayer.Combined.B",
                                               "ViewLayer.DiffCol.R",
                                               "ViewLayer.DiffCol.G",
                                               "ViewLayer.DiffCol.B",
                                               "ViewLayer.roughness.X"},
                                              {0.1f, 0.2f, 0.3f, 0.6f, 0.5f, 0.4f, 0.3f});
    const Frame g = read_frame(plain, nullptr, 1);
    EXPECT_FLOAT_EQ(g.image("albedo").at(1, 1, 0), 0.6f);
    EXPECT_FALSE(g.has("material"));  // roughness alone: the rule needs metallic too
}

TEST(IoAliases, NukeNames)
{
    const std::string dir = scratch_dir("nuke");
    const std::string path = make_named_file(
        dir,
        "nuke.exr",
        {"R", "G", "B", "depth.Z", "backward.u", "backward.v", "forward.u", "forward.v"},
        {0.5f, 0.5f, 0.5f, 12.0f, 1.5f, -2.0f, 3.0f, 4.0f});
    const Frame f = read_frame(path, nullptr, 1);
    EXPECT_FLOAT_EQ(f.image("color").at(0, 0, 3), 1.0f);  // no alpha: A = 1
    EXPECT_FLOAT_EQ(f.image("depth").at(0, 0, 0), 12.0f);
    EXPECT_FLOAT_EQ(f.image("motion").at(0, 0, 0), -1.5f);
    EXPECT_FLOAT_EQ(f.image("motion").at(0, 0, 1), -2.0f);
    EXPECT_FLOAT_EQ(f.image("motion_next").at(0, 0, 0), 3.0f);
    EXPECT_FLOAT_EQ(f.image("motion_next").at(0, 0, 1), -4.0f);
}

TEST(IoAliases, ArnoldNamesAndGraphRules)
{
    const std::string dir = scratch_dir("arnold");
    const std::string path = make_named_file(dir,
                                             "arnold.exr",
                                             {"R",
                                              "G",
                                              "B",
                                              "A",
                                              "Z",
                                              "N.R",
                                              "N.G",
                                              "N.B",
                                              "P.R",
                                              "P.G",
                                              "P.B",
                                              "motionvector.R",
                                              "motionvector.G",
                                              "zdepth.Z"},
                                             {1, 1, 1, 1, 9, 0, 0, 1, 4, 5, 6, 2.5f, 1.5f, 0.25f});
    const Frame f = read_frame(path, nullptr, 1);
    EXPECT_FLOAT_EQ(f.image("depth").at(0, 0, 0), 9.0f);
    EXPECT_FLOAT_EQ(f.image("normal").at(0, 0, 2), 1.0f);
    EXPECT_FLOAT_EQ(f.image("position").at(0, 0, 1), 5.0f);
    EXPECT_FLOAT_EQ(f.image("motion").at(0, 0, 0), 2.5f);
    EXPECT_FLOAT_EQ(f.image("motion").at(0, 0, 1), -1.5f);
    EXPECT_TRUE(f.has("zdepth"));  // unknown layer kept under its own name

    // A graph's own rule wins over the built-in ones: depth from zdepth.Z, as 1/value.
    ReadOptions o;
    o.aliases = parse_alias_rules(R"([{"pass": "depth", "channels": ["zdepth.Z"],
                                       "scale": [4], "offset": [1]}])",
                                  "test");
    const Frame g = read_frame(path, nullptr, 1, o);
    EXPECT_FLOAT_EQ(g.image("depth").at(0, 0, 0), 2.0f);
    EXPECT_TRUE(g.has("Z"));  // the unused Z channel stays available as its own pass
    EXPECT_THROW(parse_alias_rules(R"([{"pass": "depth"}])", "test"), Error);
    EXPECT_THROW(parse_alias_rules(R"([{"pass": "depth", "channels": ["a"], "scal": [1]}])", "t"),
                 Error);
}

/// The message of the Error `fn` throws ("" if none).
template <typename Fn>
std::string error_of(Fn &&fn)
{
    try {
        fn();
    } catch (const Error &e) {
        return e.what();
    }
    return {};
}

TEST(IoAliases, VRayRedshiftUnrealKarmaRenderManNames)
{
    const std::string dir = scratch_dir("renderers");
    // V-Ray: VRayDiffuseFilter is albedo; Redshift: DiffuseFilter.red.., P.red.., N.red...
    const std::string vray = make_named_file(
        dir,
        "vray.exr",
        {"R", "G", "B", "A", "VRayDiffuseFilter.R", "VRayDiffuseFilter.G", "VRayDiffuseFilter.B"},
        {1, 1, 1, 1, 0.7f, 0.6f, 0.5f});
    const Frame v = read_frame(vray, nullptr, 1);
    EXPECT_FLOAT_EQ(v.image("albedo").at(1, 1, 1), 0.6f);
    const std::string redshift = make_named_file(dir,
                                                 "redshift.exr",
                                                 {"R",
                                                  "G",
                                                  "B",
                                                  "Z",
                                                  "P.red",
                                                  "P.green",
                                                  "P.blue",
                                                  "N.red",
                                                  "N.green",
                                                  "N.blue",
                                                  "DiffuseFilter.red",
                                                  "DiffuseFilter.green",
                                                  "DiffuseFilter.blue"},
                                                 {1, 1, 1, 7, 1, 2, 3, 0, 0, -1, 0.2f, 0.3f, 0.4f});
    const Frame r = read_frame(redshift, nullptr, 1);
    EXPECT_FLOAT_EQ(r.image("depth").at(0, 0, 0), 7.0f);
    EXPECT_FLOAT_EQ(r.image("position").at(0, 0, 2), 3.0f);
    EXPECT_FLOAT_EQ(r.image("normal").at(0, 0, 2), -1.0f);
    EXPECT_FLOAT_EQ(r.image("albedo").at(0, 0, 0), 0.2f);
    // Unreal MRQ: WorldDepth in centimetres (R) -> metres; a saturated half (65504 cm) is sky.
    const std::string unreal = make_named_file(dir,
                                               "unreal.exr",
                                               {"R",
                                                "G",
                                                "B",
                                                "A",
                                                "FinalImageMovieRenderQueue_WorldDepth.R",
                                                "FinalImageMovieRenderQueue_WorldDepth.G",
                                                "FinalImageMovieRenderQueue_WorldDepth.B"},
                                               {1, 1, 1, 1, 1250.0f, 0, 0});
    EXPECT_FLOAT_EQ(read_frame(unreal, nullptr, 1).image("depth").at(0, 0, 0), 12.5f);
    const std::string unreal_sky = make_named_file(
        dir, "unreal_sky.exr", {"FinalImageMovieRenderQueue_WorldDepth.R"}, {65504});
    EXPECT_TRUE(std::isinf(read_frame(unreal_sky, nullptr, 1).image("depth").at(0, 0, 0)));
    // Karma: C is the beauty, Pz the depth.
    const std::string karma = make_named_file(
        dir, "karma.exr", {"C.R", "C.G", "C.B", "C.A", "Pz"}, {0.25f, 0.5f, 0.75f, 1, 3.5f});
    const Frame k = read_frame(karma, nullptr, 1);
    EXPECT_FLOAT_EQ(k.image("color").at(0, 0, 2), 0.75f);
    EXPECT_FLOAT_EQ(k.image("depth").at(0, 0, 0), 3.5f);
    // RenderMan: z, __Nworld, __Pworld (Nn and P are camera space).
    const std::string rman = make_named_file(dir,
                                             "rman.exr",
                                             {"R",
                                              "G",
                                              "B",
                                              "z",
                                              "__Nworld.r",
                                              "__Nworld.g",
                                              "__Nworld.b",
                                              "__Pworld.r",
                                              "__Pworld.g",
                                              "__Pworld.b"},
                                             {1, 1, 1, 4.25f, 0, 1, 0, -1, -2, -3});
    const Frame m = read_frame(rman, nullptr, 1);
    EXPECT_FLOAT_EQ(m.image("depth").at(0, 0, 0), 4.25f);
    EXPECT_FLOAT_EQ(m.image("normal").at(0, 0, 1), 1.0f);
    EXPECT_FLOAT_EQ(m.image("position").at(0, 0, 0), -1.0f);
    // Asked for one renderer's names, the others' are not recognised (canonical ones still are).
    ReadOptions only_vray;
    only_vray.convention = "vray";
    const FileInfo kv = read_file_info(karma, only_vray);
    EXPECT_FALSE(std::any_of(
        kv.passes.begin(), kv.passes.end(), [](const PassSource &p) { return p.pass == "depth"; }));
    ReadOptions only_karma;
    only_karma.convention = "karma";
    EXPECT_FLOAT_EQ(read_frame(karma, nullptr, 1, only_karma).image("depth").at(0, 0, 0), 3.5f);
    for (const auto &[file, convention] :
         std::vector<std::pair<std::string, std::string>>{{redshift, "Redshift"},
                                                          {unreal, "Unreal MRQ"},
                                                          {karma, "Karma"},
                                                          {rman, "RenderMan"}}) {
        bool named = false;
        for (const PassSource &ps : read_file_info(file).passes) {
            named = named || ps.origin == convention;
        }
        EXPECT_TRUE(named) << file << " " << convention;
    }
}

TEST(IoAliases, AmbiguousConventionsAreRefusedWithWhatToSet)
{
    const std::string dir = scratch_dir("refused");
    // V-Ray's default Z-depth is normalised: no depth pass, and asking for one says what to set.
    const std::string vray =
        make_named_file(dir,
                        "vray.exr",
                        {"R", "G", "B", "VRayZDepth.R", "VRayVelocity.X", "VRayVelocity.Y"},
                        {1, 1, 1, 0.5f, 0.5f, 0.5f});
    const FileInfo vi = read_file_info(vray);
    EXPECT_FALSE(std::any_of(vi.passes.begin(), vi.passes.end(), [](const PassSource &p) {
        return p.pass == "depth" || p.pass == "motion";
    }));
    EXPECT_TRUE(std::any_of(vi.passes.begin(), vi.passes.end(), [](const PassSource &p) {
        return p.pass == "VRayZDepth";  // still passes through under its own name
    }));
    const std::set<std::string> depth = {"depth"};
    std::string what = error_of([&] { read_frame(vray, &depth, 1); });
    EXPECT_NE(what.find("vray.exr: no pass \"depth\""), std::string::npos) << what;
    EXPECT_NE(what.find("VRayZDepth.R is V-Ray's Z-depth, normalised by default"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("Clamp and Filtering off, Black 0 and White 1"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos);
    const std::set<std::string> motion = {"motion"};
    what = error_of([&] { read_frame(vray, &motion, 1); });
    EXPECT_NE(what.find("from this frame to the next"), std::string::npos) << what;
    // Unreal's screen-normalised vectors: the suggested alias carries this file's size.
    const std::string unreal = make_named_file(dir,
                                               "unreal.exr",
                                               {"R",
                                                "G",
                                                "B",
                                                "FinalImageMovieRenderQueue_MotionVectors.R",
                                                "FinalImageMovieRenderQueue_MotionVectors.G"},
                                               {1, 1, 1, 0.5f, 0.5f});
    what = error_of([&] { read_frame(unreal, &motion, 1); });
    EXPECT_NE(what.find("\"scale\": [6, -4], \"offset\": [-3, 2]} (this file is 6x4"),
              std::string::npos)
        << what;
    // Following the advice works: the graph alias makes the pass (0.75 -> +1.5 px right).
    ReadOptions o;
    o.aliases = parse_alias_rules(
        R"([{"pass": "motion", "channels": ["FinalImageMovieRenderQueue_MotionVectors.R",
             "FinalImageMovieRenderQueue_MotionVectors.G"], "scale": [6, -4], "offset": [-3, 2]}])",
        "test");
    const std::string moved = make_named_file(dir,
                                              "moved.exr",
                                              {"FinalImageMovieRenderQueue_MotionVectors.R",
                                               "FinalImageMovieRenderQueue_MotionVectors.G"},
                                              {0.75f, 0.5f});
    EXPECT_FLOAT_EQ(read_frame(moved, &motion, 1, o).image("motion").at(0, 0, 0), 1.5f);
    // Redshift's encoded vectors and RenderMan's camera-space Nn.
    const std::string rs = make_named_file(dir,
                                           "rs.exr",
                                           {"R", "G", "B", "MotionVectors.R", "MotionVectors.G"},
                                           {1, 1, 1, 0.5f, 0.5f});
    what = error_of([&] { read_frame(rs, &motion, 1); });
    EXPECT_NE(what.find("Output Raw Vectors on"), std::string::npos) << what;
    const std::string rman = make_named_file(
        dir, "rman.exr", {"R", "G", "B", "Nn.x", "Nn.y", "Nn.z"}, {1, 1, 1, 0, 0, 1});
    const std::set<std::string> normal = {"normal"};
    what = error_of([&] { read_frame(rman, &normal, 1); });
    EXPECT_NE(what.find("output __Nworld"), std::string::npos) << what;
    // A file without such channels says nothing more than before.
    const std::string plain = make_named_file(dir, "plain.exr", {"R", "G", "B"}, {1, 1, 1});
    what = error_of([&] { read_frame(plain, &depth, 1); });
    EXPECT_EQ(what, plain + ": no pass \"depth\" in file (have: color)");
}

TEST(IoRead, MultipartWithBareChannelNames)
{
    const std::string dir = scratch_dir("multipart");
    const std::string path = dir + "/mp.exr";
    OIIO::ImageSpec specs[2] = {OIIO::ImageSpec(4, 4, 4, OIIO::TypeDesc::HALF),
                                OIIO::ImageSpec(4, 4, 3, OIIO::TypeDesc::FLOAT)};
    specs[0].channelnames = {"R", "G", "B", "A"};
    specs[0].attribute("name", "rgba");
    specs[1].channelnames = {"X", "Y", "Z"};
    specs[1].attribute("name", "N");
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out->open(path, 2, specs));
    std::vector<float> rgba(64, 0.25f), n(48, 0.0f);
    for (int i = 0; i < 16; ++i) {
        n[std::size_t(i) * 3 + 2] = 1.0f;
    }
    ASSERT_TRUE(out->write_image(OIIO::TypeFloat, rgba.data()));
    ASSERT_TRUE(out->open(path, specs[1], OIIO::ImageOutput::AppendSubimage));
    ASSERT_TRUE(out->write_image(OIIO::TypeFloat, n.data()));
    ASSERT_TRUE(out->close());
    const Frame f = read_frame(path, nullptr, 1);
    EXPECT_FLOAT_EQ(f.image("color").at(1, 1, 2), 0.25f);
    EXPECT_FLOAT_EQ(f.image("normal").at(1, 1, 2), 1.0f);
}

TEST(IoBadInput, TruncatedEmptyMisnamedAndMissing)
{
    const std::string dir = scratch_dir("badinput");
    write_exr(make_sample_frame(64, 64, 1), dir + "/good.exr", {});
    const auto size = fs::file_size(dir + "/good.exr");
    fs::copy_file(dir + "/good.exr", dir + "/truncated.exr");
    fs::resize_file(dir + "/truncated.exr", size / 2);
    std::ofstream(dir + "/empty.exr").close();
    std::ofstream(dir + "/text.exr") << "this is not an image\n";
    ASSERT_EQ(run_command("oiiotool --pattern constant:color=0.5,0.5,0.5 8x8 3 -d uint8 -o " + dir +
                          "/png.png"),
              0);
    fs::copy_file(dir + "/png.png", dir + "/png_named.exr");

    for (const char *name : {"truncated.exr", "empty.exr", "text.exr", "missing.exr"}) {
        SCOPED_TRACE(name);
        try {
            read_frame(dir + "/" + name, nullptr, 1);
            FAIL() << "no error";
        } catch (const Error &e) {
            EXPECT_EQ(e.code(), ExitCode::Runtime);
            EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
        }
    }
    // A PNG with an .exr name: either read as what it is, or a clear error; never a crash.
    try {
        const Frame f = read_frame(dir + "/png_named.exr", nullptr, 1);
        EXPECT_NEAR(f.image("color").at(0, 0, 0), 0.214f, 0.002f);  // sRGB 128/255 decoded
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("png_named.exr"), std::string::npos);
    }
}

TEST(IoBadInput, HeaderAttributeLargerThanTheFile)
{
    // OpenEXR allocates an attribute's claimed size before reading it; posthaste walks the header
    // first, so a small file claiming a 2 GB attribute is a one-line error, not a 2 GB allocation.
    const std::string dir = scratch_dir("bigattr");
    const std::string path = dir + "/bigattr.exr";
    {
        OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::HALF);
        spec.attribute("comment", "a comment");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(48, 0.5f);
        ASSERT_TRUE(out->write_image(OIIO::TypeFloat, px.data()));
        ASSERT_TRUE(out->close());
    }
    EXPECT_NO_THROW(read_frame(path, nullptr, 1));
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string key("comment\0string\0", 15);
    const auto at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const unsigned char claim[4] = {0x00, 0x00, 0x00, 0x7f};  // 2,130,706,432 bytes
    bytes.replace(at + key.size(), 4, reinterpret_cast<const char *>(claim), 4);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    try {
        read_frame(path, nullptr, 1);
        FAIL() << "no error";
    } catch (const Error &e) {
        const std::string what = e.what();
        EXPECT_EQ(e.code(), ExitCode::Runtime);
        EXPECT_NE(what.find("bigattr.exr"), std::string::npos) << what;
        EXPECT_NE(what.find("\"comment\" claims 2130706432 bytes"), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
    EXPECT_NE(verify_image_file(path), "");
}

TEST(IoBadInput, HugeDataWindowIsRefusedBeforeOpenEXRAllocatesIt)
{
    // A 4x4 file whose header claims a data window 1,000,000,000 pixels wide: OpenEXR would
    // allocate its line buffers for that width when opening the file. Under a budget the header
    // walk refuses it first, naming the part and the estimate.
    const std::string dir = scratch_dir("hugewindow");
    const std::string path = dir + "/huge.exr";
    {
        OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::HALF);
        spec.attribute("compression", "zip");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(48, 0.5f);
        ASSERT_TRUE(out->write_image(OIIO::TypeFloat, px.data()));
        ASSERT_TRUE(out->close());
    }
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string key("dataWindow\0box2i\0\x10\0\0\0", 21);
    const auto at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const std::int32_t x_max = 999999999;
    bytes.replace(at + key.size() + 8, 4, reinterpret_cast<const char *>(&x_max), 4);
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    const std::size_t saved = image_memory_budget();
    set_image_memory_budget(std::size_t(64) << 20);
    try {
        read_frame(path, nullptr, 1);
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("huge.exr: part 0: opening it would take"), std::string::npos) << what;
        EXPECT_NE(what.find("(data window 1000000000x4)"), std::string::npos) << what;
    }
    set_image_memory_budget(saved);
}

TEST(IoBadInput, HugeTilesAndMisreadHeadersAreRefusedBeforeOpenEXRAllocates)
{
    // Found by fuzz_exr_read: a 4 KB tiled file whose header claims 23824x2048 tiles (780 MB of
    // tile buffer) and has lost its dataWindow (OpenEXR then assumes 64x64). The walk reads the
    // header as OpenEXR does (fixed-size types by their own size, the channel list up to its
    // empty name), so it sees the same tiles and refuses them under the budget.
    const std::string dir = scratch_dir("hugetiles");
    const std::string path = dir + "/tiles.exr";
    {
        OIIO::ImageSpec spec(16, 16, 4, OIIO::TypeDesc::FLOAT);
        spec.tile_width = 16;
        spec.tile_height = 16;
        spec.attribute("compression", "zips");
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out->open(path, spec));
        std::vector<float> px(16 * 16 * 4, 0.5f);
        ASSERT_TRUE(out->write_image(OIIO::TypeFloat, px.data()));
        ASSERT_TRUE(out->close());
    }
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string tiles("tiles\0tiledesc\0\x09\0\0\0", 19);
    const auto at = bytes.find(tiles);
    ASSERT_NE(at, std::string::npos);
    const std::int32_t size[2] = {23824, 2048};
    bytes.replace(at + tiles.size(), 8, reinterpret_cast<const char *>(size), 8);
    const auto dw = bytes.find("dataWindow");
    ASSERT_NE(dw, std::string::npos);
    bytes.replace(dw, 10, "dataWnullw");
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    const std::size_t saved = image_memory_budget();
    set_image_memory_budget(std::size_t(64) << 20);
    std::string what;
    try {
        read_frame(path, nullptr, 1);
    } catch (const Error &e) {
        what = e.what();
    }
    EXPECT_NE(what.find("tiles.exr: part 0: opening it would take 2978 MiB"), std::string::npos)
        << what;
    EXPECT_NE(verify_image_file(path), "");
    set_image_memory_budget(saved);
}

TEST(IoBadInput, FuzzFindingsAreOneLineErrors)
{
    // Inputs fuzz_exr_read found (kept in its seed corpus): OpenImageIO 2.4 aborted the process
    // on a channel of pixel type 3; a 300-byte file with a 2^30-line data window made OpenEXR
    // allocate a 1 GB offset table (2.3 GB resident).
    const std::string corpus = std::string(POSTHASTE_TEST_DIR) + "/fuzz/corpus/exr_read/";
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"crash_unknown_pixel_type.exr", "has pixel type"},
        {"oom_offset_table.exr", "chunk offsets (1073741928 bytes), more than the"},
        {"slow_huge_tiles_no_data_window.exr", "opening it would take"}};
    const std::size_t saved = image_memory_budget();
    set_image_memory_budget(std::size_t(256) << 20);
    for (const auto &[file, expected] : cases) {
        SCOPED_TRACE(file);
        std::string what;
        try {
            read_frame(corpus + file, nullptr, 1);
        } catch (const Error &e) {
            what = e.what();
        }
        EXPECT_NE(what.find(file), std::string::npos) << what;
        EXPECT_NE(what.find(expected), std::string::npos) << what;
        EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    }
    set_image_memory_budget(saved);
}

TEST(IoBadInput, NanAndInfPixels)
{
    const std::string dir = scratch_dir("nan");
    Frame f = make_sample_frame(8, 8, 1);
    Image color = f.image("color");
    color.at(3, 4, 1) = std::numeric_limits<float>::quiet_NaN();
    color.at(5, 5, 0) = std::numeric_limits<float>::infinity();
    f.set("color", std::move(color));
    // A reflection of the sky is as far as the sky: +inf in specular_depth is no bad value either.
    f.set("specular_depth", f.pass("depth").image);
    WriteOptions o;
    o.storage["color"] = PixelStorage::Float;
    write_exr(f, dir + "/nan.exr", o);

    ReadOptions keep;
    std::map<std::string, std::size_t> counts;
    const Frame k = read_frame(dir + "/nan.exr", nullptr, 1, keep, &counts);
    EXPECT_TRUE(std::isnan(k.image("color").at(3, 4, 1)));
    EXPECT_TRUE(std::isinf(k.image("depth").at(0, 0, 0)));  // sky depth is legitimate
    EXPECT_TRUE(std::isinf(k.image("specular_depth").at(0, 0, 0)));
    // The per-frame report: two values in color, none in the depths (+inf is the sky).
    EXPECT_EQ(counts, (std::map<std::string, std::size_t>{{"color", 2}}));
    // Through a graph: one warning line for the frame.
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")"
                                   << dir << R"(/nan.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "in"},
         "params": {"path": ")" << dir
                                   << R"(/out.exr"}}]})";
    std::string log;
    EXPECT_EQ(run_command(std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --quiet", &log),
              0);
    EXPECT_NE(log.find("NaN or infinite values kept: color 2 (bad_pixels"), std::string::npos)
        << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;

    ReadOptions zero;
    zero.bad_pixels = BadPixels::Zero;
    const Frame z = read_frame(dir + "/nan.exr", nullptr, 1, zero);
    EXPECT_EQ(z.image("color").at(3, 4, 1), 0.0f);
    EXPECT_EQ(z.image("color").at(5, 5, 0), 0.0f);
    EXPECT_TRUE(std::isinf(z.image("depth").at(0, 0, 0)));
    EXPECT_TRUE(std::isinf(z.image("specular_depth").at(0, 0, 0)));

    ReadOptions error;
    error.bad_pixels = BadPixels::Error;
    try {
        read_frame(dir + "/nan.exr", nullptr, 1, error);
        FAIL();
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("channel \"G\" has a NaN or infinite value at (3, 4)"),
                  std::string::npos)
            << e.what();
    }
}

TEST(IoWrite, CompressionNamesAreValidated)
{
    EXPECT_NO_THROW(check_compression("piz", "x"));
    EXPECT_NO_THROW(check_compression("dwaa:45", "x"));
    EXPECT_NO_THROW(check_compression("zip:6", "x"));
    EXPECT_THROW(check_compression("zipp", "x"), Error);
    EXPECT_THROW(check_compression("piz:3", "x"), Error);
    EXPECT_THROW(check_compression("dwaa:abc", "x"), Error);

    const std::string dir = scratch_dir("lossy");
    const Frame f = make_sample_frame(8, 8, 1);
    WriteOptions o;
    o.compression = "dwaa";
    try {
        write_exr(f, dir + "/a.exr", o);
        FAIL();
    } catch (const Error &e) {
        EXPECT_EQ(e.code(), ExitCode::Usage);
        EXPECT_NE(std::string(e.what()).find("lossy on data pass \"depth\""), std::string::npos);
    }
    EXPECT_FALSE(fs::exists(dir + "/a.exr"));
    o.passes = {"color"};
    EXPECT_NO_THROW(write_exr(f, dir + "/b.exr", o));  // lossy color is the user's choice
    o.passes = {};
    o.allow_lossy_data = true;
    EXPECT_NO_THROW(write_exr(f, dir + "/c.exr", o));
}

TEST(IoWrite, CompressesOnTheJobsThreadsAndGivesTheSameBytes)
{
    // A frame that read no EXR (a render) still compresses on the threads the job has, and the
    // file's bytes do not depend on how many.
    const std::string dir = scratch_dir("write_threads");
    const Frame f = make_sample_frame(300, 200, 3);
    const int before = thread_count();
    std::string bytes[2];
    for (int threads : {1, 2}) {
        set_thread_count(threads);
        const std::string path = dir + "/t" + std::to_string(threads) + ".exr";
        write_exr(f, path, {});
        EXPECT_EQ(IlmThread::ThreadPool::globalThreadPool().numThreads(), threads);
        bytes[threads - 1] = test::read_bytes(path);
    }
    set_thread_count(before);
    EXPECT_FALSE(bytes[0].empty());
    EXPECT_EQ(bytes[0], bytes[1]);
}

TEST(IoWrite, FailedWriteLeavesNothingBehind)
{
    const std::string dir = scratch_dir("atomic");
    const Frame f = make_sample_frame(8, 8, 1);
    WriteOptions o;
    o.passes = {"color", "no_such_pass"};
    EXPECT_THROW(write_exr(f, dir + "/sub/x.exr", o), Error);
    EXPECT_THROW(atomic_write(dir + "/y.exr",
                              [](const std::string &tmp) {
                                  std::ofstream(tmp) << "partial";
                                  throw_runtime("simulated failure");
                              }),
                 Error);
    for (const auto &e : fs::recursive_directory_iterator(dir)) {
        EXPECT_FALSE(e.is_regular_file()) << "left behind: " << e.path();
    }
    // An existing file is replaced only once the new one is complete.
    std::ofstream(dir + "/z.exr") << "old";
    EXPECT_THROW(atomic_write(dir + "/z.exr", [](const std::string &) { throw_runtime("no"); }),
                 Error);
    std::ifstream in(dir + "/z.exr");
    std::string content;
    in >> content;
    EXPECT_EQ(content, "old");
}

TEST(IoSequence, PatternsExpandAndScan)
{
    EXPECT_EQ(expand_frame_pattern("a.####.exr", 12), "a.0012.exr");
    EXPECT_EQ(expand_frame_pattern("a.#.exr", 12), "a.12.exr");
    EXPECT_EQ(expand_frame_pattern("a.@@@.exr", 7), "a.007.exr");
    EXPECT_EQ(expand_frame_pattern("a.%04d.exr", 5), "a.0005.exr");
    EXPECT_EQ(expand_frame_pattern("a.%d.exr", 5), "a.5.exr");
    EXPECT_EQ(expand_frame_pattern("a.####.exr", 123456), "a.123456.exr");
    EXPECT_EQ(expand_frame_pattern("a.####.exr", -3), "a.-0003.exr");
    EXPECT_EQ(expand_frame_pattern("still.exr", 3), "still.exr");
    EXPECT_FALSE(has_frame_placeholder("still.exr"));

    const std::string dir = scratch_dir("scan");
    for (const char *n : {"s.0001.exr", "s.0002.exr", "s.0010.exr", "s.tmp.exr", "s.01.exr"}) {
        std::ofstream(dir + "/" + n) << "x";
    }
    EXPECT_EQ(find_frames_on_disk(dir + "/s.####.exr"), (std::vector<int>{1, 2, 10}));
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

TEST(IoWrite, HalfConversionRoundsLikeImath)
{
    // Ties, denormals, the largest half, overflow to inf, negative zero, NaN-free extremes.
    const float values[] = {0.0f,
                            -0.0f,
                            1.0f,
                            1.0f + 1.0f / 2048.0f,
                            1.0f + 3.0f / 2048.0f,
                            0.1f,
                            1e-5f,
                            6e-8f,
                            3e-8f,
                            65504.0f,
                            65519.0f,
                            65520.0f,
                            1e6f,
                            -1e6f,
                            -0.333333f,
                            2.5e-4f,
                            1234.5678f};
    const int n = int(sizeof(values) / sizeof(values[0]));
    Frame f;
    Image color(n, 1, 4);
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 4; ++c) {
            color.at(i, 0, c) = values[(i + c) % n];
        }
    }
    f.set("color", color);
    Image albedo(n, 1, 3);  // three channels: the non-vector conversion path
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
            albedo.at(i, 0, c) = values[(i + 2 * c) % n];
        }
    }
    f.set("albedo", albedo);
    const std::string dir = scratch_dir("half_round");
    write_exr(f, dir + "/h.exr", {});
    const Frame g = read_frame(dir + "/h.exr", nullptr, 1);
    for (const char *pass : {"color", "albedo"}) {
        const Image &a = f.image(pass), &b = g.image(pass);
        for (std::size_t i = 0; i < a.value_count(); ++i) {
            const float want = float(Imath::half(a.data()[i]));
            EXPECT_EQ(std::memcmp(&want, &b.data()[i], 4), 0)
                << pass << " value " << a.data()[i] << " -> " << b.data()[i] << " want " << want;
        }
    }
}

// Half storage turns finite values of 65520 and beyond into infinity; the write says so, naming
// the channels, instead of doing it silently. Counted by hand: color (the four-channel vector
// path) 65520, -70000, 1e38 and -65520, albedo (the per-channel path) 70000; 65519 rounds to
// 65504, and infinities and NaN were not finite to begin with. Float storage keeps them all.
TEST(IoWrite, HalfOverflowIsToldNamingTheChannels)
{
    const float inf = std::numeric_limits<float>::infinity();
    Frame f;
    Image color(2, 1, 4);
    const float cv[8] = {65519.0f, 65520.0f, -70000.0f, inf, std::nanf(""), 1e38f, 1.0f, -65520.0f};
    std::copy(cv, cv + 8, color.data());
    f.set("color", color);
    Image albedo(2, 1, 3);
    const float av[6] = {70000.0f, 1.0f, 2.0f, inf, -inf, 65504.0f};
    std::copy(av, av + 6, albedo.data());
    f.set("albedo", albedo);
    Image depth(2, 1, 1);
    depth.fill(1e6f);
    f.set("depth", depth);
    const std::string dir = scratch_dir("half_overflow");
    std::vector<std::string> lines;
    WriteOptions o;
    o.warn = [&](const std::string &line) { lines.push_back(line); };
    write_exr(f, dir + "/h.exr", o);
    ASSERT_EQ(lines.size(), 1u);
    EXPECT_NE(lines[0].find("beyond half's range (65504)"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("R, G, B, A"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("albedo.R, albedo.G, albedo.B"), std::string::npos) << lines[0];
    EXPECT_EQ(lines[0].find("depth"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("storage: float keeps them"), std::string::npos) << lines[0];
    const Frame g = read_frame(dir + "/h.exr", nullptr, 1);
    EXPECT_EQ(g.image("color").at(0, 0, 0), 65504.0f);
    EXPECT_EQ(g.image("color").at(0, 0, 1), inf);
    EXPECT_EQ(g.image("depth").at(0, 0, 0), 1e6f);

    // Without a listener: one line on stderr with the file and the count.
    testing::internal::CaptureStderr();
    write_exr(f, dir + "/h2.exr", {});
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find("warning: " + dir + "/h2.exr: values beyond"), std::string::npos) << err;
    EXPECT_NE(err.find("(5 values)"), std::string::npos) << err;

    // Float storage: nothing to say, every value kept.
    lines.clear();
    o.storage = {{"color", PixelStorage::Float}, {"albedo", PixelStorage::Float}};
    write_exr(f, dir + "/f.exr", o);
    EXPECT_TRUE(lines.empty());
    EXPECT_EQ(read_frame(dir + "/f.exr", nullptr, 1).image("color").at(1, 0, 1), 1e38f);
}

}  // namespace

namespace {

/// The 8-bit red channel of a PNG, row-major.
std::vector<unsigned char> png_red(const std::string &path, int &w, int &h)
{
    auto in = OIIO::ImageInput::open(path);
    EXPECT_TRUE(in);
    w = in->spec().width;
    h = in->spec().height;
    const int nch = in->spec().nchannels;
    std::vector<unsigned char> all(std::size_t(w) * std::size_t(h) * std::size_t(nch));
    EXPECT_TRUE(in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, all.data()));
    std::vector<unsigned char> red(std::size_t(w) * std::size_t(h));
    for (std::size_t i = 0; i < red.size(); ++i) {
        red[i] = all[i * std::size_t(nch)];
    }
    return red;
}

}  // namespace

// The preview's 8-bit codes by hand, through an identity transform: floor(v 255 + t) clamped
// to [0, 255] with t the 8x8 Bayer threshold (pattern + 0.5) / 64 of the pixel (0.5 without
// dither), 0 for NaN and infinities; channels the input lacks read as 1. Values at and around
// the ends, codes' edges, a huge finite value; 1-, 3- and 4-channel inputs, with and without
// alpha out, and a display window offset against the data (the pattern follows display
// coordinates).
TEST(IoWrite, PreviewCodesByHand)
{
    // The 8x8 Bayer matrix by its recursion: B(2n)[i][j] = 4 B(n)[i mod n][j mod n] +
    // B(2)[i / n][j / n], from B(1) = 0 and B(2) = {{0, 2}, {3, 1}}.
    int kBayer[8][8] = {};
    for (int n = 1; n < 8; n *= 2) {
        static constexpr int kB2[2][2] = {{0, 2}, {3, 1}};
        int next[8][8] = {};
        for (int i = 0; i < 2 * n; ++i) {
            for (int j = 0; j < 2 * n; ++j) {
                next[i][j] = 4 * kBayer[i % n][j % n] + kB2[i / n][j / n];
            }
        }
        std::copy(&next[0][0], &next[0][0] + 64, &kBayer[0][0]);
    }
    const float inf = std::numeric_limits<float>::infinity();
    const float values[] = {-1.0f,
                            0.0f,
                            0.4f / 255.0f,
                            0.6f / 255.0f,
                            1.0f / 255.0f,
                            0.2f,
                            0.5f,
                            254.5f / 255.0f,
                            1.0f,
                            1.5f,
                            1e38f,
                            inf,
                            -inf,
                            std::numeric_limits<float>::quiet_NaN()};
    const int nv = int(std::size(values));
    const std::string dir = scratch_dir("preview_codes");
    const ColorProcessor identity = ColorProcessor::between("lin_rec709", "lin_rec709", "test");
    ASSERT_TRUE(identity.is_noop());
    for (const int in_ch : {1, 3, 4}) {
        const int w = 19, h = 9;  // every value in every channel and at every dither phase
        Image img(w, h, in_ch);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < in_ch; ++c) {
                    img.at(x, y, c) = c == 3 ? 1.0f : values[(x + 3 * y + 5 * c) % nv];
                }
            }
        }
        const Rect data{2, 1, 2 + w, 1 + h};
        const Rect display{-3, -1, 2 + w, 1 + h};
        for (const bool dither : {false, true}) {
            for (const bool alpha : {false, true}) {
                PreviewOptions o;
                o.dither = dither;
                o.alpha = alpha;
                const std::string path = dir + "/codes.png";
                write_display_preview(img, data, display, identity, path, o);
                auto in = OIIO::ImageInput::open(path);
                ASSERT_TRUE(in);
                const int nch = alpha && in_ch == 4 ? 4 : 3;
                ASSERT_EQ(in->spec().nchannels, nch);
                ASSERT_EQ(in->spec().width, display.width());
                std::vector<unsigned char> got(std::size_t(display.width()) *
                                               std::size_t(display.height()) * std::size_t(nch));
                ASSERT_TRUE(in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, got.data()));
                int checked = 0;
                for (int y = data.y0; y < data.y1; ++y) {
                    for (int x = data.x0; x < data.x1; ++x) {
                        const float t =
                            dither ? (float(kBayer[y & 7][x & 7]) + 0.5f) / 64.0f : 0.5f;
                        for (int c = 0; c < nch; ++c) {
                            // A one-channel pass is grey: its value in R, G and B.
                            const float v = img.at(x - data.x0, y - data.y0, in_ch == 1 ? 0 : c);
                            const float q = std::isfinite(v) ? std::floor(v * 255.0f + t) : 0.0f;
                            const int want = int(std::clamp(q, 0.0f, 255.0f));
                            const std::size_t i =
                                (std::size_t(y - display.y0) * std::size_t(display.width()) +
                                 std::size_t(x - display.x0)) *
                                    std::size_t(nch) +
                                std::size_t(c);
                            ASSERT_EQ(int(got[i]), want)
                                << "v " << v << " channel " << c << " at " << x << "," << y
                                << " dither " << dither << " in_ch " << in_ch;
                            ++checked;
                        }
                    }
                }
                EXPECT_EQ(checked, w * h * nch);
                // Outside the data window: black (alpha 0 where written).
                EXPECT_EQ(int(got[0]), 0);
            }
        }
    }
}

// A TIFF preview reads back (OpenImageIO 2.4's in-memory output wrote a header pointing at the
// wrong directory: every TIFF unreadable, exit 0), the same bytes twice, with no time of
// writing; a grey colour pass (Y, or Y and alpha) goes through the display transform as grey
// (it bypassed it and G and B read 1: cyan).
TEST(IoWrite, TiffPreviewsReadBackAndGreyStaysGrey)
{
    const std::string dir = scratch_dir("preview_tiff");
    const ColorProcessor to_display =
        ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "test");
    Image rgb(8, 4, 3), grey(8, 4, 1), grey_alpha(8, 4, 2);
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 8; ++x) {
            const float v = 0.18f * float(x) / 4.0f;
            for (int c = 0; c < 3; ++c) {
                rgb.at(x, y, c) = v;
            }
            grey.at(x, y, 0) = v;
            grey_alpha.at(x, y, 0) = v;
            grey_alpha.at(x, y, 1) = 1.0f;
        }
    }
    const Rect window{0, 0, 8, 4};
    PreviewOptions o;
    o.dither = false;
    auto read8 = [](const std::string &path, int nch) {
        auto in = OIIO::ImageInput::open(path);
        std::vector<unsigned char> px(std::size_t(8 * 4 * nch));
        EXPECT_TRUE(in && in->spec().nchannels == nch &&
                    in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, px.data()))
            << path << ": " << (in ? in->geterror() : OIIO::geterror());
        return px;
    };
    write_display_preview(rgb, window, window, to_display, dir + "/rgb.tif", o);
    const std::vector<unsigned char> want = read8(dir + "/rgb.tif", 3);
    EXPECT_EQ(want[3 * 4], 118) << "0.18 through sRGB";  // x = 4
    // No time of writing in the file (two runs a second apart differed in it).
    EXPECT_EQ(OIIO::ImageInput::open(dir + "/rgb.tif")->spec().find_attribute("DateTime"), nullptr);
    std::ifstream first(dir + "/rgb.tif", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(first)), {});
    write_display_preview(rgb, window, window, to_display, dir + "/rgb.tif", o);
    std::ifstream second(dir + "/rgb.tif", std::ios::binary);
    EXPECT_EQ(std::string((std::istreambuf_iterator<char>(second)), {}), bytes);
    for (const Image *g : {&grey, &grey_alpha}) {
        write_display_preview(*g, window, window, to_display, dir + "/grey.png", o);
        EXPECT_EQ(read8(dir + "/grey.png", 3), want) << g->channels() << " channel(s)";
        write_display_preview(*g, window, window, to_display, dir + "/grey.tif", o);
        EXPECT_EQ(read8(dir + "/grey.tif", 3), want) << g->channels() << " channel(s)";
    }
    o.alpha = true;
    write_display_preview(grey_alpha, window, window, to_display, dir + "/grey_a.png", o);
    const std::vector<unsigned char> with_alpha = read8(dir + "/grey_a.png", 4);
    for (int i = 0; i < 8 * 4; ++i) {
        ASSERT_EQ(with_alpha[std::size_t(i) * 4 + 3], 255) << i;
        ASSERT_EQ(with_alpha[std::size_t(i) * 4 + 1], want[std::size_t(i) * 3 + 1]) << i;
    }
}

// An 8-bit preview of a transform without channel crosstalk (the sRGB display) goes through
// OpenColorIO's table over half-float inputs: every code within one of the exact float
// transform's (quantised by the same formula), most of them equal; finite values past half's
// range stay white (not infinite, which the preview writes as 0); NaN and infinities 0; an
// unpremultiplied RGBA pixel keeps its alpha.
TEST(IoWrite, PreviewHalfTableWithinOneCode)
{
    const int w = 4096, h = 2;
    Image img(w, h, 4);
    for (int x = 0; x < w; ++x) {
        // Floats that are not halves, from below 0 to well above 1.
        const float v = -0.01f + 1.7f * (float(x) + 0.37f) / float(w);
        for (int c = 0; c < 3; ++c) {
            img.at(x, 0, c) = v * (1.0f + 0.013f * float(c));
        }
        img.at(x, 0, 3) = 1.0f;
        for (int c = 0; c < 4; ++c) {
            img.at(x, 1, c) = 0.0f;
        }
    }
    const float inf = std::numeric_limits<float>::infinity();
    const float specials[][4] = {{1e5f, 7e4f, 3e38f, 1.0f},
                                 {inf, -inf, std::numeric_limits<float>::quiet_NaN(), 1.0f},
                                 {-1e5f, 0.5f, 0.25f, 0.5f}};
    for (int i = 0; i < 3; ++i) {
        std::copy_n(specials[i], 4, img.pixel(i, 1));
    }
    const std::string dir = scratch_dir("preview_half");
    const ColorProcessor table =
        ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "test", true);
    const ColorProcessor exact =
        ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "test", false);
    PreviewOptions o;
    o.dither = false;
    o.alpha = true;
    const Rect window{0, 0, w, h};
    write_display_preview(img, window, window, table, dir + "/p.png", o);
    auto in = OIIO::ImageInput::open(dir + "/p.png");
    ASSERT_TRUE(in);
    std::vector<unsigned char> got(std::size_t(w) * std::size_t(h) * 4);
    ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::UINT8, got.data()));
    auto code = [](float v) {
        return std::isfinite(v) ? int(std::clamp(std::floor(v * 255.0f + 0.5f), 0.0f, 255.0f)) : 0;
    };
    int worst = 0, differ = 0;
    for (int x = 0; x < w; ++x) {
        float rgb[3] = {img.at(x, 0, 0), img.at(x, 0, 1), img.at(x, 0, 2)};
        exact.apply_rgb(rgb);
        for (int c = 0; c < 3; ++c) {
            const int d = std::abs(int(got[std::size_t(x) * 4 + std::size_t(c)]) - code(rgb[c]));
            worst = std::max(worst, d);
            differ += d != 0 ? 1 : 0;
        }
        EXPECT_EQ(int(got[std::size_t(x) * 4 + 3]), 255);
    }
    std::printf("half table against the exact transform: worst %d code, %d of %d differ\n",
                worst,
                differ,
                3 * w);
    EXPECT_LE(worst, 1);
    EXPECT_GT(differ, 0);  // the table really is in use (values are not halves)
    EXPECT_LT(differ, w * 3 / 10);
    const unsigned char *s = got.data() + std::size_t(w) * 4;
    EXPECT_EQ(int(s[0]), 255);  // 1e5, 7e4 and 3e38: white
    EXPECT_EQ(int(s[1]), 255);
    EXPECT_EQ(int(s[2]), 255);
    EXPECT_EQ(int(s[4]), 0);  // inf, -inf, NaN
    EXPECT_EQ(int(s[5]), 0);
    EXPECT_EQ(int(s[6]), 0);
    // (-1e5, 0.5, 0.25) premultiplied by alpha 0.5: the display values of (-2e5, 1, 0.5) times
    // 0.5, alpha 128.
    float rgb[3] = {-2e5f, 1.0f, 0.5f};
    exact.apply_rgb(rgb);
    EXPECT_EQ(int(s[8]), 0);
    EXPECT_NEAR(int(s[9]), code(rgb[1] * 0.5f), 1);
    EXPECT_NEAR(int(s[10]), code(rgb[2] * 0.5f), 1);
    EXPECT_EQ(int(s[11]), 128);
}

TEST(IoWrite, PreviewDitherBreaksBandsAndKeepsTheMean)
{
    // A smooth, slow ramp (a sky or fog gradient): 1024 px spanning a few 8-bit codes.
    const int w = 1024, h = 16;
    Image ramp(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float v = 0.20f + 0.02f * float(x) / float(w - 1);
            ramp.at(x, y, 0) = ramp.at(x, y, 1) = ramp.at(x, y, 2) = v;
            ramp.at(x, y, 3) = 1.0f;
        }
    }
    const std::string dir = scratch_dir("dither");
    const ColorProcessor srgb =
        ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "test", true);
    PreviewOptions plain;
    plain.dither = false;
    PreviewOptions dithered;
    const Rect window{0, 0, w, h};
    write_display_preview(ramp, window, window, srgb, dir + "/plain.png", plain);
    write_display_preview(ramp, window, window, srgb, dir + "/dither.png", dithered);
    write_display_preview(ramp, window, window, srgb, dir + "/dither2.png", dithered);
    int pw = 0, ph = 0;
    const auto a = png_red(dir + "/plain.png", pw, ph);
    const auto b = png_red(dir + "/dither.png", pw, ph);
    ASSERT_EQ(pw, w);
    // Banding: the longest run of equal values along a row.
    auto longest_run = [&](const std::vector<unsigned char> &v, int y) {
        int best = 1, run = 1;
        for (int x = 1; x < w; ++x) {
            run = v[std::size_t(y * w + x)] == v[std::size_t(y * w + x - 1)] ? run + 1 : 1;
            best = std::max(best, run);
        }
        return best;
    };
    const int plain_run = longest_run(a, 3), dither_run = longest_run(b, 3);
    EXPECT_GE(plain_run, 100);  // about 1024 / 7 codes
    // An ordered dither leaves a row alone only where the value sits within a row's lowest or
    // highest threshold of a code (about a third of each code's width).
    EXPECT_LE(dither_run * 2, plain_run);
    std::cout << "longest run of equal values: " << plain_run << " plain, " << dither_run
              << " dithered\n";
    // The dither keeps the mean: over each 8x8 block, the average code equals the exact value
    // (the plain rounding's error is up to half a code; the dither's mean is within 1/8 code).
    double worst_plain = 0.0, worst_dither = 0.0;
    for (int bx = 0; bx < w / 8; ++bx) {
        double exact = 0.0, sa = 0.0, sb = 0.0;
        for (int y = 0; y < 8; ++y) {
            for (int x = bx * 8; x < bx * 8 + 8; ++x) {
                float rgb[3] = {ramp.at(x, y, 0), ramp.at(x, y, 1), ramp.at(x, y, 2)};
                srgb.apply_rgb(rgb);
                exact += rgb[0] * 255.0;
                sa += a[std::size_t(y * w + x)];
                sb += b[std::size_t(y * w + x)];
            }
        }
        worst_plain = std::max(worst_plain, std::abs(sa - exact) / 64.0);
        worst_dither = std::max(worst_dither, std::abs(sb - exact) / 64.0);
    }
    EXPECT_LT(worst_dither, 0.13);
    EXPECT_GT(worst_plain, 0.3);
    // Deterministic: the same frame gives the same bytes.
    std::ifstream f1(dir + "/dither.png", std::ios::binary),
        f2(dir + "/dither2.png", std::ios::binary);
    const std::string s1((std::istreambuf_iterator<char>(f1)), {});
    const std::string s2((std::istreambuf_iterator<char>(f2)), {});
    EXPECT_EQ(s1, s2);
    // The PNG row filter changes the bytes, never the pixels.
    for (const PngFilter filter : {PngFilter::adaptive,
                                   PngFilter::sub,
                                   PngFilter::up,
                                   PngFilter::average,
                                   PngFilter::paeth}) {
        PreviewOptions o = dithered;
        o.png_filter = filter;
        write_display_preview(ramp, window, window, srgb, dir + "/filtered.png", o);
        EXPECT_EQ(png_red(dir + "/filtered.png", pw, ph), b) << int(filter);
    }
}

}  // namespace posthaste

namespace posthaste {
namespace {

TEST(IoWrite, StaleTemporariesOfKilledWritesAreRemoved)
{
    namespace fs = std::filesystem;
    const std::string dir = test::scratch_dir("stale_tmp");
    // A dead process's temporary, an hour old; a live process's (this test's parent, pid 1);
    // a fresh dead one (a write of another host on a shared disk might own it); a user's file.
    const std::string dead_old = dir + "/.shot.0001.tmp999999998-123.exr";
    const std::string live = dir + "/.shot.0002.tmp1-5.exr";
    const std::string dead_new = dir + "/.shot.0003.tmp999999997-7.exr";
    const std::string user = dir + "/.notes.tmp.txt";
    for (const std::string &p : {dead_old, live, dead_new, user}) {
        std::ofstream(p) << "x";
    }
    const auto hour_ago = fs::file_time_type::clock::now() - std::chrono::hours(1);
    for (const std::string &p : {dead_old, live, user}) {
        fs::last_write_time(p, hour_ago);
    }
    Frame f;
    f.set("color", Image(4, 4, 4));
    write_exr(f, dir + "/shot.0004.exr", {});
    EXPECT_FALSE(fs::exists(dead_old));
    EXPECT_TRUE(fs::exists(live));
    EXPECT_TRUE(fs::exists(dead_new));
    EXPECT_TRUE(fs::exists(user));
    EXPECT_TRUE(fs::exists(dir + "/shot.0004.exr"));
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

// A touched mip map's levels: blocks of 2x2 where the sizes are even (the same bits as the sum of
// four over four); an odd size rounded down weighs the old pixels by their overlap with the new
// ones, so a level keeps the image's mean and place (a plain box dropped the last row and
// column: every level moved up and left, a gradient's level 4 mean read 0.44 for 0.5).
TEST(MipLevels, OddSizesRoundedDownKeepTheMeanAndPlace)
{
    int nw = 0, nh = 0;
    const std::vector<float> quad = {0.1f, 0.7f, 0.3f, 0.9f};
    const std::vector<float> even = io_detail::halve(quad, 2, 2, 1, true, true, false, nw, nh);
    ASSERT_EQ(nw, 1);
    ASSERT_EQ(nh, 1);
    EXPECT_EQ(even[0], (((0.1f + 0.7f) + 0.3f) + 0.9f) / 4.0f);
    // A ramp of 5 pixels (0..4) to 2: overlaps 2, 2, 1 and 1, 2, 2 in fifths.
    const std::vector<float> ramp = {0.0f, 1.0f, 2.0f, 3.0f, 4.0f};
    const std::vector<float> down = io_detail::halve(ramp, 5, 1, 1, true, false, false, nw, nh);
    ASSERT_EQ(nw, 2);
    EXPECT_FLOAT_EQ(down[0], 0.8f);
    EXPECT_FLOAT_EQ(down[1], 3.2f);
    EXPECT_FLOAT_EQ(0.5f * (down[0] + down[1]), 2.0f);  // the ramp's mean
    // Rounding up: blocks of two, the odd last pixel alone.
    const std::vector<float> up = io_detail::halve(ramp, 5, 1, 1, true, false, true, nw, nh);
    ASSERT_EQ(nw, 3);
    EXPECT_EQ(up, (std::vector<float>{0.5f, 2.5f, 4.0f}));
    // A 45x27 gradient down to 1x1: every level's mean stays the image's within float rounding.
    std::vector<float> img(45 * 27);
    double mean = 0.0;
    for (int y = 0; y < 27; ++y) {
        for (int x = 0; x < 45; ++x) {
            img[std::size_t(y * 45 + x)] = float(x + 3 * y) / 100.0f;
            mean += img[std::size_t(y * 45 + x)];
        }
    }
    mean /= 45.0 * 27.0;
    int w = 45, h = 27;
    while (w > 1 || h > 1) {
        img = io_detail::halve(img, w, h, 1, true, true, false, w, h);
        double m = 0.0;
        for (float v : img) {
            m += v;
        }
        EXPECT_NEAR(m / double(img.size()), mean, 1e-5) << w << "x" << h;
    }
}

}  // namespace
}  // namespace posthaste
