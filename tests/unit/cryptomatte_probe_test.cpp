// What an adversarial probe found in the cryptomatte reader, node and info, and in the mask on
// colour nodes: sidecars that are no regular file, names given twice, uint IDs, an infinite
// preview, an overflowing blend and a luminance-only mask file (io/cryptomatte.h,
// nodes/cryptomatte.cpp, cli/cmd_info.cpp, graph/mask.h).

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "core/error.h"
#include "graph/graph.h"
#include "graph/mask.h"
#include "io/cryptomatte.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

/// One channel of a hand-made file: its name, its type in the file and its 4x2 values.
struct Channel {
    std::string name;
    OIIO::TypeDesc type = OIIO::TypeDesc::FLOAT;
    std::vector<float> values;
};

/// A 4x2 EXR of `channels` with the string attributes `attributes` (name, value).
std::string write_exr(const std::string &path,
                      const std::vector<Channel> &channels,
                      const std::vector<std::pair<std::string, std::string>> &attributes)
{
    const int w = 4, h = 2, n = int(channels.size());
    OIIO::ImageSpec spec(w, h, n, OIIO::TypeDesc::FLOAT);
    spec.channelnames.clear();
    for (const Channel &c : channels) {
        spec.channelnames.push_back(c.name);
        spec.channelformats.push_back(c.type);
    }
    for (const auto &[name, value] : attributes) {
        spec.attribute(name, value);
    }
    std::vector<float> data(std::size_t(w * h * n));
    for (int i = 0; i < w * h; ++i) {
        for (int c = 0; c < n; ++c) {
            data[std::size_t(i * n + c)] = channels[std::size_t(c)].values[std::size_t(i)];
        }
    }
    auto out = OIIO::ImageOutput::create(path);
    EXPECT_TRUE(out && out->open(path, spec)) << path;
    EXPECT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, data.data())) << out->geterror();
    out->close();
    return path;
}

/// A cryptomatte's declaration under `key` (a header manifest of Cube alone).
std::vector<std::pair<std::string, std::string>> declaration(const std::string &key,
                                                             const std::string &name)
{
    return {{"cryptomatte/" + key + "/name", name},
            {"cryptomatte/" + key + "/hash", "MurmurHash3_32"},
            {"cryptomatte/" + key + "/conversion", "uint32_to_float32"},
            {"cryptomatte/" + key + "/manifest", R"({"Cube":"a8fce865"})"}};
}

/// Colour 0.5, 0.25, 0.125, 1 and the rank layer <name>00: Cube (coverage `coverage`) in the
/// first four pixels, nothing in the others.
std::vector<Channel> crypto_channels(const std::string &name,
                                     float coverage = 1.0f,
                                     OIIO::TypeDesc id_type = OIIO::TypeDesc::FLOAT)
{
    const float cube = cryptomatte::id_of("Cube");
    const float c = coverage;
    return {{"R", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.5f)},
            {"G", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.25f)},
            {"B", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.125f)},
            {"A", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 1.0f)},
            {name + "00.R", id_type, {cube, cube, cube, cube, 0, 0, 0, 0}},
            {name + "00.G", OIIO::TypeDesc::FLOAT, {c, c, c, c, 0, 0, 0, 0}},
            {name + "00.B", id_type, std::vector<float>(8, 0.0f)},
            {name + "00.A", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.0f)}};
}

/// The error evaluating the graph of `nodes_json` (its nodes), or "accepted".
std::string error_of(const std::string &nodes_json)
{
    try {
        Graph g = Graph::parse(R"({"nodes": [)" + nodes_json + "]}", "probe", nodes::catalog());
        g.evaluate(1);
    } catch (const Error &e) {
        return e.what();
    }
    return "accepted";
}

/// read `path` -> cryptomatte with `params` -> write the passes `passes`, as JSON nodes.
std::string key_graph(const std::string &path, const std::string &params, const std::string &passes)
{
    return R"({"id": "src", "type": "read", "params": {"path": ")" + path + R"("}},
        {"id": "key", "type": "cryptomatte", "inputs": {"image": "src"}, "params": )" +
           params + R"(},
        {"id": "out", "type": "write", "inputs": {"image": "key"},
         "params": {"path": ")" +
           path + R"(.out.exr", "passes": ")" + passes + R"("}})";
}

/// The problem of the one cryptomatte declared with sidecar `manif_file` beside `image`.
std::string sidecar_problem(const std::string &image, const std::string &manif_file)
{
    OIIO::ParamValueList attributes;
    attributes.attribute("cryptomatte/abc1234/name", "CryptoObject");
    attributes.attribute("cryptomatte/abc1234/hash", "MurmurHash3_32");
    attributes.attribute("cryptomatte/abc1234/conversion", "uint32_to_float32");
    attributes.attribute("cryptomatte/abc1234/manif_file", manif_file);
    const std::vector<cryptomatte::Layer> layers = cryptomatte::find_layers(attributes, image);
    EXPECT_EQ(layers.size(), 1u);
    return layers.empty() ? "" : layers[0].problem;
}

// A sidecar is a regular file of at most 256 MiB, checked before it is opened: /dev/zero was
// read until memory ran out, a FIFO blocked forever, a folder was "not JSON".
TEST(CryptomatteProbe, SidecarIsARegularFileOfBoundedSize)
{
    const std::string dir = test::scratch_dir("cryptomatte_probe_sidecar");
    const std::string image = dir + "/a.exr";
    const std::string what = image + ": cryptomatte \"CryptoObject\": its manifest file ";
    std::ofstream(dir + "/ok.json") << R"({"Cube": "a8fce865"})";
    EXPECT_EQ(sidecar_problem(image, "ok.json"), "");

    std::filesystem::create_directory(dir + "/folder.json");
    EXPECT_EQ(sidecar_problem(image, "folder.json"), what + dir + "/folder.json is a folder");

    ASSERT_EQ(::mkfifo((dir + "/fifo.json").c_str(), 0600), 0);
    EXPECT_EQ(sidecar_problem(image, "fifo.json"), what + dir + "/fifo.json is not a regular file");

    EXPECT_EQ(sidecar_problem(image, "/dev/zero"), what + "/dev/zero is not a regular file");

    // Sparse: no disk is spent on it.
    std::ofstream(dir + "/big.json").put('{');
    std::filesystem::resize_file(dir + "/big.json", (std::uintmax_t(256) << 20) + 1);
    EXPECT_EQ(sidecar_problem(image, "big.json"),
              what + dir + "/big.json is 268435457 bytes, more than the 268435456 a manifest " +
                  "may have");

    EXPECT_EQ(sidecar_problem(image, "missing.json"),
              image + ": cryptomatte \"CryptoObject\": cannot read its manifest file " + dir +
                  "/missing.json");
}

// A manifest that gives a name twice (with two IDs) is refused: JSON kept the last silently.
TEST(CryptomatteProbe, ManifestNameGivenTwiceIsRefused)
{
    OIIO::ParamValueList attributes;
    for (const auto &[name, value] : declaration("abc1234", "CryptoObject")) {
        attributes.attribute(name, value);
    }
    attributes.attribute("cryptomatte/abc1234/manifest",
                         R"({"Cube":"a8fce865","Cube":"00000001"})");
    const std::vector<cryptomatte::Layer> layers = cryptomatte::find_layers(attributes, "x.exr");
    ASSERT_EQ(layers.size(), 1u);
    EXPECT_EQ(layers[0].problem,
              "x.exr: cryptomatte \"CryptoObject\": the manifest gives name \"Cube\" twice");
    EXPECT_FALSE(layers[0].has_manifest);
    // Two names, each once: the manifest as given.
    attributes.attribute("cryptomatte/abc1234/manifest", R"({"Cube":"a8fce865","B":"24950135"})");
    EXPECT_EQ(cryptomatte::find_layers(attributes, "x.exr")[0].problem, "");
    EXPECT_EQ(cryptomatte::find_layers(attributes, "x.exr")[0].manifest.size(), 2u);
}

// Two declarations of one name (different keys) share its rank layers: an error naming the
// name and both keys, by its whole name and by its name after a view layer's prefix.
TEST(CryptomatteProbe, OneNameDeclaredTwiceIsRefused)
{
    const std::string dir = test::scratch_dir("cryptomatte_probe_twice");
    for (const char *name : {"CryptoObject", "ViewLayer.CryptoObject"}) {
        auto attributes = declaration("0000000", name);
        for (const auto &a : declaration("542cafa", name)) {
            attributes.push_back(a);
        }
        const std::string path = write_exr(dir + "/two.exr", crypto_channels(name), attributes);
        const std::string e =
            error_of(key_graph(path, R"({"layer": "CryptoObject", "matte": ["Cube"]})", "matte"));
        EXPECT_NE(e.find(": cryptomatte \"" + std::string(name) +
                         "\" is declared twice, under keys 0000000 and 542cafa"),
                  std::string::npos)
            << e;
        // info says so on each declaration's line (it listed both as valid).
        std::string out;
        ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + path, &out), 0)
            << out;
        EXPECT_NE(out.find("cryptomatte        invalid: " + path + ": cryptomatte \"" + name +
                           "\" is declared twice, under keys 0000000 and 542cafa"),
                  std::string::npos)
            << out;
        EXPECT_NE(out.find("under keys 542cafa and 0000000"), std::string::npos) << out;
    }
    // One declaration keys as before.
    const std::string one = write_exr(
        dir + "/one.exr", crypto_channels("CryptoObject"), declaration("0000000", "CryptoObject"));
    EXPECT_EQ(error_of(key_graph(one, R"({"layer": "CryptoObject", "matte": ["Cube"]})", "matte")),
              "accepted");
}

// Rank layers whose IDs are stored as uint hold the uint's value, not the float's bits: they
// keyed nothing silently, and are refused as half ones are.
TEST(CryptomatteProbe, UintIdChannelsAreRefused)
{
    const std::string dir = test::scratch_dir("cryptomatte_probe_uint");
    std::vector<Channel> channels = crypto_channels("CryptoObject", 1.0f, OIIO::TypeDesc::UINT);
    channels[4].values = {5, 5, 5, 5, 0, 0, 0, 0};  // (a uint cannot hold the float ID)
    const std::string path =
        write_exr(dir + "/uint.exr", channels, declaration("abc1234", "CryptoObject"));
    const std::string e = error_of(key_graph(path, R"({"matte": ["Cube"]})", "matte"));
    EXPECT_NE(e.find(": rank layer \"CryptoObject00\" holds its IDs as uint, not as the float32 "
                     "bits of the hash (write cryptomatte layers as float)"),
              std::string::npos)
        << e;
}

// A coverage of 3e38 made the preview's G and B infinite; it counts as 1, as in the matte.
TEST(CryptomatteProbe, PreviewOfAHugeCoverageIsFinite)
{
    const std::string dir = test::scratch_dir("cryptomatte_probe_preview");
    const std::string path = write_exr(dir + "/cov.exr",
                                       crypto_channels("CryptoObject", 3e38f),
                                       declaration("abc1234", "CryptoObject"));
    Graph g = Graph::parse(
        R"({"nodes": [)" +
            key_graph(
                path, R"({"matte": ["Cube"], "preview": true})", "matte,cryptomatte_preview") +
            "]}",
        "preview",
        nodes::catalog());
    g.set_capture("key");
    const Frame f = g.evaluate(1);
    const Image &p = f.image("cryptomatte_preview");
    const std::uint32_t bits = cryptomatte::bits_of(cryptomatte::id_of("Cube"));
    for (int i = 0; i < 8; ++i) {
        const bool cube = i < 4;
        EXPECT_EQ(p.data()[3 * i + 1],
                  cube ? float(double(std::uint32_t(bits << 8)) / 4294967295.0) : 0.0f)
            << i;
        EXPECT_EQ(p.data()[3 * i + 2],
                  cube ? float(double(std::uint32_t(bits << 16)) / 4294967295.0) : 0.0f)
            << i;
        EXPECT_EQ(f.image("matte").data()[i], cube ? 1.0f : 0.0f) << i;
    }
}

// `info` describes each cryptomatte on its own: an invalid one (a rank layer missing) hid the
// valid ones after it, and an invalid line's bytes that are not UTF-8 reached stdout raw.
TEST(CryptomatteProbe, InfoDescribesEachCryptomatteOnItsOwn)
{
    const std::string dir = test::scratch_dir("cryptomatte_probe_info");
    std::vector<Channel> channels = crypto_channels("CryptoObject");
    for (const char *c : {"R", "G", "B", "A"}) {
        channels.push_back(
            {std::string("ACrypto01.") + c, OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.0f)});
    }
    auto attributes = declaration("0000001", "ACrypto");  // ACrypto01 without ACrypto00
    for (const auto &a : declaration("0000002", "CryptoObject")) {
        attributes.push_back(a);
    }
    for (auto a : declaration("0000003", "B\xff")) {  // its hash is refused
        a.second = a.first == "cryptomatte/0000003/hash" ? "md5" : a.second;
        attributes.push_back(a);
    }
    const std::string path = write_exr(dir + "/a.exr", channels, attributes);
    std::string out;
    ASSERT_EQ(test::run_command(std::string(POSTHASTE_BINARY) + " info " + path, &out), 0) << out;
    EXPECT_NE(out.find("cryptomatte        invalid: " + path +
                       ": cryptomatte \"ACrypto\" has rank layer ACrypto01 but not ACrypto00"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("cryptomatte        invalid: " + path + ": cryptomatte \"B"),
              std::string::npos)
        << out;
    EXPECT_NE(out.find("cryptomatte        CryptoObject (key 0000002): 1 rank layers (2 ranks), "
                       "manifest of 1 names (header)"),
              std::string::npos)
        << out;
    EXPECT_EQ(out.find('\xff'), std::string::npos) << out;
}

// b - a overflowed for a = 3e38, b = -3e38 (finite in, infinite out); where it is finite the
// blend keeps the lerp's bits, and t = 0 and 1 give a and b exactly.
TEST(MaskProbe, BlendOfFarApartValuesIsFinite)
{
    EXPECT_EQ(mask_mix(3e38f, -3e38f, 0.5f), 0.0f);
    EXPECT_EQ(mask_mix(-3e38f, 3e38f, 0.25f), -3e38f * 0.75f + 3e38f * 0.25f);
    EXPECT_TRUE(std::isfinite(mask_mix(3.4e38f, -3.4e38f, 0.1f)));
    EXPECT_EQ(mask_mix(3e38f, -3e38f, 0.0f), 3e38f);
    EXPECT_EQ(mask_mix(3e38f, -3e38f, 1.0f), -3e38f);
    const float a = 0.1f, b = 0.7f, t = 0.3f;
    EXPECT_EQ(mask_mix(a, b, t), a + (b - a) * t);
    EXPECT_EQ(mask_mix(1e38f, 2e38f, 0.5f), 1e38f + (2e38f - 1e38f) * 0.5f);
}

/// The colour of `in` graded by +1 stop through the mask read from `mask` (mask_channel a).
/// `in` through a grade of one stop (or, `merge`, a multiply of `in` by itself) masked by the
/// file `mask` (none: "").
Image graded_through(const std::string &in, const std::string &mask, bool merge = false)
{
    const std::string node =
        merge ? std::string(R"({"id": "x", "type": "merge", "inputs": {"a": "in", "b": "in")") +
                    (mask.empty() ? "" : R"(, "mask": "m")") +
                    R"(}, "params": {"operation": "multiply"}})"
              : R"({"id": "x", "type": "grade", "inputs": {"image": "in", "mask": "m"},
         "params": {"exposure": 1}})";
    Graph g = Graph::parse(R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")" +
                               in + R"("}},
        {"id": "m", "type": "read", "params": {"path": ")" +
                               (mask.empty() ? in : mask) + R"("}},
        )" + node + R"(,
        {"id": "out", "type": "write", "inputs": {"image": "x"},
         "params": {"path": ")" +
                               in + R"(.out.exr", "passes": "color"}}]})",
                           "mask probe",
                           nodes::catalog());
    g.set_capture("x");
    return g.evaluate(1).image("color");
}

// A luminance-only file (Y, as Blender writes its matte outputs) as the mask: its alpha is the
// reader's 1, so the default mask_channel a applied the node everywhere. It is its own mask, as
// a one-channel pass is; a file's own alpha is still the mask.
TEST(MaskProbe, LuminanceOnlyFileIsItsOwnMask)
{
    const std::string dir = test::scratch_dir("mask_probe_y");
    const std::vector<float> half = {1, 0, 1, 0, 0, 1, 0, 1};
    std::vector<Channel> colour_channels = crypto_channels("CryptoObject");
    colour_channels.resize(4);
    const std::string in = write_exr(dir + "/in.exr", colour_channels, {});
    const std::string y = write_exr(dir + "/y.exr", {{"Y", OIIO::TypeDesc::FLOAT, half}}, {});
    // Y and A: the alpha is the file's (the luminance 0 everywhere is not the mask).
    const std::string ya = write_exr(dir + "/ya.exr",
                                     {{"Y", OIIO::TypeDesc::FLOAT, std::vector<float>(8, 0.0f)},
                                      {"A", OIIO::TypeDesc::FLOAT, half}},
                                     {});
    // R, G, B without alpha: the luminance, a grey pixel's value.
    const std::string rgb = write_exr(dir + "/rgb.exr",
                                      {{"R", OIIO::TypeDesc::FLOAT, half},
                                       {"G", OIIO::TypeDesc::FLOAT, half},
                                       {"B", OIIO::TypeDesc::FLOAT, half}},
                                      {});
    const float colour[4] = {0.5f, 0.25f, 0.125f, 1.0f};
    for (const std::string &mask : {y, ya, rgb}) {
        const Image out = graded_through(in, mask);
        ASSERT_EQ(out.channels(), 4);
        for (int i = 0; i < 8; ++i) {
            for (int c = 0; c < 4; ++c) {
                const float want =
                    half[std::size_t(i)] == 1.0f && c < 3 ? 2.0f * colour[c] : colour[c];
                EXPECT_EQ(out.data()[4 * i + c], want) << mask << " " << i << " " << c;
            }
        }
    }
    // merge reads its mask itself and keeps the same rule: the multiply where Y is 1, B where 0.
    const Image multiplied = graded_through(in, "", true);
    for (const std::string &mask : {y, ya, rgb}) {
        const Image out = graded_through(in, mask, true);
        for (int i = 0; i < 8; ++i) {
            for (int c = 0; c < 4; ++c) {
                const float want =
                    half[std::size_t(i)] == 1.0f ? multiplied.data()[4 * i + c] : colour[c];
                EXPECT_EQ(out.data()[4 * i + c], want) << "merge " << mask << " " << i << " " << c;
            }
        }
    }
}

}  // namespace
}  // namespace posthaste
