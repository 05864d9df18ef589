// Cryptomatte: the hash and its float conversion against published values, the name patterns,
// and mattes keyed from files written the way renderers write them (io/cryptomatte.h,
// nodes/cryptomatte.cpp).

#include "io/cryptomatte.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

using cryptomatte::hex_of;
using cryptomatte::id_of;
using cryptomatte::murmur3_32;
using cryptomatte::name_matches;

// SMHasher's verification values for MurmurHash3_x86_32 (as listed with the reference code).
TEST(Cryptomatte, MurmurHashMatchesPublishedValues)
{
    EXPECT_EQ(murmur3_32("", 0), 0u);
    EXPECT_EQ(murmur3_32("", 1), 0x514E28B7u);
    EXPECT_EQ(murmur3_32("", 0xffffffffu), 0x81F16F39u);
    EXPECT_EQ(murmur3_32(std::string_view("\0\0\0\0", 4), 0), 0x2362F9DEu);
    EXPECT_EQ(murmur3_32("aaaa", 0x9747b28cu), 0x5A97808Au);
    EXPECT_EQ(murmur3_32("aaa", 0x9747b28cu), 0x283E0130u);
    EXPECT_EQ(murmur3_32("aa", 0x9747b28cu), 0x5D211726u);
    EXPECT_EQ(murmur3_32("a", 0x9747b28cu), 0x7FA09EA6u);
    EXPECT_EQ(murmur3_32("Hello, world!", 0x9747b28cu), 0x24884CBAu);
    EXPECT_EQ(murmur3_32("The quick brown fox jumps over the lazy dog", 0x9747b28cu), 0x2FA826CDu);
}

// The specification's example manifest: names and the hex of their float IDs.
TEST(Cryptomatte, IdsMatchTheSpecificationsManifest)
{
    EXPECT_EQ(hex_of(id_of("bunny")), "13851a76");
    EXPECT_EQ(hex_of(id_of("default")), "42c9679f");
    EXPECT_EQ(hex_of(id_of("bunny_porcelain_mat")), "b24b26d4");
}

// The exponent is kept in 1..254: no zero, denormal, infinite or NaN ID.
TEST(Cryptomatte, FloatConversionKeepsTheExponentAwayFromZeroAnd255)
{
    EXPECT_EQ(cryptomatte::bits_of(cryptomatte::id_from_hash(0x00000005u)), 0x00800005u);
    EXPECT_EQ(cryptomatte::bits_of(cryptomatte::id_from_hash(0x7f800000u)), 0x7f000000u);
    EXPECT_EQ(cryptomatte::bits_of(cryptomatte::id_from_hash(0xff800001u)), 0xff000001u);
    EXPECT_EQ(cryptomatte::bits_of(cryptomatte::id_from_hash(0x3f800000u)), 0x3f800000u);
    for (std::uint32_t h = 0; h < 100000; ++h) {
        const float id = cryptomatte::id_from_hash(murmur3_32(std::to_string(h)));
        ASSERT_TRUE(std::isnormal(id)) << h;
    }
}

TEST(Cryptomatte, NamePatterns)
{
    EXPECT_TRUE(name_matches("bunny", "bunny"));
    EXPECT_FALSE(name_matches("bunny", "bunny2"));
    EXPECT_TRUE(name_matches("bun*", "bunny"));
    EXPECT_TRUE(name_matches("*", ""));
    EXPECT_TRUE(name_matches("*ny", "bunny"));
    EXPECT_TRUE(name_matches("b?nny", "bunny"));
    EXPECT_FALSE(name_matches("b?nny", "bnny"));
    EXPECT_TRUE(name_matches("a*b*c", "a_b_b_c"));
    EXPECT_FALSE(name_matches("a*b*c", "a_b_b_d"));
    EXPECT_TRUE(name_matches("star\\*", "star*"));
    EXPECT_FALSE(name_matches("star\\*", "starfish"));
    EXPECT_TRUE(name_matches("what\\?", "what?"));
    EXPECT_FALSE(name_matches("what\\?", "whatz"));
    EXPECT_TRUE(name_matches("floor[1]", "floor[1]"));  // brackets are literal
    EXPECT_FALSE(name_matches("floor[1]", "floor1"));
    // `?` is one UTF-8 character, and a `*` ends between characters.
    EXPECT_TRUE(name_matches("?n\u00ef", "\u00fcn\u00ef"));
    EXPECT_FALSE(name_matches("??n\u00ef", "\u00fcn\u00ef"));
    EXPECT_TRUE(name_matches("*?", "\u00fc"));
    EXPECT_TRUE(name_matches("*\u00ef", "\u00fcn\u00ef"));
    EXPECT_TRUE(name_matches("a?c", "a\U0001F600c"));
    EXPECT_TRUE(cryptomatte::has_wildcard("a*"));
    EXPECT_FALSE(cryptomatte::has_wildcard("a\\*"));
    EXPECT_EQ(cryptomatte::unescape("star\\*\\\\"), "star*\\");
}

/// One pixel's ranks: (name, coverage), most coverage first.
using Ranks = std::vector<std::pair<std::string, float>>;

struct CryptoFile {
    std::string layer = "CryptoObject";  ///< the layers' prefix
    int rank_layers = 2;
    bool half_ids = false;
    bool manifest = true;
    std::string sidecar;  ///< the manifest in this file beside the image (manif_file) instead
    std::string hash = "MurmurHash3_32";
    std::vector<int> skip_layers;  ///< rank layers left out
};

/// A 4x2 EXR as a renderer writes it: color, the rank layers and the header declaration.
std::string write_crypto_file(const std::string &path,
                              const CryptoFile &cf,
                              const std::vector<Ranks> &pixels,
                              const std::vector<std::string> &names)
{
    const int w = 4, h = 2;
    std::vector<std::string> channels = {"R", "G", "B", "A"};
    std::vector<int> layers;
    for (int k = 0; k < cf.rank_layers; ++k) {
        if (std::find(cf.skip_layers.begin(), cf.skip_layers.end(), k) == cf.skip_layers.end()) {
            layers.push_back(k);
            for (const char *c : {"R", "G", "B", "A"}) {
                const std::string suffix = {char('0' + k / 10), char('0' + k % 10), '.'};
                channels.push_back(cf.layer + suffix + c);
            }
        }
    }
    OIIO::ImageSpec spec(w, h, int(channels.size()), OIIO::TypeDesc::FLOAT);
    spec.channelnames = channels;
    if (cf.half_ids) {
        spec.channelformats.assign(channels.size(), OIIO::TypeDesc::FLOAT);
        for (std::size_t c = 4; c < channels.size(); ++c) {
            spec.channelformats[c] = OIIO::TypeDesc::HALF;
        }
    }
    const std::string key = hex_of(id_of(cf.layer)).substr(0, 7);
    spec.attribute("cryptomatte/" + key + "/name", cf.layer);
    spec.attribute("cryptomatte/" + key + "/hash", cf.hash);
    spec.attribute("cryptomatte/" + key + "/conversion", "uint32_to_float32");
    if (cf.manifest) {
        nlohmann::json m = nlohmann::json::object();
        for (const std::string &n : names) {
            m[n] = hex_of(id_of(n));
        }
        if (cf.sidecar.empty()) {
            spec.attribute("cryptomatte/" + key + "/manifest", m.dump());
        } else {
            spec.attribute("cryptomatte/" + key + "/manif_file", cf.sidecar);
            std::ofstream(std::filesystem::path(path).parent_path() / cf.sidecar) << m.dump();
        }
    }
    std::vector<float> data(std::size_t(w * h) * channels.size(), 0.0f);
    for (int i = 0; i < w * h; ++i) {
        float *px = data.data() + std::size_t(i) * channels.size();
        px[0] = px[1] = px[2] = 0.5f;
        px[3] = 1.0f;
        const Ranks &r = pixels[std::size_t(i)];
        int slot = 4;
        for (int k : layers) {
            for (int j = 0; j < 2; ++j) {
                const std::size_t rank = std::size_t(2 * k + j);
                if (rank < r.size()) {
                    px[slot + 2 * j] = id_of(r[rank].first);
                    px[slot + 2 * j + 1] = r[rank].second;
                }
            }
            slot += 4;
        }
    }
    auto out = OIIO::ImageOutput::create(path);
    EXPECT_TRUE(out && out->open(path, spec));
    EXPECT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data.data()));
    out->close();
    return path;
}

const std::vector<std::string> kNames = {"bunny", "floor[1]", "star*", "default", "what?"};

/// Every pixel has up to 4 ranks over these names.
std::vector<Ranks> sample_pixels()
{
    return {
        {{"bunny", 1.0f}},
        {{"bunny", 0.5f}, {"floor[1]", 0.3f}, {"star*", 0.2f}},
        {{"floor[1]", 0.6f}, {"default", 0.25f}, {"what?", 0.1f}, {"star*", 0.05f}},
        {},
        {{"star*", 0.75f}, {"bunny", 0.25f}},
        {{"default", 1.0f}},
        {{"what?", 0.4f}, {"bunny", 0.35f}, {"default", 0.15f}, {"floor[1]", 0.1f}},
        {{"floor[1]", 0.9f}, {"bunny", 0.1f}},
    };
}

/// The matte by hand: the coverages of the keyed names, summed in rank order.
std::vector<float> expected_matte(const std::vector<Ranks> &pixels,
                                  const std::set<std::string> &keyed)
{
    std::vector<float> out;
    for (const Ranks &r : pixels) {
        float sum = 0.0f;
        for (const auto &[name, cov] : r) {
            if (keyed.count(name)) {
                sum += cov;
            }
        }
        out.push_back(std::clamp(sum, 0.0f, 1.0f));
    }
    return out;
}

/// The graph read -> cryptomatte with `params`, its output frame (the matte through the
/// planner: the read gets the ranks from the node's request alone).
Frame key(const std::string &path, const std::string &params)
{
    Graph g = Graph::parse(
        R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
            path + R"("}},
        {"id": "key", "type": "cryptomatte", "inputs": {"image": "src"}, "params": )" +
            params +
            R"(},
        {"id": "out", "type": "write", "inputs": {"image": "key"},
         "params": {"path": ")" +
            test::scratch_dir("cryptomatte_key_out") + R"(/out.exr", "passes": ")" +
            (params.find("output") == std::string::npos ? "matte" : "color") + R"("}}]})",
        "cryptomatte test",
        nodes::catalog());
    g.set_capture("key");
    return g.evaluate(1);
}

std::vector<float> values(const Image &img)
{
    return std::vector<float>(img.data(), img.data() + img.value_count());
}

TEST(Cryptomatte, MatteIsTheSummedCoverageOfTheNamesKeyed)
{
    const std::string dir = test::scratch_dir("cryptomatte_keyed");
    const std::vector<Ranks> pixels = sample_pixels();
    const std::string path = write_crypto_file(dir + "/a.exr", CryptoFile{}, pixels, kNames);
    // Names (brackets literal), an escaped wildcard, a pattern over the manifest, an ID.
    EXPECT_EQ(values(key(path, R"({"matte": ["bunny"]})").image("matte")),
              expected_matte(pixels, {"bunny"}));
    EXPECT_EQ(values(key(path, R"({"matte": ["floor[1]", "star\\*"]})").image("matte")),
              expected_matte(pixels, {"floor[1]", "star*"}));
    EXPECT_EQ(values(key(path, R"({"matte": ["what\\?", "d*"]})").image("matte")),
              expected_matte(pixels, {"what?", "default"}));
    EXPECT_EQ(values(key(path, R"({"matte": ["*"]})").image("matte")),
              expected_matte(pixels, {"bunny", "floor[1]", "star*", "default", "what?"}));
    EXPECT_EQ(
        values(
            key(path, R"({"matte": ["<0x)" + hex_of(id_of("default")) + R"(>"]})").image("matte")),
        expected_matte(pixels, {"default"}));
    // A pattern that matches no name keys nothing; so does a name no pixel has, and either
    // says so once, as a name the manifest lacks does.
    testing::internal::CaptureStderr();
    EXPECT_EQ(values(key(path, R"({"matte": ["zebra*", "lion"]})").image("matte")),
              std::vector<float>(8, 0.0f));
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_NE(err.find(R"(matte entry "zebra*" matches no name in the manifest)"),
              std::string::npos)
        << err;
    EXPECT_NE(err.find(R"(matte entry "lion" is no name in the manifest)"), std::string::npos)
        << err;
}

TEST(Cryptomatte, KeyedAndAlphaOutputs)
{
    const std::string dir = test::scratch_dir("cryptomatte_outputs");
    const std::vector<Ranks> pixels = sample_pixels();
    const std::string path = write_crypto_file(dir + "/a.exr", CryptoFile{}, pixels, kNames);
    const std::vector<float> m = expected_matte(pixels, {"bunny"});
    const Image keyed = key(path, R"({"matte": ["bunny"], "output": "keyed"})").image("color");
    const Image alpha = key(path, R"({"matte": ["bunny"], "output": "alpha"})").image("color");
    for (int i = 0; i < 8; ++i) {
        EXPECT_EQ(keyed.data()[4 * i], 0.5f * m[std::size_t(i)]);
        EXPECT_EQ(keyed.data()[4 * i + 3], m[std::size_t(i)]);
        EXPECT_EQ(alpha.data()[4 * i], 0.5f);
        EXPECT_EQ(alpha.data()[4 * i + 3], m[std::size_t(i)]);
    }
}

// The keyable preview: R the first rank's ID, G and B the coverage-weighted viewable colours.
TEST(Cryptomatte, PreviewIsKeyable)
{
    const std::string dir = test::scratch_dir("cryptomatte_preview");
    const std::vector<Ranks> pixels = sample_pixels();
    const std::string path = write_crypto_file(dir + "/a.exr", CryptoFile{}, pixels, kNames);
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               path + R"("}},
        {"id": "key", "type": "cryptomatte", "inputs": {"image": "src"},
         "params": {"matte": ["bunny"], "preview": true}},
        {"id": "out", "type": "write", "inputs": {"image": "key"},
         "params": {"path": ")" +
                               path + R"(.p.exr", "passes": "cryptomatte_preview"}}]})",
                           "preview",
                           nodes::catalog());
    g.set_capture("key");
    const Image p = g.evaluate(1).image("cryptomatte_preview");
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        const Ranks &r = pixels[i];
        EXPECT_EQ(cryptomatte::bits_of(p.data()[3 * i]),
                  r.empty() ? 0u : cryptomatte::bits_of(id_of(r[0].first)));
        float g_sum = 0.0f;
        for (const auto &[name, cov] : r) {
            const std::uint32_t bits = cryptomatte::bits_of(id_of(name));
            g_sum += cov * float(double(std::uint32_t(bits << 8)) / 4294967295.0);
        }
        EXPECT_EQ(p.data()[3 * i + 1], g_sum) << i;
    }
}

// Blender names its layers after the view layer: ViewLayer.CryptoObject00. A name keys without
// a manifest; a pattern does not.
TEST(Cryptomatte, ViewLayerPrefixAndNoManifest)
{
    const std::string dir = test::scratch_dir("cryptomatte_blender");
    const std::vector<Ranks> pixels = sample_pixels();
    CryptoFile cf;
    cf.layer = "ViewLayer.CryptoObject";
    cf.manifest = false;
    const std::string path = write_crypto_file(dir + "/b.exr", cf, pixels, kNames);
    EXPECT_EQ(values(key(path, R"({"layer": "CryptoObject", "matte": ["bunny"]})").image("matte")),
              expected_matte(pixels, {"bunny"}));
    try {
        key(path, R"({"matte": ["bun*"]})");
        FAIL() << "a pattern without a manifest was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("a pattern needs a manifest"), std::string::npos)
            << e.what();
    }
}

// A manifest in a sidecar file (manif_file, relative to the image) serves patterns as one in the
// header does; a sidecar that is missing or not a manifest is named.
TEST(Cryptomatte, SidecarManifest)
{
    const std::string dir = test::scratch_dir("cryptomatte_sidecar");
    const std::vector<Ranks> pixels = sample_pixels();
    CryptoFile cf;
    cf.sidecar = "manifest.json";
    const std::string path = write_crypto_file(dir + "/a.exr", cf, pixels, kNames);
    EXPECT_EQ(values(key(path, R"({"matte": ["flo*"]})").image("matte")),
              expected_matte(pixels, {"floor[1]"}));
    std::filesystem::remove(dir + "/manifest.json");
    try {
        key(path, R"({"matte": ["bunny"]})");
        FAIL() << "a missing sidecar was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("cannot read its manifest file"), std::string::npos)
            << e.what();
    }
    std::ofstream(dir + "/manifest.json") << R"({"bunny": "13851a7"})";
    try {
        key(path, R"({"matte": ["bunny"]})");
        FAIL() << "a malformed sidecar was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("manifest entry \"bunny\": expected 8 hex digits"),
                  std::string::npos)
            << e.what();
    }
}

TEST(Cryptomatte, FilesThatBreakTheSpecificationAreNamed)
{
    const std::string dir = test::scratch_dir("cryptomatte_bad");
    const std::vector<Ranks> pixels = sample_pixels();
    const auto error_of = [&](const CryptoFile &cf, const std::string &params) {
        const std::string path = write_crypto_file(dir + "/bad.exr", cf, pixels, kNames);
        try {
            key(path, params);
        } catch (const Error &e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    CryptoFile hash;
    hash.hash = "md5";
    EXPECT_NE(error_of(hash, R"({"matte": ["bunny"]})")
                  .find("cryptomatte \"CryptoObject\": hash \"md5\" (only MurmurHash3_32"),
              std::string::npos);
    CryptoFile gap;
    gap.rank_layers = 3;
    gap.skip_layers = {1};
    EXPECT_NE(error_of(gap, R"({"matte": ["bunny"]})")
                  .find("has rank layer CryptoObject02 but not CryptoObject01"),
              std::string::npos);
    CryptoFile half;
    half.half_ids = true;
    EXPECT_NE(error_of(half, R"({"matte": ["bunny"]})").find("holds its IDs as half floats"),
              std::string::npos);
    EXPECT_NE(error_of(CryptoFile{}, R"({"layer": "CryptoMaterial", "matte": ["bunny"]})")
                  .find("no cryptomatte \"CryptoMaterial\" in the frame (have: CryptoObject)"),
              std::string::npos);
}

// `info` lists each cryptomatte with its ranks and manifest; a file that breaks the
// specification says why.
TEST(Cryptomatte, InfoListsEachCryptomatte)
{
    const std::string dir = test::scratch_dir("cryptomatte_info");
    write_crypto_file(dir + "/a.exr", CryptoFile{}, sample_pixels(), kNames);
    std::string out;
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + dir + "/a.exr", &out), 0)
        << out;
    EXPECT_NE(out.find("cryptomatte        CryptoObject (key " +
                       hex_of(id_of("CryptoObject")).substr(0, 7) +
                       "): 2 rank layers (4 ranks), manifest of 5 names (header)"),
              std::string::npos)
        << out;
    CryptoFile gap;
    gap.rank_layers = 3;
    gap.skip_layers = {0};
    write_crypto_file(dir + "/b.exr", gap, sample_pixels(), kNames);
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + dir + "/b.exr", &out), 0)
        << out;
    EXPECT_NE(out.find("cryptomatte        invalid: "), std::string::npos) << out;
    EXPECT_NE(out.find("has rank layer CryptoObject02 but not CryptoObject00"), std::string::npos)
        << out;
}

// A multi-part file that declares its cryptomatte only in the header of the part holding the
// rank layers (as a compositor splitting layers into parts writes it): keyed, listed by info,
// and written back with the declaration in that part alone. It was invisible: only the first
// part's header was searched.
TEST(Cryptomatte, DeclaredOnlyInTheRankLayersPart)
{
    const std::string dir = test::scratch_dir("cryptomatte_part");
    const std::vector<Ranks> pixels = sample_pixels();
    const std::string single = write_crypto_file(dir + "/one.exr", CryptoFile{}, pixels, kNames);
    const std::string path = dir + "/parts.exr";
    {
        auto in = OIIO::ImageInput::open(single);
        ASSERT_TRUE(in);
        const OIIO::ImageSpec &all = in->spec();
        std::vector<float> data(std::size_t(all.image_pixels()) * std::size_t(all.nchannels));
        ASSERT_TRUE(in->read_image(0, 0, 0, all.nchannels, OIIO::TypeDesc::FLOAT, data.data()));
        OIIO::ImageSpec rgba(all.width, all.height, 4, OIIO::TypeDesc::FLOAT);
        rgba.attribute("name", "rgba");
        OIIO::ImageSpec ranks(all.width, all.height, all.nchannels - 4, OIIO::TypeDesc::FLOAT);
        ranks.channelnames.assign(all.channelnames.begin() + 4, all.channelnames.end());
        ranks.attribute("name", "CryptoObject");
        for (const OIIO::ParamValue &p : all.extra_attribs) {
            if (p.name().string().rfind("cryptomatte/", 0) == 0) {
                ranks.extra_attribs.push_back(p);
            }
        }
        const OIIO::ImageSpec specs[2] = {rgba, ranks};
        auto out = OIIO::ImageOutput::create(path);
        ASSERT_TRUE(out && out->open(path, 2, specs));
        const std::size_t stride = std::size_t(all.nchannels) * sizeof(float);
        ASSERT_TRUE(out->write_image(
            OIIO::TypeDesc::FLOAT, data.data(), OIIO::stride_t(stride), OIIO::AutoStride));
        ASSERT_TRUE(out->open(path, ranks, OIIO::ImageOutput::AppendSubimage));
        ASSERT_TRUE(out->write_image(
            OIIO::TypeDesc::FLOAT, data.data() + 4, OIIO::stride_t(stride), OIIO::AutoStride));
        out->close();
    }
    EXPECT_EQ(values(key(path, R"({"matte": ["bunny", "d*"]})").image("matte")),
              expected_matte(pixels, {"bunny", "default"}));
    std::string log;
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + path, &log), 0) << log;
    EXPECT_NE(log.find("cryptomatte        CryptoObject (key "), std::string::npos) << log;
    EXPECT_NE(log.find("manifest of 5 names (header)"), std::string::npos) << log;
    // Passed through (colour graded), the declaration stays in the rank layers' part alone.
    const std::string graph = dir + "/g.json";
    std::ofstream(graph) << R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")"
                         << path << R"("}},
        {"id": "g", "type": "grade", "inputs": {"image": "in"}, "params": {"gain": [2, 2, 2]}},
        {"id": "out", "type": "write", "inputs": {"image": "g"}, "params": {"path": ")"
                         << dir << R"(/back.exr"}}]})";
    ASSERT_EQ(
        test::run_command(std::string(POSTHASTE_BINARY) + " run " + graph + " --frames 1 -q", &log),
        0)
        << log;
    auto back = OIIO::ImageInput::open(dir + "/back.exr");
    ASSERT_TRUE(back);
    const std::string name = "cryptomatte/" + hex_of(id_of("CryptoObject")).substr(0, 7) + "/name";
    EXPECT_EQ(back->spec().find_attribute(name), nullptr);
    ASSERT_TRUE(back->seek_subimage(1, 0));
    EXPECT_EQ(back->spec().get_string_attribute(name), "CryptoObject");
}

// Read and written back (a grade on colour in between), the rank layers and the declaration
// come out bit for bit.
TEST(Cryptomatte, RankLayersPassThroughBitForBit)
{
    const std::string dir = test::scratch_dir("cryptomatte_through");
    const std::string in =
        write_crypto_file(dir + "/in.exr", CryptoFile{}, sample_pixels(), kNames);
    const std::string out = dir + "/out.exr";
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": ")" +
                               in + R"("}},
        {"id": "grade", "type": "grade", "inputs": {"image": "src"}, "params": {"exposure": 1}},
        {"id": "out", "type": "write", "inputs": {"image": "grade"}, "params": {"path": ")" +
                               out + R"("}}]})",
                           "through",
                           nodes::catalog());
    g.evaluate(1);
    auto a = OIIO::ImageInput::open(in), b = OIIO::ImageInput::open(out);
    ASSERT_TRUE(a && b);
    const OIIO::ImageSpec &sa = a->spec(), &sb = b->spec();
    for (const char *attr : {"name", "hash", "conversion", "manifest"}) {
        const std::string key =
            "cryptomatte/" + hex_of(id_of("CryptoObject")).substr(0, 7) + "/" + attr;
        EXPECT_EQ(sa.get_string_attribute(key), sb.get_string_attribute(key)) << key;
    }
    std::vector<float> pa(std::size_t(sa.image_pixels()) * std::size_t(sa.nchannels)),
        pb(std::size_t(sb.image_pixels()) * std::size_t(sb.nchannels));
    ASSERT_TRUE(a->read_image(0, 0, 0, sa.nchannels, OIIO::TypeDesc::FLOAT, pa.data()));
    ASSERT_TRUE(b->read_image(0, 0, 0, sb.nchannels, OIIO::TypeDesc::FLOAT, pb.data()));
    int compared = 0;
    for (int ca = 0; ca < sa.nchannels; ++ca) {
        const std::string &name = sa.channelnames[std::size_t(ca)];
        if (name.rfind("CryptoObject", 0) != 0) {
            continue;
        }
        const auto it = std::find(sb.channelnames.begin(), sb.channelnames.end(), name);
        ASSERT_NE(it, sb.channelnames.end()) << name;
        const int cb = int(it - sb.channelnames.begin());
        EXPECT_EQ(sb.channelformat(cb), OIIO::TypeDesc::FLOAT) << name;
        for (int i = 0; i < int(sa.image_pixels()); ++i) {
            ASSERT_EQ(cryptomatte::bits_of(pa[std::size_t(i * sa.nchannels + ca)]),
                      cryptomatte::bits_of(pb[std::size_t(i * sb.nchannels + cb)]))
                << name << " pixel " << i;
        }
        ++compared;
    }
    EXPECT_EQ(compared, 8);
}

// Blender 3.4's own Cryptomatte node on a Cycles render (samples/cryptomatte, made by
// tests/cycles/make_cryptomatte_set.py): the same mattes, to the bit (held to 1e-6).
TEST(Cryptomatte, MattesEqualBlendersCryptomatteNode)
{
    const std::string dir = std::string(POSTHASTE_SOURCE_DIR) + "/samples/cryptomatte/";
    const std::string scene = dir + "scene.exr";
    const struct {
        const char *file, *layer, *matte;
    } cases[] = {
        {"cube", "CryptoObject", R"(["Cube"])"},
        {"ball001_pole1", "CryptoObject", R"(["Ball.001", "Pole[1]"])"},
        {"star", "CryptoObject", R"(["Star\\*"])"},
        {"chrome", "CryptoMaterial", R"(["Chrome"])"},
        {"glass", "CryptoMaterial", R"(["Glass\\?"])"},
    };
    for (const auto &c : cases) {
        SCOPED_TRACE(c.file);
        const Frame ours =
            key(scene, std::string(R"({"layer": ")") + c.layer + R"(", "matte": )" + c.matte + "}");
        auto in = OIIO::ImageInput::open(dir + "blender_matte_" + c.file + ".exr");
        ASSERT_TRUE(in);
        const OIIO::ImageSpec &spec = in->spec();
        std::vector<float> theirs(std::size_t(spec.image_pixels()) * std::size_t(spec.nchannels));
        ASSERT_TRUE(in->read_image(0, 0, 0, spec.nchannels, OIIO::TypeDesc::FLOAT, theirs.data()));
        const Image &m = ours.image("matte");
        ASSERT_EQ(m.value_count(), std::size_t(spec.image_pixels()));
        double worst = 0.0, sum = 0.0;
        for (std::size_t i = 0; i < m.value_count(); ++i) {
            const float t = theirs[i * std::size_t(spec.nchannels)];
            worst = std::max(worst, double(std::abs(m.data()[i] - t)));
            sum += t;
        }
        EXPECT_LE(worst, 1e-6);
        EXPECT_GT(sum, 5.0);  // the matte keys something
    }
}

TEST(Cryptomatte, GraphErrorsNameTheParameter)
{
    const auto error_of = [](const std::string &params) {
        try {
            Graph g = Graph::parse(R"({"nodes": [
                {"id": "src", "type": "read", "params": {"path": "x.exr"}},
                {"id": "key", "type": "cryptomatte", "inputs": {"image": "src"}, "params": )" +
                                       params + R"(},
                {"id": "out", "type": "write", "inputs": {"image": "key"},
                 "params": {"path": "o.exr", "passes": "matte"}}]})",
                                   "g.json",
                                   nodes::catalog());
            g.set_capture("key");
            for (const GraphNode &n : g.nodes()) {
                if (n.type->check && n.identity.id == "key") {
                    CheckContext ctx{n.params, n.identity, n.requested, {1}, {true}};
                    n.type->check(ctx);
                }
            }
        } catch (const Error &e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_NE(error_of(R"({"matte": []})").find("param \"matte\": expected a non-empty list"),
              std::string::npos);
    EXPECT_NE(
        error_of(R"({"matte": ["<nope>"]})").find("expected an ID as <8 hex digits> or <float>"),
        std::string::npos);
    EXPECT_NE(error_of(R"({"matte": [3]})").find("names as non-empty strings"), std::string::npos);
    EXPECT_EQ(error_of(R"({"matte": ["bunny", "<0x13851a76>", "<1.5e-3>", "<-2>"]})"), "accepted");
    // Spaces, signs inside the hex digits, and a hexadecimal float (a 7-digit typo) are refused.
    for (const char *bad : {"<0x 1234567>", "<0x-0000001>", "< 1.5>", "<0xa8fce86>", "<+-1>"}) {
        EXPECT_NE(error_of(std::string(R"({"matte": [")") + bad + R"("]})")
                      .find("expected an ID as <8 hex digits> or <float>"),
                  std::string::npos)
            << bad;
    }
}

// Two cryptomattes whose names end alike: a layer named exactly is that one (the other, which
// sorts first, was keyed); a short name that both end in is refused, naming both. An alpha
// output on a gray colour (Y) gives Y, A. A broken declaration fails only where it is used (it
// failed every cryptomatte of the file).
TEST(Cryptomatte, LayerNamesPickExactlyOrRefuse)
{
    Frame f;
    f.set_size(2, 1);
    Image gray(2, 1, 1);
    gray.fill(0.5f);
    f.set("color", gray, {"Y"});
    const float b = id_of("b");
    const auto declare = [&](const std::string &key, const std::string &name, float coverage) {
        f.attributes.attribute("cryptomatte/" + key + "/name", name);
        f.attributes.attribute("cryptomatte/" + key + "/hash", "MurmurHash3_32");
        f.attributes.attribute("cryptomatte/" + key + "/conversion", "uint32_to_float32");
        Image rank(2, 1, 4);
        rank.at(0, 0, 0) = b;
        rank.at(0, 0, 1) = coverage;
        f.set(name + "00", rank, {"R", "G", "B", "A"});
    };
    declare("1111111", "CryptoObject", 0.25f);
    declare("2222222", "A.CryptoObject", 1.0f);
    const Frame exact =
        test::run_node("cryptomatte", f, R"({"layer": "CryptoObject", "matte": ["b"]})");
    EXPECT_EQ(exact.image("matte").at(0, 0, 0), 0.25f);
    const Frame whole =
        test::run_node("cryptomatte", f, R"({"layer": "A.CryptoObject", "matte": ["b"]})");
    EXPECT_EQ(whole.image("matte").at(0, 0, 0), 1.0f);
    const Frame alpha = test::run_node(
        "cryptomatte", f, R"({"layer": "CryptoObject", "matte": ["b"], "output": "alpha"})");
    EXPECT_EQ(alpha.pass("color").channels, (std::vector<std::string>{"Y", "A"}));
    EXPECT_EQ(alpha.image("color").at(0, 0, 0), 0.5f);
    EXPECT_EQ(alpha.image("color").at(0, 0, 1), 0.25f);
    // A broken declaration is an error where it is used, and no hindrance to the others.
    declare("5555555", "Broken", 1.0f);
    f.attributes.attribute("cryptomatte/5555555/hash", "md5");
    EXPECT_EQ(test::run_node("cryptomatte", f, R"({"layer": "CryptoObject", "matte": ["b"]})")
                  .image("matte")
                  .at(0, 0, 0),
              0.25f);
    try {
        test::run_node("cryptomatte", f, R"({"layer": "Broken", "matte": ["b"]})");
        ADD_FAILURE() << "a broken cryptomatte was keyed";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find(R"(cryptomatte "Broken": hash "md5")"),
                  std::string::npos)
            << e.what();
    }
    declare("3333333", "B.Other", 1.0f);
    declare("4444444", "C.Other", 1.0f);
    try {
        test::run_node("cryptomatte", f, R"({"layer": "Other", "matte": ["b"]})");
        ADD_FAILURE() << "an ambiguous layer was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find(
                      R"(layer "Other" names B.Other, C.Other: give the whole name)"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace posthaste
