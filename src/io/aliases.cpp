#include "io/aliases.h"

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>
#include <numeric>
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
        // Shader AOVs a user adds for the passes Blender does not write (docs/CONVENTIONS.md):
        // albedo (colour, the Principled base colour: DiffCol is black on a metal), roughness
        // and metallic (values); anisotropy 0.
        r.push_back(rule("albedo", {"*.albedo.R", "*.albedo.G", "*.albedo.B"}, "Blender"));
        r.push_back(rule("material", {"*.roughness.X", "*.metallic.X", ""}, "Blender"));
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
        // V-Ray: VRayDiffuseFilter is the pure diffuse surface colour. Its depth, velocity and
        // normals need render settings posthaste cannot see: builtin_refusal_rules.
        const std::vector<std::vector<std::string>> rgb = {{"R", "G", "B"},
                                                           {"red", "green", "blue"}};
        auto layer3 = [](const std::string &layer, const std::vector<std::string> &s) {
            return std::vector<std::string>{
                layer + "." + s[0], layer + "." + s[1], layer + "." + s[2]};
        };
        for (const auto &s : rgb) {
            r.push_back(rule("albedo", layer3("VRayDiffuseFilter", s), "V-Ray"));
        }
        // Redshift: DiffuseFilter (diffuse colour without lighting), P (World Position), N; the
        // Depth AOV in its default raw "Z" mode is the canonical Z channel.
        for (const auto &s : rgb) {
            r.push_back(rule("albedo", layer3("DiffuseFilter", s), "Redshift"));
        }
        r.push_back(rule("position", layer3("P", rgb[1]), "Redshift"));
        r.push_back(rule("normal", layer3("N", rgb[1]), "Redshift"));
        // Unreal Movie Render Queue: WorldDepth in centimetres in R (metres here). A 16-bit
        // post-process material saturates at 65504 cm; from 655 m on, depth is the sky (+inf).
        r.push_back(rule(
            "depth", {"FinalImageMovieRenderQueue_WorldDepth.R"}, "Unreal MRQ", {0.01f}, 655.0f));
        // Karma: C is the beauty, Pz the depth along the view axis (ray:hitPz); its albedo is
        // the canonical albedo.R/G/B.
        r.push_back(rule("color", {"C.R", "C.G", "C.B", "C.A"}, "Karma"));
        r.push_back(rule("depth", {"Pz"}, "Karma"));

        // RenderMan: z is camera-space depth; __Nworld and __Pworld are the world-space normal
        // and position (Nn and P are camera space).
        r.push_back(rule("depth", {"z"}, "RenderMan"));
        for (const auto &s :
             std::vector<std::vector<std::string>>{{"r", "g", "b"}, {"x", "y", "z"}}) {
            r.push_back(rule("normal", layer3("__Nworld", s), "RenderMan"));
            r.push_back(rule("position", layer3("__Pworld", s), "RenderMan"));
        }
        r.push_back(rule("albedo", {"albedo.r", "albedo.g", "albedo.b"}, "RenderMan"));
        int priority = 100;
        for (AliasRule &a : r) {
            a.priority = priority++;
        }
        return r;
    }();
    return kRules;
}

const std::vector<RefusalRule> &builtin_refusal_rules()
{
    static const std::vector<RefusalRule> kRules = [] {
        std::vector<RefusalRule> r;
        auto add = [&](std::string pass,
                       std::vector<std::string> channels,
                       std::string origin,
                       std::string message) {
            r.push_back(
                {std::move(pass), std::move(channels), std::move(origin), std::move(message)});
        };
        const std::string alias_help = " (a graph \"aliases\" rule, docs/CONVENTIONS.md)";
        // V-Ray (docs.chaos.com, VRayZDepth / Velocity / render element pages).
        for (const char *c : {"VRayZDepth.R", "VRayZDepth.Z", "VRayZDepth.Y", "VRayZDepth"}) {
            add("depth",
                {c},
                "V-Ray",
                "{C0} is V-Ray's Z-depth, normalised by default (Clamp on, Black 0 to White 1000, "
                "filtered): render it with Clamp and Filtering off, Black 0 and White 1, then map "
                "it with {\"pass\": \"depth\", \"channels\": [\"{C0}\"]}" +
                    alias_help);
        }
        for (const auto &xy : std::vector<std::vector<std::string>>{
                 {"VRayVelocity.X", "VRayVelocity.Y"}, {"VRayVelocity.R", "VRayVelocity.G"}}) {
            for (const char *pass : {"motion", "motion_next"}) {
                add(pass,
                    xy,
                    "V-Ray",
                    "{C0}/{C1} are V-Ray's velocity, clamped and grey-centred by default (Clamp "
                    "velocity on, Max velocity 1), from this frame to the next, y up: render with "
                    "Clamp velocity and Filtering off, check the sign on a known move, then map it "
                    "with {\"pass\": \"motion_next\", \"channels\": [\"{C0}\", \"{C1}\"], "
                    "\"scale\": [1, -1]}" +
                        alias_help);
            }
        }
        for (const auto &n : std::vector<std::vector<std::string>>{
                 {"VRayNormals.X", "VRayNormals.Y", "VRayNormals.Z"},
                 {"VRayNormals.R", "VRayNormals.G", "VRayNormals.B"}}) {
            add("normal",
                n,
                "V-Ray",
                "VRayNormals are camera-space and posthaste's normal is world-space: add a "
                "VRaySamplerInfo render element (Normal, World) and map its channels" +
                    alias_help);
        }
        // Redshift (docs.redshift3d.com, Motion Vectors AOV).
        for (const auto &xy :
             std::vector<std::vector<std::string>>{{"MotionVectors.R", "MotionVectors.G"},
                                                   {"MotionVectors.red", "MotionVectors.green"}}) {
            add("motion",
                xy,
                "Redshift",
                "{C0}/{C1} are Redshift's motion vectors, encoded into 0..1 by default (Max Motion "
                "In Pixels, Image Output Min/Max): render with Output Raw Vectors on and "
                "Filtering off, check direction and sign on a known move, then map them with "
                "{\"pass\": \"motion\", \"channels\": [\"{C0}\", \"{C1}\"], \"scale\": [1, -1]}" +
                    alias_help);
        }
        // Unreal Movie Render Queue (dev.epicgames.com, Cinematic Render Passes).
        add("motion",
            {"FinalImageMovieRenderQueue_MotionVectors.R",
             "FinalImageMovieRenderQueue_MotionVectors.G"},
            "Unreal MRQ",
            "Unreal's MotionVectors are screen-normalised around 0.5 (0.5 = no motion) and "
            "sources disagree on their factor (1 or 2) and sign: check a known move, then map "
            "them with {\"pass\": \"motion\", \"channels\": [\"{C0}\", \"{C1}\"], \"scale\": "
            "[{W}, -{H}], \"offset\": [-{W/2}, {H/2}]} (this file is {W}x{H}; double both if "
            "your move comes out half as long)" +
                alias_help);
        // RenderMan (rmanwiki, Arbitrary Output Variables).
        for (const auto &v :
             std::vector<std::vector<std::string>>{{"r", "g"}, {"x", "y"}, {"R", "G"}}) {
            add("motion",
                {"motionBack." + v[0], "motionBack." + v[1]},
                "RenderMan",
                "{C0}/{C1} are RenderMan's motionBack, whose scale and offset Pixar does not "
                "document (Nuke's VectorBlur has a PRMan preset for them): measure a known move "
                "and map them with a scale and offset" +
                    alias_help);
            add("motion_next",
                {"motionFore." + v[0], "motionFore." + v[1]},
                "RenderMan",
                "{C0}/{C1} are RenderMan's motionFore, whose scale and offset Pixar does not "
                "document: measure a known move and map them with a scale and offset" +
                    alias_help);
        }
        for (const auto &v :
             std::vector<std::vector<std::string>>{{"r", "g", "b"}, {"x", "y", "z"}}) {
            add("normal",
                {"Nn." + v[0], "Nn." + v[1], "Nn." + v[2]},
                "RenderMan",
                "RenderMan's Nn is camera-space and posthaste's normal is world-space: output "
                "__Nworld (it maps without an alias)");
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

const std::vector<std::pair<std::string, std::string>> &known_conventions()
{
    static const std::vector<std::pair<std::string, std::string>> kNames = {
        {"blender", "Blender"},
        {"nuke", "Nuke"},
        {"arnold", "Arnold"},
        {"vray", "V-Ray"},
        {"redshift", "Redshift"},
        {"unreal", "Unreal MRQ"},
        {"karma", "Karma"},
        {"renderman", "RenderMan"}};
    return kNames;
}

namespace {

/// Whether a built-in rule of `origin` applies under `convention` ("" / "auto": all).
bool in_convention(const std::string &origin, const std::string &convention)
{
    if (convention.empty() || convention == "auto" || origin == "canonical") {
        return true;
    }
    for (const auto &[name, o] : known_conventions()) {
        if (name == convention) {
            return o == origin;
        }
    }
    return false;
}

}  // namespace

std::vector<PassSource> map_channels(const std::vector<PartChannels> &parts,
                                     const std::vector<AliasRule> &graph_rules,
                                     const std::string &convention)
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
    for (const AliasRule &r : builtin_alias_rules()) {
        if (in_convention(r.origin, convention)) {
            rules.push_back(r);
        }
    }
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
        PassSource &ps = others[layer];
        // EXR keeps a part's channels sorted by name: a pass of "0" to "11" comes back as 0, 1,
        // 10, 11, 2, ... Numbered channels go back in their numbers' order.
        const bool numbered = std::all_of(
            ps.channel_suffixes.begin(), ps.channel_suffixes.end(), [](const std::string &c) {
                return !c.empty() && c.size() < 9 &&
                       std::all_of(c.begin(), c.end(), [](char d) { return d >= '0' && d <= '9'; });
            });
        if (numbered && ps.sources.size() == ps.channel_suffixes.size()) {
            std::vector<std::size_t> idx(ps.sources.size());
            std::iota(idx.begin(), idx.end(), std::size_t(0));
            std::stable_sort(idx.begin(), idx.end(), [&](std::size_t i, std::size_t j) {
                return std::stoi(ps.channel_suffixes[i]) < std::stoi(ps.channel_suffixes[j]);
            });
            PassSource sorted = ps;
            for (std::size_t k = 0; k < idx.size(); ++k) {
                sorted.sources[k] = ps.sources[idx[k]];
                sorted.channel_suffixes[k] = ps.channel_suffixes[idx[k]];
            }
            ps = std::move(sorted);
        }
        out.push_back(std::move(ps));
    }
    return out;
}

std::vector<RefusedPass> refused_passes(const std::vector<PartChannels> &parts,
                                        const std::vector<PassSource> &made,
                                        int width,
                                        int height,
                                        const std::string &convention)
{
    auto has_channel = [&](const std::string &name) {
        for (const PartChannels &p : parts) {
            for (const std::string &n : p.names) {
                if (matches(name, n)) {
                    return true;
                }
            }
        }
        return false;
    };
    auto replace_all = [](std::string s, const std::string &from, const std::string &to) {
        for (std::size_t at = s.find(from); at != std::string::npos;
             at = s.find(from, at + to.size())) {
            s.replace(at, from.size(), to);
        }
        return s;
    };
    std::vector<RefusedPass> out;
    for (const RefusalRule &rule : builtin_refusal_rules()) {
        if (!in_convention(rule.origin, convention)) {
            continue;
        }
        const bool have_pass = std::any_of(
            made.begin(), made.end(), [&](const PassSource &p) { return p.pass == rule.pass; });
        const bool said = std::any_of(
            out.begin(), out.end(), [&](const RefusedPass &p) { return p.pass == rule.pass; });
        if (have_pass || said ||
            !std::all_of(rule.channels.begin(), rule.channels.end(), has_channel)) {
            continue;
        }
        std::string m = rule.message;
        for (std::size_t k = 0; k < rule.channels.size(); ++k) {
            m = replace_all(m, "{C" + std::to_string(k) + "}", rule.channels[k]);
        }
        auto half = [](int v) { return std::to_string(v / 2) + (v % 2 ? ".5" : ""); };
        m = replace_all(m, "{W/2}", half(width));
        m = replace_all(m, "{H/2}", half(height));
        m = replace_all(m, "{W}", std::to_string(width));
        m = replace_all(m, "{H}", std::to_string(height));
        out.push_back({rule.pass, rule.origin, std::move(m)});
    }
    return out;
}

}  // namespace posthaste
