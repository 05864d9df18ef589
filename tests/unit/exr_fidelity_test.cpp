// EXR fidelity: a generated corpus of files as other tools write them (windows of every kind,
// tiled and mip-mapped environments, every compression, channel sets, multi-part and stereo
// files, luminance/chroma and deep files) goes through read -> write and comes out unchanged,
// checked with OpenEXR's own reader (exr_corpus.cpp), or equal to the conversion computed there.

#include <ImfChannelList.h>
#include <ImfChromaticitiesAttribute.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfInputPart.h>
#include <ImfIntAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfStandardAttributes.h>
#include <ImfStringAttribute.h>
#include <ImfTileDescription.h>
#include <ImfTiledInputFile.h>
#include <ImfTimeCodeAttribute.h>
#include <ImfVecAttribute.h>
#include <gtest/gtest.h>
#include <half.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>

#include "core/error.h"
#include "core/memory.h"
#include "exr_corpus.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace corpus = test::corpus;

/// The scratch folder, emptied once per process.
const std::string &scratch()
{
    static const std::string kDir = test::scratch_dir("exr_corpus");
    return kDir;
}

const std::vector<corpus::Entry> &the_corpus()
{
    static const std::vector<corpus::Entry> kEntries = corpus::write_corpus(scratch() + "/in");
    return kEntries;
}

const corpus::Entry &entry(const std::string &name)
{
    for (const corpus::Entry &e : the_corpus()) {
        if (e.name == name) {
            return e;
        }
    }
    throw std::runtime_error("no corpus entry " + name);
}

std::string out_path(const std::string &name)
{
    return scratch() + "/out/" + name + ".exr";
}

TEST(ExrFidelity, EveryFlatFileComesThroughUnchanged)
{
    int checked = 0;
    for (const corpus::Entry &e : the_corpus()) {
        if (e.kind != corpus::Kind::Flat && e.kind != corpus::Kind::LumaOnly) {
            continue;
        }
        SCOPED_TRACE(e.name + ": " + e.what);
        const std::string out = out_path(e.name);
        const Frame f = read_frame(e.path, nullptr, 1);
        write_exr(f, out, {});
        EXPECT_EQ(corpus::compare_exr(e.path, out), "");
        ++checked;
    }
    EXPECT_GE(checked, 25);
}

TEST(ExrFidelity, EveryHeaderAttributeComesThrough)
{
    // Names, types and value bytes of every attribute, on every flat file: nothing lost, and
    // nothing of the reader's or writer's own added (a write date, a level-mode directive) but
    // the frame number posthaste stamps on what it writes. Compression ('auto' keeps it unless
    // lossy) and the files' structure are compare_exr's. The line order too ("overlap" is
    // stored bottom up), which OpenImageIO does not report: the reader reads it from the header.
    int checked = 0;
    for (const corpus::Entry &e : the_corpus()) {
        if (e.kind != corpus::Kind::Flat) {
            continue;
        }
        SCOPED_TRACE(e.name + ": " + e.what);
        const std::string out = out_path(e.name + "_attributes");
        write_exr(read_frame(e.path, nullptr, 1), out, {});
        std::vector<std::string> ignore = {"compression", "frameNumber"};
        EXPECT_EQ(corpus::compare_attributes(e.path, out, ignore), "");
        ++checked;
    }
    EXPECT_GE(checked, 25);
    // The file of every type, twice: the same bytes (no date of writing).
    const Frame f = read_frame(entry("attributes").path, nullptr, 1);
    write_exr(f, out_path("attributes_again"), {});
    EXPECT_EQ(test::read_bytes(out_path("attributes_attributes")),
              test::read_bytes(out_path("attributes_again")));
}

// An attribute the graph changed is written as changed, one it removed stays removed (it came
// back from the source part's header); the rest keep their OpenEXR types (the restore of the file's
// own attributes takes only those whose values the graph left alone).
TEST(ExrFidelity, ChangedAttributesWinOverTheFilesOwn)
{
    Frame f = read_frame(entry("attributes").path, nullptr, 1);
    const float moved[3] = {9.0f, 8.0f, 7.0f};
    f.attributes.remove("studio:floats3");
    f.attributes.push_back(
        OIIO::ParamValue("studio:floats3", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 3), 1, moved));
    f.attributes.remove("studio:v3f");
    f.attributes.remove("ImageDescription");  // OpenEXR's comments
    const std::string out = out_path("attributes_changed");
    write_exr(f, out, {});
    Imf::InputFile in(out.c_str());
    const Imf::Header &h = in.header();
    const auto *a = h.findTypedAttribute<Imf::FloatVectorAttribute>("studio:floats3");
    ASSERT_NE(a, nullptr);  // a float[3] as OpenImageIO holds it: a floatvector again
    EXPECT_EQ(a->value(), (Imf::FloatVector{9.0f, 8.0f, 7.0f}));
    EXPECT_EQ(h.find("studio:v3f"), h.end());
    EXPECT_EQ(h.find("comments"), h.end());
    EXPECT_NE(h.find("owner"), h.end());
    EXPECT_NE(h.findTypedAttribute<Imf::FloatVectorAttribute>("studio:floats2"), nullptr);
    EXPECT_NE(h.findTypedAttribute<Imf::ChromaticitiesAttribute>("studio:chromaticities"), nullptr);
    EXPECT_TRUE(h.hasPreviewImage());
    ASSERT_NE(h.find("studio:blob"), h.end());
    EXPECT_STREQ(h["studio:blob"].typeName(), "studioBlob");

    // New pixels: the preview, a thumbnail of the old ones, stays out; the rest is kept.
    Image color = f.image("color");
    color.at(0, 0, 0) += 1.0f;
    f.set("color", std::move(color));
    write_exr(f, out_path("attributes_regraded"), {});
    Imf::InputFile regraded(out_path("attributes_regraded").c_str());
    EXPECT_FALSE(regraded.header().hasPreviewImage());
    EXPECT_NE(regraded.header().find("studio:blob"), regraded.header().end());
}

// An attribute of a studio's own under a name OpenImageIO takes for a standard one (FNumber,
// description) comes back alone: its standard twin (aperture, comments) is not added beside it.
TEST(ExrFidelity, AStudiosOwnStandardLookingNamesAddNoTwins)
{
    const std::string src = scratch() + "/twins.exr";
    {
        Imf::Header h(4, 2);
        h.channels().insert("R", Imf::Channel(Imf::HALF));
        h.insert("FNumber", Imf::FloatAttribute(4.0f));
        h.insert("description", Imf::StringAttribute("a studio's own"));
        std::vector<half> px(8, half(0.5f));
        Imf::FrameBuffer fb;
        fb.insert("R", Imf::Slice(Imf::HALF, reinterpret_cast<char *>(px.data()), 2, 8));
        Imf::OutputFile out(src.c_str(), h);
        out.setFrameBuffer(fb);
        out.writePixels(2);
    }
    write_exr(read_frame(src, nullptr, 1), out_path("twins"), {});
    Imf::InputFile in(out_path("twins").c_str());
    const Imf::Header &h = in.header();
    EXPECT_NE(h.findTypedAttribute<Imf::FloatAttribute>("FNumber"), nullptr);
    EXPECT_NE(h.findTypedAttribute<Imf::StringAttribute>("description"), nullptr);
    EXPECT_EQ(h.find("aperture"), h.end());
    EXPECT_EQ(h.find("comments"), h.end());
}

// A layout the write is asked to rebuild (single part, or a part per pass) keeps the header's
// attributes too, the comments, capture date, software and time code among them (they were
// dropped there as "structural"), and adds no alpha to an RGB file (it wrote the reader's
// constant A).
TEST(ExrFidelity, RebuiltLayoutsKeepAttributesAndAddNoAlpha)
{
    const corpus::Entry &e = entry("attributes");
    for (const ExrLayout layout : {ExrLayout::Single, ExrLayout::Multipart}) {
        SCOPED_TRACE(layout == ExrLayout::Single ? "single" : "multipart");
        const std::string out =
            out_path(layout == ExrLayout::Single ? "rebuilt_single" : "rebuilt_multipart");
        WriteOptions o;
        o.layout = layout;
        write_exr(read_frame(e.path, nullptr, 1), out, o);
        // A part per pass names its parts: the rest of the header is the source's.
        std::vector<std::string> ignore = {"compression", "frameNumber", "name", "type"};
        EXPECT_EQ(corpus::compare_attributes(e.path, out, ignore), "");
        Imf::InputFile in(out.c_str());
        EXPECT_TRUE(in.header().findTypedAttribute<Imf::TimeCodeAttribute>("timeCode"));
        EXPECT_TRUE(in.header().findTypedAttribute<Imf::StringAttribute>("comments"));
    }
    const std::string rgb = scratch() + "/rgb.exr";
    {
        Frame f;
        Image c(4, 2, 3);
        c.fill(0.25f);
        f.set("color", c, {"R", "G", "B"});
        write_exr(f, rgb, {});
    }
    for (const ExrLayout layout : {ExrLayout::Single, ExrLayout::Multipart}) {
        WriteOptions o;
        o.layout = layout;
        const std::string out = scratch() + "/rgb_rebuilt.exr";
        write_exr(read_frame(rgb, nullptr, 1), out, o);
        Imf::InputFile in(out.c_str());
        std::vector<std::string> names;
        for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
            names.push_back(it.name());
        }
        EXPECT_EQ(names, (std::vector<std::string>{"B", "G", "R"}));
    }
}

TEST(ExrFidelity, GraphReadWriteIsAPassThrough)
{
    // The user's path: `posthaste run` with a read -> write graph and default parameters.
    const std::string dir = scratch() + "/cli";
    std::filesystem::create_directories(dir);
    for (const char *name : {"overscan_around",
                             "stereo_multipart",
                             "cube_mip",
                             "types_mixed",
                             "negative_origin",
                             "single_g",
                             "comp_dwaa"}) {
        SCOPED_TRACE(name);
        const std::string graph = dir + "/" + name + ".json";
        std::ofstream(graph) << R"({"nodes": [
            {"id": "in", "type": "read", "params": {"path": ")"
                             << entry(name).path << R"("}},
            {"id": "out", "type": "write", "inputs": {"image": "in"},
             "params": {"path": ")"
                             << dir << "/" << name << R"(.exr"}}]})";
        std::string log;
        ASSERT_EQ(
            test::run_command(
                std::string(POSTHASTE_BINARY) + " run " + graph + " --frames 1 --quiet", &log),
            0)
            << log;
        EXPECT_EQ(corpus::compare_exr(entry(name).path, dir + "/" + name + ".exr"), "");
    }
}

// A Blender file through read -> write comes out bit for bit: its Vector pass is read as motion
// with a scale of -1 on two channels, and -1 * +0 + 0 is +0, so the write's inverse turned the
// sky's +0 into -0 (3,109 values of Vector.X and Vector.Z) until the read stopped adding an
// offset of 0.
TEST(ExrFidelity, BlenderVectorPassComesThroughBitForBit)
{
    const std::string dir = scratch() + "/blender";
    std::filesystem::create_directories(dir);
    const std::string in = std::string(POSTHASTE_SOURCE_DIR) + "/samples/cycles/yard.passes.exr";
    std::ofstream(dir + "/g.json") << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")"
                                   << in << R"("}},
        {"id": "out", "type": "write", "inputs": {"image": "in"},
         "params": {"path": ")" << dir
                                   << R"(/out.exr"}}]})";
    std::string log;
    ASSERT_EQ(
        test::run_command(
            std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1 --quiet", &log),
        0)
        << log;
    EXPECT_EQ(corpus::compare_exr(in, dir + "/out.exr"), "");
}

/// A uint channel of a single-part scanline file over `box` (absolute pixels, inside its data
/// window), as OpenEXR reads it.
std::vector<std::uint32_t> read_uint_channel(const std::string &path,
                                             const char *name,
                                             const Rect &box)
{
    Imf::InputFile in(path.c_str());
    const Imath::Box2i dw = in.header().dataWindow();
    const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    std::vector<std::uint32_t> all(std::size_t(w) * std::size_t(h));
    const std::size_t xs = sizeof(std::uint32_t), ys = xs * std::size_t(w);
    Imf::FrameBuffer fb;
    fb.insert(name,
              Imf::Slice(Imf::UINT,
                         reinterpret_cast<char *>(all.data()) -
                             (std::ptrdiff_t(dw.min.x) * std::ptrdiff_t(xs) +
                              std::ptrdiff_t(dw.min.y) * std::ptrdiff_t(ys)),
                         xs,
                         ys));
    in.setFrameBuffer(fb);
    in.readPixels(dw.min.y, dw.max.y);
    std::vector<std::uint32_t> v;
    for (int y = box.y0; y < box.y1; ++y) {
        for (int x = box.x0; x < box.x1; ++x) {
            v.push_back(
                all[std::size_t(y - dw.min.y) * std::size_t(w) + std::size_t(x - dw.min.x)]);
        }
    }
    return v;
}

TEST(ExrFidelity, CropKeepsUintIdsBeyondTwoToThe24)
{
    // crop moves no pixel: a uint id (> 2^24, which a float pass rounds) comes out as the file
    // had it, cut to the box, as a uint channel (it was written as a rounded float).
    const std::string dir = scratch() + "/crop_uint";
    std::filesystem::create_directories(dir);
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")"
                         << entry("types_mixed").path << R"("}},
        {"id": "c", "type": "crop", "inputs": {"image": "in"}, "params": {"box": [5, 4, 30, 20]}},
        {"id": "out", "type": "write", "inputs": {"image": "c"}, "params": {"path": ")"
                         << dir << R"(/out.exr"}}]})";
    std::string log;
    ASSERT_EQ(test::run_command(
                  std::string(POSTHASTE_BINARY) + " run " + graph + " --frames 1 --quiet", &log),
              0)
        << log;
    const Rect box{5, 4, 30, 20};
    const std::vector<std::uint32_t> want = read_uint_channel(entry("types_mixed").path, "id", box);
    EXPECT_TRUE(
        std::any_of(want.begin(), want.end(), [](std::uint32_t v) { return v > (1u << 24) + 1; }));
    EXPECT_EQ(read_uint_channel(dir + "/out.exr", "id", box), want);
}

// Storage asked as float rounds uint ids beyond 2^24: the write says so once, naming the
// channel (it was silent); storage auto keeps them (CropKeepsUintIdsBeyondTwoToThe24).
TEST(ExrFidelity, AskedStorageSaysWhenItRoundsUintIds)
{
    const std::string dir = scratch() + "/storage_uint";
    std::filesystem::create_directories(dir);
    for (const char *storage : {"float", "auto"}) {
        std::ofstream(dir + "/g.json")
            << R"({"nodes": [
            {"id": "in", "type": "read", "params": {"path": ")"
            << entry("types_mixed").path << R"("}},
            {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": ")"
            << dir << "/" << storage << R"(.exr", "storage": ")" << storage << R"("}}]})";
        std::string log;
        ASSERT_EQ(test::run_command(
                      std::string(POSTHASTE_BINARY) + " run " + dir + "/g.json --frames 1", &log),
                  0)
            << log;
        const bool said = log.find("uint id channel(s) id written as floats lose the low bits") !=
                          std::string::npos;
        EXPECT_EQ(said, std::string(storage) == "float") << storage << ": " << log;
    }
}

TEST(ExrFidelity, GraphErrorsAndInfo)
{
    const std::string dir = scratch() + "/cli_errors";
    std::filesystem::create_directories(dir);
    auto run = [&](const std::string &file, const std::string &read_params, std::string &log) {
        const std::string graph = dir + "/g.json";
        std::ofstream(graph) << R"({"nodes": [
            {"id": "in", "type": "read", "params": {"path": ")"
                             << file << "\", " << read_params << R"(}},
            {"id": "out", "type": "write", "inputs": {"image": "in"},
             "params": {"path": ")"
                             << dir << R"(/out.exr"}}]})";
        return test::run_command(
            std::string(POSTHASTE_BINARY) + " run " + graph + " --frames 1 --quiet", &log);
    };
    std::string log;
    EXPECT_EQ(run(entry("stereo_multipart").path, R"("view": "middle")", log), 1);
    EXPECT_NE(log.find("no view \"middle\" (have: left, right)"), std::string::npos) << log;
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
    EXPECT_EQ(run(entry("deep_scanline").path, R"("deep": "error")", log), 1);
    EXPECT_NE(log.find("deep_scanline.exr: part 0 is deep"), std::string::npos) << log;
    EXPECT_FALSE(std::filesystem::exists(dir + "/out.exr"));
    EXPECT_EQ(run(entry("deep_scanline").path, R"("deep": "flatten")", log), 0) << log;

    // info: windows, views, tiling, levels, deep samples.
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " +
                                    entry("stereo_multipart").path + " " + entry("cube_mip").path +
                                    " " + entry("deep_tiled").path,
                                &log),
              0)
        << log;
    for (const char *want : {"views              left, right; passes from \"left\"",
                             "display window     (0,0)-(31,31) 32x32",
                             "data window        (0,0)-(31,191) 32x192",
                             "tiled 16x16, mipmap 8 levels, cube environment",
                             "deep samples:",
                             "color@right",
                             // another view's pass is mapped (and shown) as the chosen view's
                             "motion_next@right <- forward.u, -forward.v (Nuke)"}) {
        EXPECT_NE(log.find(want), std::string::npos) << want << "\n" << log;
    }
}

TEST(ExrFidelity, WindowsAreKept)
{
    const Frame f = read_frame(entry("overscan_around").path, nullptr, 1);
    EXPECT_EQ(f.display_window, (Rect{30, 20, 400, 300}));
    EXPECT_EQ(f.data_window, (Rect{0, 0, 400, 300}));
    EXPECT_EQ(f.image("color").width(), 400);
    const Frame g = read_frame(entry("negative_origin").path, nullptr, 1);
    EXPECT_EQ(g.display_window, (Rect{-16, -8, 48, 40}));
    EXPECT_EQ(g.data_window, (Rect{-20, -10, 31, 31}));
    const Frame c = read_frame(entry("cube_mip").path, nullptr, 1);
    EXPECT_EQ(c.data_window.height(), 192);  // all six faces
    EXPECT_EQ(c.display_window.height(), 32);
}

TEST(ExrFidelity, ChannelsKeepNamesAndAlphaIsNotAdded)
{
    // RGB without alpha: the color pass has A = 1 for the nodes, but no A is written.
    const Frame rgb = read_frame(entry("rgb_no_alpha").path, nullptr, 1);
    ASSERT_EQ(rgb.image("color").channels(), 4);
    EXPECT_EQ(rgb.image("color").at(0, 0, 3), 1.0f);
    write_exr(rgb, out_path("rgb_again"), {});
    const FileInfo info = read_file_info(out_path("rgb_again"));
    ASSERT_EQ(info.parts[0].channels.size(), 3u);
    // A node that makes alpha vary gets it written, next to R, G, B.
    Frame changed = rgb;
    Image color = rgb.image("color");
    color.at(0, 0, 3) = 0.5f;
    changed.set("color", std::move(color));
    write_exr(changed, out_path("rgb_alpha"), {});
    EXPECT_EQ(read_file_info(out_path("rgb_alpha")).parts[0].channels.size(), 4u);
    // A single channel "G" stays "G".
    write_exr(read_frame(entry("single_g").path, nullptr, 1), out_path("g_again"), {});
    const FileInfo g = read_file_info(out_path("g_again"));
    ASSERT_EQ(g.parts[0].channels.size(), 1u);
    EXPECT_EQ(g.parts[0].channels[0].name, "G");
}

TEST(ExrFidelity, TouchedPassGoesBackToItsChannelsAndTypes)
{
    // types_mixed: half color, float depth, uint id. Scaling the color keeps half and the
    // channel names; the untouched uint id keeps its bits beyond 2^24.
    const Frame f = read_frame(entry("types_mixed").path, nullptr, 1);
    Frame g = f;
    Image color = f.image("color");
    for (std::size_t i = 0; i < color.pixel_count(); ++i) {
        for (int c = 0; c < 3; ++c) {
            color.data()[i * 4 + std::size_t(c)] *= 2.0f;  // alpha (made up: 1) stays
        }
    }
    g.set("color", std::move(color));
    write_exr(g, out_path("types_touched"), {});
    const FileInfo in = read_file_info(entry("types_mixed").path);
    const FileInfo out = read_file_info(out_path("types_touched"));
    ASSERT_EQ(out.parts.size(), 1u);
    ASSERT_EQ(in.parts[0].channels.size(), out.parts[0].channels.size());
    for (std::size_t c = 0; c < in.parts[0].channels.size(); ++c) {
        EXPECT_EQ(in.parts[0].channels[c].name, out.parts[0].channels[c].name);
        EXPECT_EQ(in.parts[0].channels[c].type, out.parts[0].channels[c].type);
    }
    const Frame back = read_frame(out_path("types_touched"), nullptr, 1);
    const Image &a = f.image("color"), &b = back.image("color");
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            const float v = a.at(x, y, 0);
            if (std::isfinite(v) && std::abs(v) < 16000.0f) {
                ASSERT_EQ(b.at(x, y, 0), 2.0f * v) << x << "," << y;
            }
        }
    }
}

TEST(ExrFidelity, TouchedMipMapGetsItsLevelsAgain)
{
    const Frame f = read_frame(entry("cube_mip").path, nullptr, 1);
    Frame g = f;
    Image color = f.image("color");
    color.fill(0.5f);
    g.set("color", std::move(color));
    write_exr(g, out_path("cube_touched"), {});
    const FileInfo info = read_file_info(out_path("cube_touched"));
    EXPECT_EQ(info.parts[0].mip_levels, read_file_info(entry("cube_mip").path).parts[0].mip_levels);
    EXPECT_EQ(info.parts[0].envmap, "cube");
    EXPECT_EQ(info.data_window, f.data_window);
    EXPECT_EQ(info.display_window, f.display_window);
}

TEST(ExrFidelity, TouchedRipmapGetsItsLevelsAgain)
{
    // ripmap: 20x12, ROUND_UP, 6x5 levels. Red = x and green = y: halving the width takes red
    // to 2i + 0.5 and leaves green; halving the height the other way round.
    const std::string in = entry("ripmap").path;
    const Frame f = read_frame(in, nullptr, 1);
    Frame g = f;
    Image color = f.image("color");
    for (int y = 0; y < color.height(); ++y) {
        for (int x = 0; x < color.width(); ++x) {
            color.at(x, y, 0) = float(x);
            color.at(x, y, 1) = float(y);
        }
    }
    g.set("color", std::move(color));
    const std::string out = out_path("ripmap_touched");
    write_exr(g, out, {});
    Imf::TiledInputFile file(out.c_str());
    ASSERT_EQ(file.header().tileDescription().mode, Imf::RIPMAP_LEVELS);
    ASSERT_EQ(file.numXLevels(), 6);
    ASSERT_EQ(file.numYLevels(), 5);
    auto level = [&](int lx, int ly) {
        const int w = file.levelWidth(lx), h = file.levelHeight(ly);
        std::vector<half> px(std::size_t(w) * std::size_t(h) * 2);
        Imf::FrameBuffer fb;
        const Imath::V2i origin = file.header().dataWindow().min;
        for (int c = 0; c < 2; ++c) {
            fb.insert(c == 0 ? "R" : "G",
                      Imf::Slice::Make(Imf::HALF,
                                       px.data() + c,
                                       origin,
                                       std::int64_t(w),
                                       std::int64_t(h),
                                       std::size_t(4),
                                       std::size_t(4) * std::size_t(w)));
        }
        file.setFrameBuffer(fb);
        file.readTiles(0, file.numXTiles(lx) - 1, 0, file.numYTiles(ly) - 1, lx, ly);
        return px;
    };
    const std::vector<half> a = level(1, 0), b = level(0, 1), c = level(1, 1);
    for (int j = 0; j < 6; ++j) {
        for (int i = 0; i < 10; ++i) {
            const std::size_t k = std::size_t(j) * 10 + std::size_t(i);
            EXPECT_EQ(float(a[k * 2]), 2.0f * float(i) + 0.5f);  // (1, 0): 10x12, red halved
            EXPECT_EQ(float(a[k * 2 + 1]), float(j));
            EXPECT_EQ(float(c[k * 2]), 2.0f * float(i) + 0.5f);  // (1, 1): 10x6, both
            EXPECT_EQ(float(c[k * 2 + 1]), 2.0f * float(j) + 0.5f);
        }
    }
    for (int i = 0; i < 20; ++i) {  // (0, 1): 20x6, green halved
        EXPECT_EQ(float(b[std::size_t(i) * 2]), float(i));
        EXPECT_EQ(float(b[std::size_t(i) * 2 + 1]), 0.5f);
    }
    // Rounding up, an odd edge pixel makes a level pixel alone: widths 10, 5, 3, 2, 1 give red
    // 0.5 2.5 .. 18.5; 1.5 5.5 .. 17.5; 3.5 11.5 17.5; 7.5 17.5; 12.5.
    const std::vector<half> last = level(5, 0);
    EXPECT_EQ(float(last[0]), 12.5f);
    // Its levels are held within the memory budget: the 20x12 file's other levels take 7.4 KB.
    const std::size_t saved = image_memory_budget();
    set_image_memory_budget(image_memory_in_use() + 4096);
    std::string what;
    try {
        read_frame(in, nullptr, 1);
    } catch (const Error &e) {
        what = e.what();
    }
    set_image_memory_budget(saved);
    EXPECT_NE(what.find("ripmap.exr: part 0: its ripmap levels need"), std::string::npos) << what;
    // Read in part (the colour alone), it stays a ripmap: its levels are made again.
    const std::set<std::string> color_only = {"color"};
    write_exr(read_frame(in, &color_only, 1), out_path("ripmap_color"), {});
    Imf::TiledInputFile part(out_path("ripmap_color").c_str());
    EXPECT_EQ(part.header().tileDescription().mode, Imf::RIPMAP_LEVELS);
    EXPECT_EQ(part.numXLevels(), 6);
    EXPECT_EQ(part.numYLevels(), 5);
}

TEST(ExrFidelity, ViewsComeFromOneEye)
{
    const std::string path = entry("stereo_multipart").path;
    const FileInfo info = read_file_info(path);
    EXPECT_EQ(info.views, (std::vector<std::string>{"left", "right"}));
    EXPECT_EQ(info.view, "left");
    ReadOptions right;
    right.view = "right";
    const Frame l = read_frame(path, nullptr, 1);
    const Frame r = read_frame(path, nullptr, 1, right);
    // Every canonical pass of the right view comes from the right view's parts: the default
    // frame's color@right and depth@right are the right frame's color and depth.
    ASSERT_TRUE(l.has("color@right"));
    ASSERT_TRUE(l.has("depth@right"));
    EXPECT_TRUE(l.image("color@right").bit_equal(r.image("color")));
    EXPECT_TRUE(l.image("depth@right").bit_equal(r.image("depth")));
    EXPECT_TRUE(r.image("color@left").bit_equal(l.image("color")));
    EXPECT_FALSE(l.image("color").bit_equal(r.image("color")));
    // Written from the right view, the file is still the same file.
    write_exr(r, out_path("stereo_right"), {});
    EXPECT_EQ(corpus::compare_exr(path, out_path("stereo_right")), "");
    // Single-part multi-view: right.R is the right view's R.
    const std::string sp = entry("stereo_singlepart").path;
    const Frame sr = read_frame(sp, nullptr, 1, right);
    const Frame sl = read_frame(sp, nullptr, 1);
    EXPECT_TRUE(sl.image("color@right").bit_equal(sr.image("color")));
    EXPECT_FALSE(sl.image("color").bit_equal(sr.image("color")));
}

/// Channel names of every part of `path`, through OpenEXR.
std::vector<std::string> all_channel_names(const std::string &path)
{
    std::vector<std::string> names;
    Imf::MultiPartInputFile in(path.c_str());
    for (int p = 0; p < in.parts(); ++p) {
        const Imf::ChannelList &cl = in.header(p).channels();
        for (auto it = cl.begin(); it != cl.end(); ++it) {
            names.push_back(it.name());
        }
    }
    return names;
}

/// The world-to-camera matrix of a view of stereo_cameras(): the right eye 0.5 right of the left.
glm::mat4 stereo_world_to_camera(const std::string &view)
{
    glm::mat4 m(1.0f);
    m[3][2] = 4.0f;
    m[3][0] = view == "right" ? -0.5f : 0.0f;
    return m;
}

/// The corpus's multi-part stereo file with a camera per view (stereo_world_to_camera and a
/// worldToNDC of each), written once.
const std::string &stereo_cameras()
{
    static const std::string kPath = [] {
        const std::string path = scratch() + "/stereo_cameras.exr";
        Imf::MultiPartInputFile in(entry("stereo_multipart").path.c_str());
        std::vector<Imf::Header> headers;
        for (int p = 0; p < in.parts(); ++p) {
            headers.push_back(in.header(p));
            const glm::mat4 w2c = stereo_world_to_camera(headers.back().view());
            glm::mat4 proj(0.0f);  // a perspective frustum onto NDC [0,1]^2
            proj[0][0] = 0.8f;
            proj[1][1] = -1.0f;
            proj[2][0] = proj[2][1] = 0.5f;
            proj[2][3] = 1.0f;
            proj[3][2] = -0.1f;
            const glm::mat4 w2ndc = proj * w2c;
            Imath::M44f a, b;  // Imath's [i][j] is GLM's [i][j]: the same memory
            for (int i = 0; i < 4; ++i) {
                for (int j = 0; j < 4; ++j) {
                    a[i][j] = w2c[i][j];
                    b[i][j] = w2ndc[i][j];
                }
            }
            Imf::addWorldToCamera(headers.back(), a);
            Imf::addWorldToNDC(headers.back(), b);
        }
        Imf::MultiPartOutputFile out(path.c_str(), headers.data(), int(headers.size()));
        for (int p = 0; p < in.parts(); ++p) {
            Imf::InputPart from(in, p);
            Imf::OutputPart(out, p).copyPixels(from);
        }
        return path;
    }();
    return kPath;
}

TEST(ExrFidelity, RebuiltLayoutsKeepTheViews)
{
    const std::string path = stereo_cameras();
    for (const char *source : {"stereo_cameras", "stereo_singlepart"}) {
        const std::string in_path =
            source == std::string("stereo_cameras") ? path : entry("stereo_singlepart").path;
        for (const char *chosen : {"left", "right"}) {
            ReadOptions pick;
            pick.view = chosen;
            const Frame f = read_frame(in_path, nullptr, 1, pick);
            for (const ExrLayout layout : {ExrLayout::Single, ExrLayout::Multipart}) {
                const bool single = layout == ExrLayout::Single;
                SCOPED_TRACE(std::string(source) + ", read as " + chosen + ", " +
                             (single ? "single" : "multipart"));
                WriteOptions o;
                o.layout = layout;
                const std::string out = out_path(std::string("views_") + source + "_" + chosen +
                                                 (single ? "_single" : "_multipart"));
                write_exr(f, out, o);
                // The views come back in the file's order, under OpenEXR's names (no "@").
                const FileInfo info = read_file_info(out);
                EXPECT_EQ(info.views, (std::vector<std::string>{"left", "right"}));
                for (const std::string &n : all_channel_names(out)) {
                    EXPECT_EQ(n.find('@'), std::string::npos) << n;
                }
                for (const char *view : {"left", "right"}) {
                    ReadOptions v;
                    v.view = view;
                    const Frame a = read_frame(in_path, nullptr, 1, v);
                    const Frame b = read_frame(out, nullptr, 1, v);
                    for (const std::string pass : {"color", "depth"}) {
                        ASSERT_TRUE(b.has(pass)) << view << " " << pass;
                        EXPECT_TRUE(a.image(pass).bit_equal(b.image(pass))) << view << " " << pass;
                    }
                    // Each view's part keeps its view's camera where the layout has a part per
                    // view; one part has one header, its default view's (the bare channels').
                    if (in_path == path) {
                        const std::string camera_view = single ? "left" : view;
                        ASSERT_TRUE(b.camera.world_to_camera) << view;
                        EXPECT_EQ(*b.camera.world_to_camera, stereo_world_to_camera(camera_view))
                            << view;
                    }
                }
            }
        }
    }
}

// A node that moves pixels moves every view's camera: the left frame's right camera after the
// node is the camera the node gives the right frame, and a write puts it into the right parts.
TEST(ExrFidelity, GeometryNodesMoveEveryViewsCamera)
{
    const std::string &path = stereo_cameras();
    ReadOptions right;
    right.view = "right";
    const Frame l = read_frame(path, nullptr, 1);
    const Frame r = read_frame(path, nullptr, 1, right);
    ASSERT_EQ(l.view_cameras.count("right"), 1u);
    EXPECT_EQ(l.view_cameras.at("right"), r.camera);
    const std::pair<const char *, const char *> cases[] = {
        {"transform", R"({"scale": 2, "translate_x": 3})"},
        {"transform", R"({"rotate": 30, "filter": "nearest"})"},
        {"crop", R"({"box": [4, 2, 20, 16], "reformat": true})"},
        {"crop", R"({"box": [-8, 0, 40, 24], "crop_data": false})"}};
    for (const auto &[node, params] : cases) {
        SCOPED_TRACE(std::string(node) + " " + params);
        const Frame lo = test::run_node(node, l, params);
        const Frame ro = test::run_node(node, r, params);
        ASSERT_TRUE(lo.camera.world_to_ndc && l.camera.world_to_ndc);
        EXPECT_NE(*lo.camera.world_to_ndc, *l.camera.world_to_ndc);  // the node moved it
        ASSERT_EQ(lo.view_cameras.count("right"), 1u);
        EXPECT_EQ(lo.view_cameras.at("right"), ro.camera);
        const std::string out = out_path(std::string("views_moved_") + node);
        write_exr(lo, out, {});
        EXPECT_EQ(read_frame(out, nullptr, 1, right).camera, ro.camera);
        EXPECT_EQ(read_frame(out, nullptr, 1).camera, lo.camera);
    }
}

// A renumbered frame's number goes to every view's parts (only the chosen view's had it).
TEST(ExrFidelity, EveryViewsPartsTakeTheFramesNumber)
{
    Frame f = read_frame(entry("stereo_multipart").path, nullptr, 1);
    f.number = 12;
    const std::string out = out_path("views_numbered");
    write_exr(f, out, {});
    Imf::MultiPartInputFile in(out.c_str());
    ASSERT_GT(in.parts(), 2);
    for (int p = 0; p < in.parts(); ++p) {
        const auto *n = in.header(p).findTypedAttribute<Imf::IntAttribute>("frameNumber");
        ASSERT_NE(n, nullptr) << "part " << p;
        EXPECT_EQ(n->value(), 12) << "part " << p;
    }
}

TEST(ExrFidelity, LuminanceChromaReadsAsRgb)
{
    const corpus::Entry &e = entry("luma_chroma");
    const corpus::Rgba expected = corpus::rgba_of(e.path);
    const Frame f = read_frame(e.path, nullptr, 1);
    const Image &c = f.image("color");
    ASSERT_EQ(c.width(), expected.width);
    ASSERT_EQ(c.height(), expected.height);
    EXPECT_EQ(f.data_window.x0, expected.x0);
    for (int y = 0; y < c.height(); ++y) {
        for (int x = 0; x < c.width(); ++x) {
            for (int k = 0; k < 4; ++k) {
                ASSERT_EQ(
                    c.at(x, y, k),
                    expected.rgba[(std::size_t(y) * std::size_t(c.width()) + std::size_t(x)) * 4 +
                                  std::size_t(k)])
                    << x << "," << y << "," << k;
            }
        }
    }
    // Its header's attributes and the camera's aperture come with it, and go out again.
    EXPECT_EQ(f.camera.fstop, 2.8f);
    ASSERT_NE(f.attributes.find_pv("comments"), nullptr);
    EXPECT_EQ(f.attributes.find_pv("comments")->get_string(), "luma comments");
    // Written back as RGBA half: the same values.
    write_exr(f, out_path("luma_chroma_rgb"), {});
    EXPECT_TRUE(read_frame(out_path("luma_chroma_rgb"), nullptr, 1).image("color").bit_equal(c));
    {
        Imf::InputFile in(out_path("luma_chroma_rgb").c_str());
        const Imf::Header &h = in.header();
        EXPECT_NE(h.findTypedAttribute<Imf::StringAttribute>("comments"), nullptr);
        EXPECT_NE(h.findTypedAttribute<Imf::TimeCodeAttribute>("timeCode"), nullptr);
        EXPECT_NE(h.findTypedAttribute<Imf::FloatAttribute>("aperture"), nullptr);
        EXPECT_NE(h.findTypedAttribute<Imf::DoubleAttribute>("studio:double"), nullptr);
    }
    // Luminance only: one channel Y, gray for the nodes, Y again when written.
    const Frame y = read_frame(entry("y_only").path, nullptr, 1);
    EXPECT_EQ(y.image("color").at(3, 2, 0), y.image("color").at(3, 2, 2));
}

namespace {
std::vector<std::string> channel_list(const std::string &path)
{
    Imf::InputFile in(path.c_str());
    std::vector<std::string> names;
    for (auto it = in.header().channels().begin(); it != in.header().channels().end(); ++it) {
        names.push_back(it.name());
    }
    return names;
}
}  // namespace

// A luminance-only file read as gray RGB goes back to its Y channel when a node left it gray
// (an exposure, a blur), in every layout; it went out as R, G, B once a node touched it. A node
// that makes it coloured writes R, G and B.
TEST(ExrFidelity, LuminanceStaysLuminanceThroughANode)
{
    const Frame in = read_frame(entry("y_only").path, nullptr, 1);
    Frame doubled = in, tinted = in;
    Image twice = in.image("color"), tint = in.image("color");
    for (int y = 0; y < twice.height(); ++y) {
        for (int x = 0; x < twice.width(); ++x) {
            for (int k = 0; k < 3; ++k) {
                twice.at(x, y, k) *= 2.0f;
                tint.at(x, y, k) *= k == 0 ? 1.0f : 0.5f;
            }
        }
    }
    doubled.set("color", twice);
    tinted.set("color", tint);
    for (const ExrLayout layout : {ExrLayout::Auto, ExrLayout::Single, ExrLayout::Multipart}) {
        SCOPED_TRACE(int(layout));
        WriteOptions o;
        o.layout = layout;
        const std::string out = scratch() + "/y_doubled.exr";
        write_exr(doubled, out, o);
        EXPECT_EQ(channel_list(out), (std::vector<std::string>{"Y"}));
        const Image back = read_frame(out, nullptr, 1).image("color");
        EXPECT_EQ(back.at(3, 2, 1), 2.0f * in.image("color").at(3, 2, 1));
        EXPECT_TRUE(back.bit_equal(twice));
        write_exr(tinted, out, o);
        EXPECT_EQ(channel_list(out), (std::vector<std::string>{"B", "G", "R"}));
    }
}

// Exif metadata in an EXR header (oiiotool keeps its command history as Exif:ImageHistory) is
// the file's own: it comes through a rebuilt layout and shows in the frame's attributes, and
// `info` prints it on one line.
TEST(ExrFidelity, AnExrsExifAttributesComeThrough)
{
    const std::string src = scratch() + "/exif.exr";
    {
        Frame f;
        Image c(4, 2, 4);
        c.fill(0.5f);
        f.set("color", c);
        f.attributes.push_back(OIIO::ParamValue("Exif:ImageHistory", "graded\ttwice\nby hand"));
        write_exr(f, src, {});
    }
    const Frame f = read_frame(src, nullptr, 1);
    const OIIO::ParamValue *p = f.attributes.find_pv("Exif:ImageHistory");
    ASSERT_NE(p, nullptr);
    EXPECT_EQ(p->get_string(), "graded\ttwice\nby hand");
    WriteOptions o;
    o.layout = ExrLayout::Multipart;
    write_exr(f, out_path("exif_rebuilt"), o);
    Imf::InputFile in(out_path("exif_rebuilt").c_str());
    const auto *a = in.header().findTypedAttribute<Imf::StringAttribute>("Exif:ImageHistory");
    ASSERT_NE(a, nullptr);
    EXPECT_EQ(a->value(), "graded\ttwice\nby hand");
    std::string log;
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + src, &log), 0) << log;
    EXPECT_NE(log.find("  Exif:ImageHistory  string = graded\\ttwice\\nby hand\n"),
              std::string::npos)
        << log;
}

TEST(ExrFidelity, DeepFilesFlattenFrontToBack)
{
    for (const char *name : {"deep_scanline", "deep_tiled"}) {
        SCOPED_TRACE(name);
        const corpus::Entry &e = entry(name);
        const corpus::Flat expected = corpus::flatten_deep(e.path);
        const Frame f = read_frame(e.path, nullptr, 1);
        const Image &c = f.image("color"), &z = f.image("depth");
        ASSERT_EQ(c.width(), expected.width);
        ASSERT_EQ(f.data_window.x0, expected.x0);
        ASSERT_EQ(f.data_window.y0, expected.y0);
        for (int y = 0; y < c.height(); ++y) {
            for (int x = 0; x < c.width(); ++x) {
                const float *ex =
                    &expected.rgbaz[(std::size_t(y) * std::size_t(c.width()) + std::size_t(x)) * 5];
                for (int k = 0; k < 4; ++k) {
                    ASSERT_NEAR(c.at(x, y, k), ex[k], 1e-6f) << x << "," << y << "," << k;
                }
                ASSERT_EQ(z.at(x, y, 0), ex[4]) << x << "," << y;
            }
        }
        ReadOptions refuse;
        refuse.deep = DeepMode::Error;
        try {
            read_frame(e.path, nullptr, 1, refuse);
            ADD_FAILURE() << "deep: error accepted a deep file";
        } catch (const Error &err) {
            EXPECT_NE(std::string(err.what()).find("deep"), std::string::npos) << err.what();
        }
    }
}

TEST(ExrFidelity, BadViewAndAbsurdWindowsAreOneLineErrors)
{
    ReadOptions o;
    o.view = "middle";
    try {
        read_frame(entry("stereo_multipart").path, nullptr, 1, o);
        ADD_FAILURE() << "unknown view accepted";
    } catch (const Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("no view \"middle\""), std::string::npos) << m;
        EXPECT_NE(m.find("left, right"), std::string::npos) << m;
        EXPECT_EQ(m.find('\n'), std::string::npos);
    }
    o.view = "left";
    EXPECT_THROW(read_frame(entry("window_inside").path, nullptr, 1, o), Error);  // no views

    // A header whose data window is absurd: patch the dataWindow attribute of a tiny file.
    const std::string path = out_path("absurd");
    {
        Frame f;
        f.set("color", Image(4, 4, 4));
        write_exr(f, path, {});
    }
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string key = std::string("dataWindow\0box2i\0", 17);
    const auto at = bytes.find(key);
    ASSERT_NE(at, std::string::npos);
    const std::int32_t huge[4] = {0, 0, 200000, 3};  // xmax far beyond the limit
    std::memcpy(&bytes[at + key.size() + 4], huge, sizeof(huge));
    std::ofstream(path, std::ios::binary) << bytes;
    try {
        read_frame(path, nullptr, 1);
        ADD_FAILURE() << "absurd window accepted";
    } catch (const Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("absurd"), std::string::npos) << m;  // the file
        EXPECT_NE(m.find("part 0"), std::string::npos) << m;
        EXPECT_NE(m.find("200001"), std::string::npos) << m;
    }
}

// Every node on a frame whose data window is offset from the display window and larger than it
// gives the pixels it gives on the same data placed at the origin (with the camera seen from the
// data window), and keeps both windows.
namespace {
/// Every part's view and channels with their pixel types, in file order.
std::vector<std::string> part_layout(const std::string &path)
{
    Imf::MultiPartInputFile in(path.c_str());
    std::vector<std::string> out;
    for (int p = 0; p < in.parts(); ++p) {
        const Imf::Header &h = in.header(p);
        std::string line = h.hasView() ? h.view() + ":" : ":";
        for (auto it = h.channels().begin(); it != h.channels().end(); ++it) {
            line += std::string(" ") + it.name() + "/" + std::to_string(int(it.channel().type));
        }
        out.push_back(line);
    }
    return out;
}
}  // namespace

// lens resamples every pass; a write then puts each back where it came from (its part, view,
// name and pixel type), as transform does. It cleared the frame's passes first, so they all
// went out under canonical names: a stereo file's right eye as "color@right.R", float colour
// as half, a second part's Z as "subimage01.Z". A uint id channel moved by the nearest pixel
// stays uint (it went out as float), and the vignette leaves alpha alone (it darkened it).
TEST(ExrFidelity, LensKeepsTheFilesLayout)
{
    constexpr auto npos = std::string::npos;
    for (const char *name : {"stereo_singlepart", "stereo_multipart", "types_mixed"}) {
        for (const char *params : {R"({"vignette": 0.5})", R"({"k1": 0.1})"}) {
            SCOPED_TRACE(std::string(name) + " " + params);
            const Frame in = read_frame(entry(name).path, nullptr, 1);
            const Frame out = test::run_node("lens", in, params);
            EXPECT_FALSE(out.image("color").bit_equal(in.image("color")));
            if (std::string(params).find("vignette") != npos) {
                const Image &a = in.image("color"), &b = out.image("color");
                for (std::size_t i = 0; i < a.pixel_count(); ++i) {
                    ASSERT_EQ(a.data()[i * 4 + 3], b.data()[i * 4 + 3]) << i;
                }
            }
            const std::string path = out_path(std::string("lens_") + name);
            write_exr(out, path, {});
            std::vector<std::string> expected = part_layout(entry(name).path);
            if (std::string(name) == "types_mixed" && std::string(params).find("k1") != npos) {
                // The window grew: the pixels outside the source have no coverage, so the RGB
                // file's alpha (1 where the reader made it up) is written, as half as colour.
                expected = {": A/1 B/1 G/1 R/1 depth.Z/2 id/0"};
            }
            EXPECT_EQ(part_layout(path), expected);
        }
    }
}

// A rebuilt layout names channels anew, but storage "auto" keeps each channel's pixel type
// (half masks and colour, a uint id) and compression "auto" the source part's (they went out
// as float, and as piz); a part without a view stays without one whichever view is read.
TEST(ExrFidelity, RebuiltLayoutsKeepTypesCompressionAndViewlessParts)
{
    const auto compressions = [](const std::string &path) {
        std::set<int> out;
        Imf::MultiPartInputFile in(path.c_str());
        for (int p = 0; p < in.parts(); ++p) {
            out.insert(int(in.header(p).compression()));
        }
        return out;
    };
    for (const ExrLayout layout : {ExrLayout::Single, ExrLayout::Multipart}) {
        const bool single = layout == ExrLayout::Single;
        WriteOptions o;
        o.layout = layout;
        const std::string mixed = out_path(single ? "types_single" : "types_multipart");
        write_exr(read_frame(entry("types_mixed").path, nullptr, 1), mixed, o);
        const std::vector<std::string> want =
            single ? std::vector<std::string>{": B/1 G/1 R/1 Z/2 id/0"}
                   : std::vector<std::string>{": B/1 G/1 R/1", ": Z/2", ": id/0"};
        EXPECT_EQ(part_layout(mixed), want);
        EXPECT_EQ(compressions(mixed), compressions(entry("types_mixed").path));
    }
    // The stereo file with a part "matte" that has no view.
    const std::string path = scratch() + "/stereo_matte.exr";
    {
        Imf::MultiPartInputFile in(entry("stereo_multipart").path.c_str());
        std::vector<Imf::Header> headers;
        for (int p = 0; p < in.parts(); ++p) {
            headers.push_back(in.header(p));
        }
        Imf::Header matte(headers[0].displayWindow(), headers[0].dataWindow());
        matte.channels().insert("Y", Imf::Channel(Imf::HALF));
        matte.setName("matte");
        matte.setType(Imf::SCANLINEIMAGE);
        headers.push_back(matte);
        Imf::MultiPartOutputFile out(path.c_str(), headers.data(), int(headers.size()));
        for (int p = 0; p < in.parts(); ++p) {
            Imf::InputPart from(in, p);
            Imf::OutputPart(out, p).copyPixels(from);
        }
        const Imath::Box2i dw = matte.dataWindow();
        const int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
        std::vector<half> y(std::size_t(w) * std::size_t(h), half(0.75f));
        Imf::FrameBuffer fb;
        fb.insert("Y",
                  Imf::Slice(Imf::HALF,
                             reinterpret_cast<char *>(y.data() - dw.min.x - dw.min.y * w),
                             sizeof(half),
                             sizeof(half) * std::size_t(w)));
        Imf::OutputPart part(out, int(headers.size()) - 1);
        part.setFrameBuffer(fb);
        part.writePixels(h);
    }
    for (const char *chosen : {"left", "right"}) {
        ReadOptions pick;
        pick.view = chosen;
        WriteOptions o;
        o.layout = ExrLayout::Multipart;
        const std::string out = out_path(std::string("matte_") + chosen);
        write_exr(read_frame(path, nullptr, 1, pick), out, o);
        std::vector<std::string> layout = part_layout(out);
        std::sort(layout.begin(), layout.end());
        EXPECT_EQ(layout,
                  (std::vector<std::string>{": Y/1",
                                            "left: A/1 B/1 G/1 R/1",
                                            "left: Z/2",
                                            "left: motion_next.X/2 motion_next.Y/2",
                                            "left: whitebarmask.mask/1",
                                            "right: A/1 B/1 G/1 R/1",
                                            "right: Z/2",
                                            "right: motion_next.X/2 motion_next.Y/2",
                                            "right: whitebarmask.mask/1"}))
            << chosen;
    }
}

// A node that spreads a pass beyond its part's window (a blur of colour into the overscan the
// motion part covers) widens that part to the frame's data window: the values there were cut
// away. A part whose pass stays inside keeps its window.
TEST(ExrFidelity, APassSpreadBeyondItsPartWidensThePart)
{
    const corpus::Entry &e = entry("multipart_layers");
    const Frame in = read_frame(e.path, nullptr, 1);
    const FileInfo before = read_file_info(e.path);
    ASSERT_NE(before.parts[0].data_window, in.data_window);
    const Frame blurred = test::run_node("blur", in, R"({"sigma": 3, "passes": "color"})");
    const std::string out = out_path("spread");
    write_exr(blurred, out, {});
    const FileInfo after = read_file_info(out);
    EXPECT_EQ(after.parts[0].data_window, in.data_window);
    EXPECT_EQ(after.parts[1].data_window, before.parts[1].data_window);  // depth: untouched
    const Frame back = read_frame(out, nullptr, 1);
    const Rect &rgba = before.parts[0].data_window;
    const int x = rgba.x0 - 1 - in.data_window.x0, y = rgba.y0 + 5 - in.data_window.y0;
    const float want = blurred.image("color").at(x, y, 0);
    ASSERT_GT(want, 0.0f);
    EXPECT_NEAR(back.image("color").at(x, y, 0), want, want * 1e-3f);  // stored as half
}

// A widened part keeps an untouched uint id beyond 2^24 as the file had it (inside its old
// window; zero beyond it, as read): it was written from the float pass, which rounds such ids.
TEST(ExrFidelity, AWidenedPartKeepsItsUintIds)
{
    const std::string path = scratch() + "/widened_uint.exr";
    const Imath::Box2i display({0, 0}, {31, 23});
    const Imath::Box2i inner({8, 6}, {23, 17});
    const int w = inner.max.x - inner.min.x + 1, h = inner.max.y - inner.min.y + 1;
    std::vector<std::uint32_t> ids(std::size_t(w) * std::size_t(h));
    for (std::size_t i = 0; i < ids.size(); ++i) {
        ids[i] = (1u << 24) + 1u + 2u * std::uint32_t(i);  // odd: no float holds them
    }
    {
        Imf::Header rgb(display, inner);
        rgb.setName("rgb");
        rgb.setType(Imf::SCANLINEIMAGE);
        for (const char *c : {"R", "G", "B", "id"}) {
            rgb.channels().insert(c, Imf::Channel(c[0] == 'i' ? Imf::UINT : Imf::FLOAT));
        }
        Imf::Header depth(display, display);
        depth.setName("depth");
        depth.setType(Imf::SCANLINEIMAGE);
        depth.channels().insert("Z", Imf::Channel(Imf::FLOAT));
        std::vector<Imf::Header> headers{rgb, depth};
        Imf::MultiPartOutputFile out(path.c_str(), headers.data(), int(headers.size()));
        std::vector<float> color(std::size_t(w) * std::size_t(h), 0.5f);
        color[std::size_t(h / 2) * std::size_t(w)] = 40.0f;  // a bright pixel at the left edge
        const std::ptrdiff_t origin = std::ptrdiff_t(inner.min.x) + std::ptrdiff_t(inner.min.y) * w;
        Imf::FrameBuffer fb;
        for (const char *c : {"R", "G", "B"}) {
            fb.insert(c,
                      Imf::Slice(Imf::FLOAT,
                                 reinterpret_cast<char *>(color.data() - origin),
                                 sizeof(float),
                                 sizeof(float) * std::size_t(w)));
        }
        fb.insert("id",
                  Imf::Slice(Imf::UINT,
                             reinterpret_cast<char *>(ids.data() - origin),
                             sizeof(std::uint32_t),
                             sizeof(std::uint32_t) * std::size_t(w)));
        Imf::OutputPart part0(out, 0);
        part0.setFrameBuffer(fb);
        part0.writePixels(h);
        const int dw = display.max.x + 1, dh = display.max.y + 1;
        std::vector<float> z(std::size_t(dw) * std::size_t(dh), 3.0f);
        Imf::FrameBuffer zb;
        zb.insert("Z",
                  Imf::Slice(Imf::FLOAT,
                             reinterpret_cast<char *>(z.data()),
                             sizeof(float),
                             sizeof(float) * std::size_t(dw)));
        Imf::OutputPart part1(out, 1);
        part1.setFrameBuffer(zb);
        part1.writePixels(dh);
    }
    const Frame blurred =
        test::run_node("blur", read_frame(path, nullptr, 1), R"({"sigma": 2, "passes": "color"})");
    const std::string out = out_path("widened_uint");
    write_exr(blurred, out, {});
    const FileInfo after = read_file_info(out);
    ASSERT_EQ(after.parts[0].data_window, (Rect{0, 0, 32, 24}));  // widened
    const Rect old{inner.min.x, inner.min.y, inner.max.x + 1, inner.max.y + 1};
    EXPECT_EQ(read_uint_channel(out, "id", old), ids);
    const std::vector<std::uint32_t> beyond = read_uint_channel(out, "id", Rect{0, 0, 32, 6});
    EXPECT_TRUE(std::all_of(beyond.begin(), beyond.end(), [](std::uint32_t v) { return v == 0; }));
}

// A renamed or copied pass is written as the file held it: half colour renamed "beauty" stays
// half (it went out as float, the default of a new name), float depth renamed "albedo" stays
// float (albedo's default is half). Four channels renamed "depth" are refused: depth is the
// bare Z, and R, G, B, A under it read back as colour.
TEST(ExrFidelity, ARenamedPassKeepsItsPixelType)
{
    const Frame in = read_frame(entry("types_mixed").path, nullptr, 1);
    const Frame out = test::run_node(
        "channels",
        in,
        R"({"rename": {"color": "beauty", "depth": "albedo"}, "copy": {"z2": "depth"}})");
    const std::string path = out_path("renamed_types");
    write_exr(out, path, {});
    EXPECT_EQ(
        part_layout(path),
        (std::vector<std::string>{": albedo.Z/2 beauty.B/1 beauty.G/1 beauty.R/1 id/0 z2.Z/2"}));
    try {
        test::run_node("channels", in, R"({"rename": {"color": "depth"}})");
        ADD_FAILURE() << "four channels renamed depth";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find(
                      R"(rename "color" -> "depth": depth has one channel (Z), "color" has 4)"),
                  std::string::npos)
            << e.what();
    }
}

TEST(ExrFidelity, NodesWorkInTheDataWindow)
{
    const int w = 61, h = 37;
    Frame base = test::make_sample_frame(w, h, 3);
    Image tangent(w, h, 3);
    for (std::size_t i = 0; i < tangent.pixel_count(); ++i) {
        tangent.data()[i * 3] = 1.0f;
    }
    base.set("tangent", std::move(tangent));
    base.camera.prev_world_to_camera = base.camera.world_to_camera;
    base.camera.prev_world_to_ndc = base.camera.world_to_ndc;
    Frame offset = base;
    offset.data_window = {-7, -4, w - 7, h - 4};
    offset.display_window = {0, 0, w - 14, h - 9};
    Frame origin = base;
    origin.camera = offset.pixel_camera();  // what the data window's pixels see
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"dof", "{}"},
        {"motion_blur", "{}"},
        {"motion_blur", R"({"source": "camera"})"},
        {"fog", R"({"model": "exp", "density": 0.05})"},
        {"fog", R"({"model": "height"})"},
        {"relight", R"({"lights": [{"type": "point", "position": [0, 3, 0], "intensity": 20}]})"},
        {"hatching", "{}"},
        {"ocio", R"({"to": "srgb"})"},
        {"channels", R"({"keep": "color"})"},
    };
    for (const auto &[type, params] : cases) {
        SCOPED_TRACE(type + " " + params);
        const Frame a = test::run_node(type, offset, params);
        const Frame b = test::run_node(type, origin, params);
        EXPECT_EQ(a.data_window, offset.data_window);
        EXPECT_EQ(a.display_window, offset.display_window);
        for (const auto &[name, p] : b.passes()) {
            ASSERT_TRUE(a.has(name)) << name;
            EXPECT_TRUE(a.image(name).bit_equal(*p.image)) << name;
        }
    }
    // A preview shows the display window.
    const std::string png = scratch() + "/out/preview_window.png";
    write_preview(place_in_window(offset.image("color"), offset.data_window, offset.display_window),
                  png,
                  false);
    EXPECT_EQ(read_file_info(png).display_window.width(), w - 14);
}

TEST(ExrFidelity, MergeWorksInBsWindow)
{
    Frame b = test::make_sample_frame(16, 8, 1);
    Frame a = test::make_sample_frame(4, 4, 1);
    a.data_window = {10, 2, 14, 6};
    a.display_window = b.display_window;
    Image ones(4, 4, 4);
    ones.fill(1.0f);
    a.set("color", std::move(ones));
    // Over: A is opaque white inside its window, B elsewhere.
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "a", "type": "read", "params": {"path": "a.exr"}},
        {"id": "b", "type": "read", "params": {"path": "b.exr"}},
        {"id": "m", "type": "merge", "inputs": {"a": "a", "b": "b"}, "params": {}},
        {"id": "out", "type": "write", "inputs": {"image": "m"}, "params": {"path": "x.exr"}}]})",
                           "merge windows",
                           nodes::catalog());
    const Frame out =
        g.run_node(g.find("m"),
                   {std::make_shared<const Frame>(b), std::make_shared<const Frame>(a)},
                   {"b", "a"},
                   1);
    EXPECT_EQ(out.data_window, b.data_window);
    const Image &c = out.image("color");
    EXPECT_EQ(c.at(11, 3, 0), 1.0f);
    EXPECT_EQ(c.at(2, 3, 0), b.image("color").at(2, 3, 0));
    EXPECT_EQ(c.at(10, 6, 0), b.image("color").at(10, 6, 0));  // below A's window
}

}  // namespace
}  // namespace posthaste
