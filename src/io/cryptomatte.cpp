// io/cryptomatte.cpp: the Cryptomatte header, IDs and name patterns (io/cryptomatte.h).

#include "io/cryptomatte.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"
#include "core/frame.h"
#include "io/source_file.h"

namespace posthaste::cryptomatte {

namespace {

constexpr std::string_view kPrefix = "cryptomatte/";
constexpr std::string_view kRequest = "cryptomatte:";
/// A sidecar manifest larger than this is refused (the largest production manifests hold a few
/// hundred thousand names: some tens of MB).
constexpr std::uintmax_t kMaxSidecarBytes = 256u << 20;

/// Whether `pass` is a rank layer of the cryptomatte `name`: the name and two digits.
bool is_rank_of(const std::string &name, const std::string &pass)
{
    return pass.size() == name.size() + 2 && pass.compare(0, name.size(), name) == 0 &&
           std::isdigit(static_cast<unsigned char>(pass[pass.size() - 2])) &&
           std::isdigit(static_cast<unsigned char>(pass[pass.size() - 1]));
}

}  // namespace

bool Layer::is(std::string_view type) const
{
    if (name == type) {
        return true;
    }
    return name.size() > type.size() &&
           name.compare(name.size() - type.size(), type.size(), type) == 0 &&
           name[name.size() - type.size() - 1] == '.';
}

namespace {

/// The manifest's JSON text as name -> ID, sorted by name; `what` leads the errors.
std::vector<std::pair<std::string, float>> parse_manifest(const std::string &text,
                                                          const std::string &what)
{
    nlohmann::json j;
    // The top level's names as the parser meets them: JSON keeps the last of a name given twice
    // silently, and which ID is that name's is not for the reader to guess.
    std::set<std::string> names;
    std::string twice;
    const nlohmann::json::parser_callback_t note =
        [&](int depth, nlohmann::json::parse_event_t event, nlohmann::json &parsed) {
            if (event == nlohmann::json::parse_event_t::key && depth == 1 && twice.empty() &&
                !names.insert(parsed.get<std::string>()).second) {
                twice = parsed.get<std::string>();
            }
            return true;
        };
    try {
        j = nlohmann::json::parse(text, note);
    } catch (const nlohmann::json::parse_error &e) {
        throw_runtime(what, ": the manifest is not JSON (", e.what(), ")");
    }
    if (!j.is_object()) {
        throw_runtime(what, ": the manifest is not a JSON object of name: \"8 hex digits\"");
    }
    if (!twice.empty()) {
        throw_runtime(what, ": the manifest gives name \"", twice, "\" twice");
    }
    std::vector<std::pair<std::string, float>> out;
    for (auto it = j.begin(); it != j.end(); ++it) {
        const std::string hex = it.value().is_string() ? it.value().get<std::string>() : "";
        if (hex.size() != 8 ||
            hex.find_first_not_of("0123456789abcdefABCDEF") != std::string::npos) {
            throw_runtime(what,
                          ": manifest entry \"",
                          it.key(),
                          "\": expected 8 hex digits, got ",
                          // (a nested value's dump recursed without bound)
                          it.value().is_primitive() ? it.value().dump()
                                                    : std::string(it.value().type_name()));
        }
        const std::uint32_t bits = std::uint32_t(std::stoul(hex, nullptr, 16));
        float id;
        std::memcpy(&id, &bits, sizeof(id));
        out.emplace_back(it.key(), id);
    }
    std::sort(out.begin(), out.end());
    return out;
}

/// Throws what breaks the specification in the declaration of `l` (fields by name); fills its
/// manifest.
void check_declaration(Layer &l,
                       const std::map<std::string, std::string> &fields,
                       const std::string &what,
                       const std::string &image_path)
{
    const auto field = [&](const char *f) {
        const auto it = fields.find(f);
        return it == fields.end() ? std::string() : it->second;
    };
    const std::string &key = l.key;
    if (l.name.empty()) {
        throw_runtime(what, ": the header has no cryptomatte/", key, "/name");
    }
    if (field("hash") != "MurmurHash3_32") {
        throw_runtime(what, ": hash \"", field("hash"), "\" (only MurmurHash3_32 is specified)");
    }
    if (field("conversion") != "uint32_to_float32") {
        throw_runtime(what,
                      ": conversion \"",
                      field("conversion"),
                      "\" (only uint32_to_float32 is specified)");
    }
    if (fields.count("manifest")) {
        l.manifest = parse_manifest(field("manifest"), what);
        l.has_manifest = true;
        l.manifest_from = "header";
    } else if (fields.count("manif_file")) {
        const std::filesystem::path sidecar =
            std::filesystem::path(image_path).parent_path() / field("manif_file");
        // Checked before it is opened: a FIFO blocked the open forever, and /dev/zero was read
        // until memory ran out.
        std::error_code ec;
        const auto status = std::filesystem::status(sidecar, ec);
        if (std::filesystem::is_directory(status)) {
            throw_runtime(what, ": its manifest file ", sidecar.string(), " is a folder");
        }
        if (std::filesystem::exists(status) && !std::filesystem::is_regular_file(status)) {
            throw_runtime(what, ": its manifest file ", sidecar.string(), " is not a regular file");
        }
        const std::uintmax_t size =
            std::filesystem::is_regular_file(status) ? std::filesystem::file_size(sidecar, ec) : 0;
        if (!ec && size > kMaxSidecarBytes) {
            throw_runtime(what,
                          ": its manifest file ",
                          sidecar.string(),
                          " is ",
                          size,
                          " bytes, more than the ",
                          kMaxSidecarBytes,
                          " a manifest may have");
        }
        std::ifstream in(sidecar);
        if (!in || !std::filesystem::is_regular_file(status)) {
            throw_runtime(what, ": cannot read its manifest file ", sidecar.string());
        }
        std::stringstream text;
        text << in.rdbuf();
        l.manifest = parse_manifest(text.str(), what + " (" + sidecar.string() + ")");
        l.has_manifest = true;
        l.manifest_from = sidecar.string();
    }
}

}  // namespace

std::vector<Layer> find_layers(const OIIO::ParamValueList &attributes,
                               const std::string &image_path)
{
    // cryptomatte/<key>/<field>, grouped by key.
    std::map<std::string, std::map<std::string, std::string>> by_key;
    for (const OIIO::ParamValue &p : attributes) {
        const std::string n = p.name().string();
        if (n.compare(0, kPrefix.size(), kPrefix) != 0) {
            continue;
        }
        const std::size_t slash = n.find('/', kPrefix.size());
        if (slash == std::string::npos) {
            continue;
        }
        const std::string key = n.substr(kPrefix.size(), slash - kPrefix.size());
        by_key[key][n.substr(slash + 1)] = p.get_string();
    }
    std::vector<Layer> layers;
    for (const auto &entry : by_key) {
        const std::string &key = entry.first;
        const std::map<std::string, std::string> &fields = entry.second;
        Layer l;
        l.key = key;
        l.name = fields.count("name") ? fields.at("name") : std::string();
        const std::string what =
            image_path + ": cryptomatte \"" + (l.name.empty() ? key : l.name) + "\"";
        try {
            check_declaration(l, fields, what, image_path);
        } catch (const Error &e) {
            // Kept with its problem: it is an error where this cryptomatte is used, and no
            // hindrance to the file's others.
            l.problem = e.what();
            l.manifest.clear();
            l.has_manifest = false;
        }
        layers.push_back(std::move(l));
    }
    std::stable_sort(layers.begin(), layers.end(), [](const Layer &a, const Layer &b) {
        return a.name < b.name;
    });
    return layers;
}

namespace {

/// The key of a "cryptomatte/<key>/<field>" attribute, or "" for any other.
std::string key_of(const std::string &name)
{
    if (name.compare(0, kPrefix.size(), kPrefix) != 0) {
        return {};
    }
    const std::size_t slash = name.find('/', kPrefix.size());
    return slash == std::string::npos ? std::string()
                                      : name.substr(kPrefix.size(), slash - kPrefix.size());
}

}  // namespace

OIIO::ParamValueList with_declarations_of(const OIIO::ParamValueList &own,
                                          const std::vector<const OIIO::ParamValueList *> &others)
{
    OIIO::ParamValueList out = own;
    std::set<std::string> taken;
    for (const OIIO::ParamValue &p : own) {
        taken.insert(key_of(p.name().string()));
    }
    for (const OIIO::ParamValueList *list : others) {
        std::set<std::string> here;
        for (const OIIO::ParamValue &p : *list) {
            const std::string key = key_of(p.name().string());
            if (!key.empty() && taken.count(key) == 0) {
                out.push_back(p);
                here.insert(key);
            }
        }
        taken.insert(here.begin(), here.end());
    }
    return out;
}

OIIO::ParamValueList declarations(const Frame &frame)
{
    if (!frame.source) {
        return frame.attributes;
    }
    std::vector<const OIIO::ParamValueList *> others;
    for (const SourcePart &part : frame.source->parts) {
        others.push_back(&part.spec.extra_attribs);
    }
    return with_declarations_of(frame.attributes, others);
}

std::vector<std::string> rank_passes(const Layer &layer,
                                     const std::vector<std::string> &pass_names,
                                     const std::string &where)
{
    // <name>NN for every NN present; the highest decides how many there must be.
    int highest = -1;
    std::vector<bool> present(100, false);
    for (const std::string &p : pass_names) {
        if (is_rank_of(layer.name, p)) {
            const int k = std::stoi(p.substr(p.size() - 2));
            present[std::size_t(k)] = true;
            highest = std::max(highest, k);
        }
    }
    std::vector<std::string> out;
    for (int k = 0; k <= highest; ++k) {
        const std::string suffix = {char('0' + k / 10), char('0' + k % 10)};
        if (!present[std::size_t(k)]) {
            throw_runtime(where,
                          ": cryptomatte \"",
                          layer.name,
                          "\" has rank layer ",
                          layer.name,
                          highest < 10 ? "0" : "",
                          highest,
                          " but not ",
                          layer.name,
                          suffix);
        }
        out.push_back(layer.name + suffix);
    }
    return out;
}

namespace {

/// The bytes of the UTF-8 character at name[n] (1 for a byte that starts none).
std::size_t char_bytes(std::string_view name, std::size_t n)
{
    const unsigned char c = static_cast<unsigned char>(name[n]);
    std::size_t len = c >= 0xf0 && c < 0xf8 ? 4 : c >= 0xe0 ? 3 : c >= 0xc0 ? 2 : 1;
    if (c >= 0xf8) {
        len = 1;
    }
    for (std::size_t k = 1; k < len; ++k) {
        if (n + k >= name.size() || (static_cast<unsigned char>(name[n + k]) & 0xc0) != 0x80) {
            return 1;  // not well formed: a byte is a character
        }
    }
    return len;
}

}  // namespace

bool name_matches(std::string_view pattern, std::string_view name)
{
    // Iterative glob with one backtrack point (the last `*`), by UTF-8 characters: `?` matches
    // "ü" (two bytes), and a `*` never ends inside a character.
    std::size_t p = 0, n = 0, star_p = std::string_view::npos, star_n = 0;
    while (n < name.size()) {
        if (p < pattern.size() && pattern[p] == '*') {
            star_p = ++p;
            star_n = n;
            continue;
        }
        if (p < pattern.size()) {
            const bool escaped = pattern[p] == '\\' && p + 1 < pattern.size();
            const char c = escaped ? pattern[p + 1] : pattern[p];
            if (!escaped && c == '?') {
                ++p;
                n += char_bytes(name, n);
                continue;
            }
            if (c == name[n]) {
                p += escaped ? 2 : 1;
                ++n;
                continue;
            }
        }
        if (star_p == std::string_view::npos) {
            return false;
        }
        p = star_p;
        star_n += char_bytes(name, star_n);
        n = star_n;
    }
    while (p < pattern.size() && pattern[p] == '*') {
        ++p;
    }
    return p == pattern.size();
}

bool has_wildcard(std::string_view pattern)
{
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] == '\\') {
            ++i;
        } else if (pattern[i] == '*' || pattern[i] == '?') {
            return true;
        }
    }
    return false;
}

std::string unescape(std::string_view pattern)
{
    std::string out;
    for (std::size_t i = 0; i < pattern.size(); ++i) {
        if (pattern[i] == '\\' && i + 1 < pattern.size()) {
            ++i;
        }
        out += pattern[i];
    }
    return out;
}

std::string request_for(std::string_view type)
{
    return std::string(kRequest) + std::string(type);
}

bool parse_request(std::string_view request, std::string &type)
{
    if (request.compare(0, kRequest.size(), kRequest) != 0) {
        return false;
    }
    type = std::string(request.substr(kRequest.size()));
    return true;
}

std::set<std::string> requested_ranks(const std::set<std::string> &optional,
                                      const OIIO::ParamValueList &attributes,
                                      const std::vector<std::string> &pass_names)
{
    std::set<std::string> out;
    std::vector<std::string> types;
    for (const std::string &request : optional) {
        std::string type;
        if (parse_request(request, type)) {
            types.push_back(type);
        }
    }
    if (types.empty()) {
        return out;
    }
    // The names alone: a declaration's other fields (and its sidecar) are not needed to keep
    // its layers.
    for (const OIIO::ParamValue &p : attributes) {
        const std::string n = p.name().string();
        if (n.compare(0, kPrefix.size(), kPrefix) != 0 || n.size() < 5 ||
            n.compare(n.size() - 5, 5, "/name") != 0) {
            continue;
        }
        Layer l;
        l.name = p.get_string();
        for (const std::string &type : types) {
            if (type.empty() || l.is(type)) {
                for (const std::string &pass : pass_names) {
                    if (is_rank_of(l.name, pass)) {
                        out.insert(pass);
                    }
                }
            }
        }
    }
    return out;
}

}  // namespace posthaste::cryptomatte
