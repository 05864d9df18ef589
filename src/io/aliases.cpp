#include "io/aliases.h"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.h"
#include "core/passes.h"

namespace posthaste {
namespace {

AliasRule rule(std::string pass,
               std::vector<std::string> channels,
               std::string origin,
               std::vector<float> scale = {},
               float infinite_above = 0.0f)
{
    AliasRule r;
    r.pass = std::move(pass);
    r.channels = std::move(channels);
    r.scale = std::move(scale);
    r.origin = std::move(origin);
    r.infinite_above = infinite_above;
    return r;
}

bool matches(const std::string &pattern, const std::string &name)
{
    if (pattern.starts_with("*.")) {
        const std::string tail = pattern.substr(1);  // ".Vector.X"
        return name == pattern.substr(2) || (name.size() > tail.size() && name.ends_with(tail));
    }
    return pattern == name;
}

std::string layer_of(const std::string &name)
{
    const auto dot = name.rfind('.');
    return dot == std::string::npos ? std::string() : name.substr(0, dot);
}

std::string suffix_of(const std::string &name)
{
    const auto dot = name.rfind('.');
    return dot == std::string::npos ? name : name.substr(dot + 1);
}

}  // namespace

const std::vector<AliasRule> &builtin_alias_rules()
{
    static const std::vector<AliasRule> kRules = [] {
        std::vector<AliasRule> r;
        // Canonical names (what posthaste writes).
        for (const pass::CanonicalPass &cp : pass::canonical_passes()) {
            std::vector<std::string> names;
            for (std::string_view c : cp.channels) {
                names.push_back(cp.layer.empty() ? std::string(c)
                                                 : std::string(cp.layer) + "." + std::string(c));
            }
            r.push_back(rule(std::string(cp.name), names, "canonical"));
        }
        // Blender multilayer EXR (any view-layer name). Vector X,Y = previous minus current
        // position in pixels with y up, so motion = (-X, +Y); Z,W = current minus next.
        r.push_back(rule(
            "color", {"*.Combined.R", "*.Combined.G", "*.Combined.B", "*.Combined.A"}, "Blender"));
        r.push_back(rule("depth", {"*.Depth.Z"}, "Blender", {}, 1e10f));
        r.push_back(rule("normal", {"*.Normal.X", "*.Normal.Y", "*.Normal.Z"}, "Blender"));
        r.push_back(rule("position", {"*.Position.X", "*.Position.Y", "*.Position.Z"}, "Blender"));
        r.push_back(rule("motion", {"*.Vector.X", "*.Vector.Y"}, "Blender", {-1.0f, 1.0f}));
        r.push_back(rule("motion_next", {"*.Vector.Z", "*.Vector.W"}, "Blender", {-1.0f, 1.0f}));
        r.push_back(rule("albedo", {"*.DiffCol.R", "*.DiffCol.G", "*.DiffCol.B"}, "Blender"));
        // Nuke: depth.Z as distance; backward = previous minus current (y up), forward = next
        // minus current (y up).
        r.push_back(rule("depth", {"depth.Z"}, "Nuke"));
        r.push_back(rule("motion", {"backward.u", "backward.v"}, "Nuke", {-1.0f, 1.0f}));
        r.push_back(rule("motion_next", {"forward.u", "forward.v"}, "Nuke", {1.0f, -1.0f}));
        // Arnold AOVs: N and P as RGB layers; motionvector R,G = screen motion in pixels over one
        // frame, y up (as Nuke's VectorBlur reads it).
        r.push_back(rule("normal", {"N.R", "N.G", "N.B"}, "Arnold"));
        r.push_back(rule("position", {"P.R", "P.G", "P.B"}, "Arnold"));
        r.push_back(rule("motion", {"motionvector.R", "motionvector.G"}, "Arnold", {1.0f, -1.0f}));
        r.push_back(rule("albedo", {"albedo.X", "albedo.Y", "albedo.Z"}, "Arnold"));
        int priority = 100;
        for (AliasRule &a : r) {
            a.priority = priority++;
        }
        return r;
    }();
    return kRules;
}

std::vector<AliasRule> parse_alias_rules(const std::string &json_text, const std::string &where)
{
    using json = nlohmann::json;
    std::vector<AliasRule> rules;
    const json doc = json::parse(json_text, nullptr, false);
    if (!doc.is_array()) {
        throw_usage(where, ": expected an array of alias rules");
    }
    for (std::size_t i = 0; i < doc.size(); ++i) {
        const json &a = doc[i];
        const std::string w = where + "[" + std::to_string(i) + "]";
        if (!a.is_object()) {
            throw_usage(w, ": expected an object {\"pass\": ..., \"channels\": [...]}");
        }
        for (auto it = a.begin(); it != a.end(); ++it) {
            static const std::vector<std::string> keys = {
                "pass", "channels", "scale", "offset", "infinite_above"};
            if (std::find(keys.begin(), keys.end(), it.key()) == keys.end()) {
                throw_usage(w,
                            ": unknown key \"",
                            it.key(),
                            "\" (keys: pass, channels, scale, "
                            "offset, infinite_above)");
            }
        }
        if (!a.contains("pass") || !a["pass"].is_string() || a["pass"].get<std::string>().empty()) {
            throw_usage(w, ": \"pass\" must be a pass name");
        }
        if (!a.contains("channels") || !a["channels"].is_array() || a["channels"].empty() ||
            a["channels"].size() > 4) {
            throw_usage(w, ": \"channels\" must be an array of 1 to 4 channel names");
        }
        AliasRule r;
        r.pass = a["pass"].get<std::string>();
        for (const json &c : a["channels"]) {
            if (!c.is_string()) {
                throw_usage(w, ": \"channels\" must hold strings");
            }
            r.channels.push_back(c.get<std::string>());
        }
        for (const char *key : {"scale", "offset"}) {
            if (!a.contains(key)) {
                continue;
            }
            const json &v = a[key];
            if (!v.is_array() || v.size() != r.channels.size()) {
                throw_usage(
                    w, ": \"", key, "\" must be an array of ", r.channels.size(), " numbers");
            }
            std::vector<float> &dst = std::string(key) == "scale" ? r.scale : r.offset;
            for (const json &x : v) {
                if (!x.is_number()) {
                    throw_usage(w, ": \"", key, "\" must hold numbers");
                }
                dst.push_back(x.get<float>());
            }
        }
        if (a.contains("infinite_above")) {
            if (!a["infinite_above"].is_number() || a["infinite_above"].get<double>() <= 0.0) {
                throw_usage(w, ": \"infinite_above\" must be a positive number");
            }
            r.infinite_above = a["infinite_above"].get<float>();
        }
        r.origin = "graph";
        r.priority = int(i);
        rules.push_back(std::move(r));
    }
    return rules;
}

std::vector<PassSource> map_channels(const std::vector<PartChannels> &parts,
                                     const std::vector<AliasRule> &graph_rules)
{
    struct Ref {
        int part, channel;
        std::string name;
    };
    std::vector<Ref> all;
    for (std::size_t p = 0; p < parts.size(); ++p) {
        for (std::size_t c = 0; c < parts[p].names.size(); ++c) {
            all.push_back({int(p), int(c), parts[p].names[c]});
        }
    }
    std::set<std::string> used;  // full names consumed by a pass
    std::vector<PassSource> out;
    std::set<std::string> made;

    auto find_channel = [&](const std::string &pattern) -> const Ref * {
        const Ref *best = nullptr;
        for (const Ref &r : all) {
            if (matches(pattern, r.name) && (!best || r.name < best->name)) {
                best = &r;  // several view layers: the alphabetically first one
            }
        }
        return best;
    };

    std::vector<AliasRule> rules = graph_rules;
    rules.insert(rules.end(), builtin_alias_rules().begin(), builtin_alias_rules().end());
    for (const AliasRule &rule : rules) {
        if (made.count(rule.pass)) {
            continue;
        }
        PassSource ps;
        ps.pass = rule.pass;
        ps.infinite_above = rule.infinite_above;
        ps.origin = rule.origin;
        bool complete = true;
        for (std::size_t k = 0; k < rule.channels.size(); ++k) {
            ChannelSource cs;
            cs.scale = rule.scale.empty() ? 1.0f : rule.scale[k];
            cs.offset = rule.offset.empty() ? 0.0f : rule.offset[k];
            if (!rule.channels[k].empty()) {
                const Ref *r = find_channel(rule.channels[k]);
                if (!r) {
                    // Color may lack alpha: A = 1.
                    if (rule.pass == pass::kColor && k == 3) {
                        cs.scale = 0.0f;
                        cs.offset = 1.0f;
                    } else {
                        complete = false;
                        break;
                    }
                } else {
                    cs.part = r->part;
                    cs.channel = r->channel;
                    cs.name = r->name;
                }
            }
            ps.sources.push_back(cs);
        }
        if (!complete) {
            continue;
        }
        const pass::CanonicalPass *canonical = pass::find_canonical(rule.pass);
        for (std::size_t k = 0; k < ps.sources.size(); ++k) {
            if (canonical && canonical->channels.size() == ps.sources.size()) {
                ps.channel_suffixes.emplace_back(canonical->channels[k]);
            } else {
                ps.channel_suffixes.push_back(suffix_of(rule.channels[k]));
            }
            if (!ps.sources[k].name.empty()) {
                used.insert(ps.sources[k].name);
            }
        }
        made.insert(rule.pass);
        out.push_back(std::move(ps));
    }

    // Luminance-only files: Y (and A) make the color pass.
    if (!made.count(pass::kColor)) {
        if (const Ref *y = find_channel("Y")) {
            PassSource ps;
            ps.pass = pass::kColor;
            ps.origin = "luminance";
            for (int k = 0; k < 3; ++k) {
                ps.sources.push_back({y->part, y->channel, y->name, 1.0f, 0.0f});
            }
            if (const Ref *a = find_channel("A")) {
                ps.sources.push_back({a->part, a->channel, a->name, 1.0f, 0.0f});
                used.insert(a->name);
            } else {
                ps.sources.push_back({-1, -1, "", 0.0f, 1.0f});
            }
            ps.channel_suffixes = {"R", "G", "B", "A"};
            used.insert(y->name);
            made.insert(pass::kColor);
            out.push_back(std::move(ps));
        }
    }

    // Everything else: one pass per layer, in file order.
    std::map<std::string, PassSource> others;
    std::vector<std::string> order;
    for (const Ref &r : all) {
        if (used.count(r.name)) {
            continue;
        }
        std::string layer = layer_of(r.name);
        if (layer.empty()) {
            layer = r.name;
        }
        if (made.count(layer)) {
            layer += "_file";  // do not shadow a canonical pass made from other channels
        }
        auto [it, inserted] = others.try_emplace(layer);
        if (inserted) {
            it->second.pass = layer;
            it->second.origin = "layer";
            order.push_back(layer);
        }
        if (it->second.sources.size() < std::size_t(64)) {
            it->second.sources.push_back({r.part, r.channel, r.name, 1.0f, 0.0f});
            it->second.channel_suffixes.push_back(suffix_of(r.name));
        }
    }
    for (const std::string &layer : order) {
        out.push_back(std::move(others[layer]));
    }
    return out;
}

}  // namespace posthaste
