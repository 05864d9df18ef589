// nodes/cryptomatte.cpp: an ID matte keyed from a Cryptomatte (io/cryptomatte.h): the summed
// coverage, over every rank, of the IDs whose names the graph lists. Names hash to IDs
// (MurmurHash3_x86_32, seed 0, the specification's float conversion), so a name keys without a
// manifest; wildcards search the manifest. The ranks are read from the input frame's header
// and passes: the node asks its source for them by a "cryptomatte:<layer>" request, which a
// read resolves against the file's header.

#include "io/cryptomatte.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <nlohmann/json.hpp>

#include "io/source_file.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kLayer =
    ParamSpec::string("layer", "")
        .doc(
            "The cryptomatte, by type name (CryptoObject, CryptoMaterial, CryptoAsset or any "
            "other; Blender's ViewLayer.CryptoObject answers to CryptoObject); empty: the frame's "
            "only one.");
constexpr ParamSpec kMatte = ParamSpec::json("matte", "[]")
                                 .doc(
                                     "The names keyed: a list of strings, each a name, a pattern "
                                     "with * (any run) and ? (one "
                                     "character; \\ makes the next character literal), or an ID: "
                                     "<8 hex digits> (the manifest's "
                                     "value, 0x optional) or <float>.");
constexpr ParamSpec kOutput =
    ParamSpec::choice("output", "matte|alpha|keyed", "matte")
        .doc(
            "matte: add the matte as a pass; alpha: color's alpha becomes the matte; keyed: color "
            "(alpha too) multiplied by the matte.");
constexpr ParamSpec kPass = ParamSpec::string("pass", "matte")
                                .doc("The pass the matte is written to (output matte).")
                                .only_when("output", "matte");
constexpr ParamSpec kPreview =
    ParamSpec::boolean("preview", false)
        .doc(
            "Also write pass \"cryptomatte_preview\": R the first rank's ID (keyable: a picker "
            "reads the ID there), G and B the coverage-weighted viewable colours of every rank "
            "(the specification's (hash << 8) and (hash << 16) over 2^32 - 1).");
constexpr ParamSpec kParams[] = {kLayer, kMatte, kOutput, kPass, kPreview};
/// What the node keys and writes, its parameters bound to the fields.
struct KeySettings {
    enum class Output { Matte, Alpha, Keyed };  ///< output's choices, in order
    std::string layer;
    Output output = Output::Matte;
    std::string pass = "matte";
    bool preview = false;
};
constexpr Binding<KeySettings> kFields[] = {
    bind<&KeySettings::layer>(kLayer),
    bind<&KeySettings::output>(kOutput),
    bind<&KeySettings::pass>(kPass),
    bind<&KeySettings::preview>(kPreview),
};
using Output = KeySettings::Output;

constexpr PortSpec kInputs[] = {
    {"image",
     "",
     false,
     "A frame with a cryptomatte: its header and rank layers (<name>00, ...)."}};

/// The matte list as given (checked in check()).
std::vector<std::string> entries_of(const NodeParams &p)
{
    std::vector<std::string> out;
    for (const auto &e : nlohmann::json::parse(p.get_json(kMatte))) {
        out.push_back(e.get<std::string>());
    }
    return out;
}

/// An entry's ID when it is one ("<1.5e-12>", "<0x13851a76>").
bool id_entry(const std::string &e, float &id)
{
    if (e.size() < 3 || e.front() != '<' || e.back() != '>') {
        return false;
    }
    const std::string inner = e.substr(1, e.size() - 2);
    char *end = nullptr;
    // The manifest's form: 8 hex digits (with or without 0x) are the ID's bits.
    const bool prefixed =
        inner.size() == 10 && inner[0] == '0' && (inner[1] == 'x' || inner[1] == 'X');
    const std::string digits = prefixed ? inner.substr(2) : inner;
    if (digits.size() == 8 &&
        digits.find_first_not_of("0123456789abcdefABCDEF") == std::string::npos) {
        const std::uint32_t b = std::uint32_t(std::strtoul(digits.c_str(), &end, 16));
        std::memcpy(&id, &b, sizeof(id));
        return true;
    }
    // Else a decimal float ("1.5e-12", "-3"): no spaces, no hexadecimal floats.
    if (inner.find_first_not_of("0123456789.eE+-") != std::string::npos) {
        return false;
    }
    id = std::strtof(inner.c_str(), &end);
    return end != inner.c_str() && *end == '\0' && std::isfinite(id);
}

/// The type the file the pass came from holds an ID channel (R or B) of it in, when that is
/// not float32 (half, uint, ...), else UNKNOWN. A uint channel reads as its value, not as the
/// bits of a float ID, and a half cannot hold a 32-bit hash: neither keys anything.
OIIO::TypeDesc stored_id_type(const Frame &f, const Pass &p)
{
    if (!f.source) {
        return OIIO::TypeDesc::UNKNOWN;
    }
    for (std::size_t c = 0; c < p.origin.size(); c += 2) {
        const ChannelOrigin &o = p.origin[c];
        if (o.part >= 0 && std::size_t(o.part) < f.source->parts.size()) {
            const OIIO::TypeDesc t =
                f.source->parts[std::size_t(o.part)].spec.channelformat(o.channel);
            if (t != OIIO::TypeDesc::FLOAT) {
                return t;
            }
        }
    }
    return OIIO::TypeDesc::UNKNOWN;
}

const cryptomatte::Layer &choose_layer(const std::vector<cryptomatte::Layer> &layers,
                                       const std::string &type,
                                       const std::string &where)
{
    std::string have;
    for (const cryptomatte::Layer &l : layers) {
        have += (have.empty() ? "" : ", ") + l.name;
    }
    if (layers.empty()) {
        throw_runtime(where,
                      ": the frame's header declares no cryptomatte (cryptomatte/<key>/name)");
    }
    if (type.empty()) {
        if (layers.size() > 1) {
            throw_runtime(
                where, ": the frame has ", layers.size(), " cryptomattes (", have, "): give layer");
        }
        return layers.front();
    }
    // The cryptomatte of exactly that name, else the one whose name ends in it after a view
    // layer's prefix; two such are ambiguous.
    std::vector<const cryptomatte::Layer *> by_suffix;
    std::string matching;
    const cryptomatte::Layer *exact = nullptr;
    for (const cryptomatte::Layer &l : layers) {
        if (l.name.empty()) {
            continue;  // (a declaration without a name: its problem is said where it is used)
        }
        if (l.name == type) {
            // Two keys of one name share its rank layers: which is meant cannot be told (the
            // first by key order was taken silently).
            if (exact) {
                throw_runtime(where,
                              ": cryptomatte \"",
                              type,
                              "\" is declared twice, under keys ",
                              exact->key,
                              " and ",
                              l.key);
            }
            exact = &l;
            continue;
        }
        if (l.is(type)) {
            by_suffix.push_back(&l);
            matching += (matching.empty() ? "" : ", ") + l.name;
        }
    }
    if (exact) {
        return *exact;
    }
    for (std::size_t i = 1; i < by_suffix.size(); ++i) {
        if (by_suffix[i]->name == by_suffix[i - 1]->name) {  // (sorted by name)
            throw_runtime(where,
                          ": cryptomatte \"",
                          by_suffix[i]->name,
                          "\" is declared twice, under keys ",
                          by_suffix[i - 1]->key,
                          " and ",
                          by_suffix[i]->key);
        }
    }
    if (by_suffix.size() > 1) {
        throw_runtime(where, ": layer \"", type, "\" names ", matching, ": give the whole name");
    }
    if (!by_suffix.empty()) {
        return *by_suffix.front();
    }
    throw_runtime(where, ": no cryptomatte \"", type, "\" in the frame (have: ", have, ")");
}

/// The IDs the entries key, as float bits, sorted.
std::vector<std::uint32_t> keyed_ids(NodeContext &ctx,
                                     const cryptomatte::Layer &layer,
                                     const std::vector<std::string> &entries)
{
    std::vector<std::uint32_t> ids;
    for (const std::string &e : entries) {
        float id = 0.0f;
        if (id_entry(e, id)) {
            ids.push_back(cryptomatte::bits_of(id));
        } else if (cryptomatte::has_wildcard(e)) {
            if (!layer.has_manifest) {
                throw_runtime(ctx.where(),
                              ": matte entry \"",
                              e,
                              "\": a pattern needs a manifest, and cryptomatte \"",
                              layer.name,
                              "\" has none (give names or <ID>s)");
            }
            int n = 0;
            for (const auto &[name, value] : layer.manifest) {
                if (cryptomatte::name_matches(e, name)) {
                    ids.push_back(cryptomatte::bits_of(value));
                    ++n;
                }
            }
            if (n == 0) {
                ctx.state().note_once(ctx.node().describe() + ": matte entry \"" + e +
                                      "\" matches no name in the manifest of \"" + layer.name +
                                      "\"");
            }
        } else {
            const std::string name = cryptomatte::unescape(e);
            ids.push_back(cryptomatte::bits_of(cryptomatte::id_of(name)));
            const auto in_manifest =
                std::lower_bound(layer.manifest.begin(),
                                 layer.manifest.end(),
                                 name,
                                 [](const std::pair<std::string, float> &a, const std::string &n) {
                                     return a.first < n;
                                 });
            if (layer.has_manifest &&
                (in_manifest == layer.manifest.end() || in_manifest->first != name)) {
                ctx.state().note_once(ctx.node().describe() + ": matte entry \"" + e +
                                      "\" is no name in the manifest of \"" + layer.name +
                                      "\" (keyed by its hash all the same)");
            }
        }
    }
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
    return ids;
}

/// Summed coverage of `ids` over the rank passes, clamped to [0, 1]; non-finite coverage counts
/// as none.
Image matte_of(const std::vector<const Image *> &ranks,
               const std::vector<std::uint32_t> &ids,
               int w,
               int h)
{
    Image out = Image::uninitialized(w, h, 1);
    // Most samples hold an ID that is not keyed: a 65,536-bit filter (8 KB, in L1) of the keyed
    // IDs' hashed bits turns almost all of them away with one test; the rest are looked up.
    std::vector<std::uint64_t> filter(1024, 0);
    const auto slot = [](std::uint32_t b) { return (b * 0x9E3779B1u) >> 16; };
    for (std::uint32_t b : ids) {
        filter[slot(b) >> 6] |= std::uint64_t(1) << (slot(b) & 63u);
    }
    const bool few = ids.size() <= 8;
    const auto keyed = [&](float id) {
        const std::uint32_t b = cryptomatte::bits_of(id);
        const std::uint32_t s = slot(b);
        if ((filter[s >> 6] >> (s & 63u) & 1u) == 0) {
            return false;
        }
        if (few) {
            for (std::uint32_t k : ids) {
                if (k == b) {
                    return true;
                }
            }
            return false;
        }
        return std::binary_search(ids.begin(), ids.end(), b);
    };
    parallel_for(0, h, [&](int y) {
        float *o = out.pixel(0, y);
        std::fill(o, o + w, 0.0f);
        for (const Image *r : ranks) {
            const float *p = r->pixel(0, y);
            for (int x = 0; x < w; ++x, p += 4) {
                // Both ranks of the pixel through the filter, one branch for the pair.
                const std::uint32_t s0 = slot(cryptomatte::bits_of(p[0]));
                const std::uint32_t s2 = slot(cryptomatte::bits_of(p[2]));
                if ((((filter[s0 >> 6] >> (s0 & 63u)) | (filter[s2 >> 6] >> (s2 & 63u))) & 1u) ==
                    0) {
                    continue;
                }
                if (keyed(p[0]) && std::isfinite(p[1])) {
                    o[x] += p[1];
                }
                if (keyed(p[2]) && std::isfinite(p[3])) {
                    o[x] += p[3];
                }
            }
        }
        for (int x = 0; x < w; ++x) {
            o[x] = std::clamp(o[x], 0.0f, 1.0f);
        }
    });
    return out;
}

/// The keyable preview: R the first rank's ID, G and B the coverage-weighted sum of each rank's
/// viewable colours from its ID's bits.
Image preview_of(const std::vector<const Image *> &ranks, int w, int h)
{
    Image out(w, h, 3);
    constexpr double kMax = 4294967295.0;
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            float *o = out.pixel(x, y);
            for (std::size_t k = 0; k < ranks.size(); ++k) {
                const float *p = ranks[k]->pixel(x, y);
                for (int j = 0; j < 2; ++j) {
                    const float id = p[2 * j], cov = p[2 * j + 1];
                    if (k == 0 && j == 0) {
                        o[0] = id;
                    }
                    if (!(cov > 0.0f) || !std::isfinite(cov)) {
                        continue;
                    }
                    // Within [0, 1] as the matte's sum is: a coverage of 3e38 made inf here.
                    const float c = std::min(cov, 1.0f);
                    const std::uint32_t bits = cryptomatte::bits_of(id);
                    o[1] += c * float(double(std::uint32_t(bits << 8)) / kMax);
                    o[2] += c * float(double(std::uint32_t(bits << 16)) / kMax);
                }
            }
        }
    });
    return out;
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const std::string where = ctx.where();
    const std::string path = in.source ? in.source->path : std::string("the frame");
    std::vector<cryptomatte::Layer> layers;
    try {
        layers = cryptomatte::find_layers(cryptomatte::declarations(in), path);
    } catch (const Error &e) {
        rethrow_with_prefix(e, where + ": ");
    }
    const KeySettings ks = fill(ctx.params(), kFields);
    const cryptomatte::Layer &layer = choose_layer(layers, ks.layer, where);
    if (!layer.problem.empty()) {
        throw_runtime(where, ": ", layer.problem);
    }
    const std::vector<std::string> rank_names =
        cryptomatte::rank_passes(layer, in.pass_names(), where);
    if (rank_names.empty()) {
        throw_runtime(where,
                      ": cryptomatte \"",
                      layer.name,
                      "\" has no rank layer among the frame's passes (",
                      layer.name,
                      "00, ...)");
    }
    std::vector<const Image *> ranks;
    std::deque<Image> reordered;  // rank layers whose channels were not in r, g, b, a order
    for (const std::string &name : rank_names) {
        const Pass &p = in.pass(name, where);
        if (p.image->channels() != 4) {
            throw_runtime(where,
                          ": rank layer \"",
                          name,
                          "\" has ",
                          p.image->channels(),
                          " channels, expected 4 (id, coverage, id, coverage)");
        }
        const OIIO::TypeDesc stored =
            p.storage == PixelStorage::Half ? OIIO::TypeDesc::HALF : stored_id_type(in, p);
        if (stored == OIIO::TypeDesc::HALF) {
            throw_runtime(where,
                          ": rank layer \"",
                          name,
                          "\" holds its IDs as half floats, which cannot hold a 32-bit hash "
                          "(write cryptomatte layers as float)");
        }
        if (stored != OIIO::TypeDesc::UNKNOWN) {
            throw_runtime(where,
                          ": rank layer \"",
                          name,
                          "\" holds its IDs as ",
                          stored.c_str(),
                          ", not as the float32 bits of the hash (write cryptomatte layers as "
                          "float)");
        }
        // The channels by name where the file names them (r, g, b, a in any case and order).
        int order[4] = {0, 1, 2, 3};
        bool named = p.channels.size() == 4, identity = true;
        for (int c = 0; named && c < 4; ++c) {
            const auto it =
                std::find_if(p.channels.begin(), p.channels.end(), [&](const std::string &n) {
                    return n.size() == 1 &&
                           std::toupper(static_cast<unsigned char>(n[0])) == "RGBA"[c];
                });
            named = it != p.channels.end();
            order[c] = named ? int(it - p.channels.begin()) : c;
            identity = identity && order[c] == c;
        }
        if (named && !identity) {
            Image ordered = Image::uninitialized(p.image->width(), p.image->height(), 4);
            for (std::size_t i = 0; i < ordered.pixel_count(); ++i) {
                for (int c = 0; c < 4; ++c) {
                    ordered.data()[4 * i + std::size_t(c)] =
                        p.image->data()[4 * i + std::size_t(order[c])];
                }
            }
            reordered.push_back(std::move(ordered));
            ranks.push_back(&reordered.back());
        } else {
            ranks.push_back(p.image.get());
        }
    }
    const std::vector<std::uint32_t> ids = keyed_ids(ctx, layer, entries_of(ctx.params()));
    Image matte = matte_of(ranks, ids, in.width(), in.height());
    const Output output = ks.output;
    if (ks.preview) {
        ctx.output().set(
            "cryptomatte_preview", preview_of(ranks, in.width(), in.height()), {"R", "G", "B"});
    }
    if (output == Output::Matte) {
        ctx.output().set(ks.pass, std::move(matte), {"A"});
        return;
    }
    const Pass &cp = in.pass(pass::kColor, where);
    const Image &color = *cp.image;
    // Alpha is a colour's fourth channel, or the second of a gray one (Y, A).
    const int alpha = color.channels() <= 2 ? 1 : 3;
    const int nc =
        output == Output::Alpha ? std::max(color.channels(), alpha + 1) : color.channels();
    Image out = Image::uninitialized(color.width(), color.height(), nc);
    parallel_for(0, out.height(), [&](int y) {
        for (int x = 0; x < out.width(); ++x) {
            const float m = matte.at(x, y, 0);
            const float *s = color.pixel(x, y);
            float *d = out.pixel(x, y);
            for (int c = 0; c < nc; ++c) {
                const float v = c < color.channels() ? s[c] : 1.0f;
                d[c] = output == Output::Keyed ? v * m : (c == alpha ? m : v);
            }
        }
    });
    std::vector<std::string> channels = cp.channels;
    if (int(channels.size()) < nc) {
        channels.push_back("A");
    }
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), channels, cp.storage);
}

void plan(PlanContext &ctx)
{
    const KeySettings ks = fill(ctx.params, kFields);
    ctx.inputs[0].add_optional(cryptomatte::request_for(ks.layer));
    if (ks.output != Output::Matte) {
        ctx.inputs[0].add(pass::kColor);
    } else {
        ctx.inputs[0].remove(ks.pass);  // the node makes it
    }
    ctx.inputs[0].remove("cryptomatte_preview");
}

void check(CheckContext &ctx)
{
    nlohmann::json j;
    try {
        j = nlohmann::json::parse(ctx.params.get_json(kMatte));
    } catch (const nlohmann::json::parse_error &) {
        throw_param_expected(ctx, kMatte, "a list of names", ctx.params.get_json(kMatte));
    }
    if (!j.is_array() || j.empty()) {
        throw_param_expected(ctx, kMatte, "a non-empty list of names, patterns or <ID>s", j.dump());
    }
    for (const auto &e : j) {
        float id = 0.0f;
        if (!e.is_string() || e.get<std::string>().empty()) {
            throw_param_expected(ctx, kMatte, "names as non-empty strings", e.dump());
        }
        const std::string s = e.get<std::string>();
        if (s.front() == '<' && !id_entry(s, id)) {
            throw_param_expected(ctx, kMatte, "an ID as <8 hex digits> or <float>", quoted(s));
        }
    }
    const KeySettings ks = fill(ctx.params, kFields);
    if (ks.output == Output::Matte && ks.pass.empty()) {
        throw_param_expected(ctx, kPass, "a pass name", "\"\"");
    }
}

}  // namespace

extern const NodeType kCryptomatte{
    {"cryptomatte",
     "ID matte from a Cryptomatte: the coverage of the objects (or materials, assets) named.",
     kInputs,
     kParams,
     ""},
    &execute,
    &plan,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kCryptomatte, kFields, problems); }};

}  // namespace posthaste::nodes
