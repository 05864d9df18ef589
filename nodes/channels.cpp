// nodes/channels.cpp: select, rename and shuffle passes. Applied in this order:
//   copy:   {"new_pass": ["color.R", "depth.Z", "1"]}  builds a pass from channels of existing
//           passes (or constants), or {"new_pass": "old_pass"} copies a whole pass;
//   rename: {"old": "new"} (all at once: {"a": "b", "b": "a"} swaps);   remove: "a,b";
//   keep: "a,b" or "*".
// Asks its input only for the passes that the result needs.

#include <algorithm>
#include <map>
#include <nlohmann/json.hpp>

#include "io/source_file.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kCopy =
    ParamSpec::json("copy", "{}")
        .doc(
            "New passes from channels: {\"name\": [\"pass.channel\" or a number, ...]} or "
            "{\"name\": \"pass\"}.");
constexpr ParamSpec kRename =
    ParamSpec::json("rename", "{}")
        .doc("Renames: {\"old\": \"new\"}, all at once ({\"a\": \"b\", \"b\": \"a\"} swaps).");
constexpr ParamSpec kRemove = ParamSpec::string("remove", "").doc("Passes to drop (comma list).");
constexpr ParamSpec kKeep =
    ParamSpec::string("keep", "*").doc("Passes to keep (comma list), * for all.");
constexpr ParamSpec kParams[] = {kCopy, kRename, kRemove, kKeep};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to reshape."}};

struct ChannelRef {
    std::string pass;    // empty: constant
    std::string suffix;  // channel name within the pass, or index digits
    float constant = 0.0f;
};
struct Copy {
    std::string target;
    std::string whole_pass;  // copy a whole pass
    std::vector<ChannelRef> channels;
};
struct Ops {
    std::vector<Copy> copies;
    std::vector<std::pair<std::string, std::string>> renames;
    std::vector<std::string> removes;
    bool keep_all = true;
    std::vector<std::string> keeps;
};

constexpr Binding<Ops> kOpsFields[] = {bind<&Ops::removes>(kRemove)};

Ops parse_ops(const NodeParams &params, const NodeIdentity &node)
{
    using json = nlohmann::json;
    const std::string where = node.json_path + "/params";
    Ops ops;
    const json copy = json::parse(params.get_json(kCopy));
    if (!copy.is_object()) {
        throw_usage(where, "/copy: ", node.describe(), ": expected an object");
    }
    for (auto it = copy.begin(); it != copy.end(); ++it) {
        Copy c;
        c.target = it.key();
        const std::string w = where + "/copy/" + it.key() + ": " + node.describe();
        if (it.value().is_string()) {
            c.whole_pass = it.value().get<std::string>();
        } else if (it.value().is_array() && !it.value().empty() && it.value().size() <= 4) {
            for (const json &e : it.value()) {
                ChannelRef r;
                if (e.is_number()) {
                    r.constant = e.get<float>();
                } else if (e.is_string()) {
                    const std::string s = e.get<std::string>();
                    const auto dot = s.rfind('.');
                    if (dot == std::string::npos || dot == 0 || dot + 1 == s.size()) {
                        throw_usage(w, ": channel \"", s, "\" must be written pass.channel");
                    }
                    r.pass = s.substr(0, dot);
                    r.suffix = s.substr(dot + 1);
                } else {
                    throw_usage(w, ": expected \"pass.channel\" strings or numbers");
                }
                c.channels.push_back(r);
            }
        } else {
            throw_usage(w, ": expected a pass name or an array of 1 to 4 channels");
        }
        ops.copies.push_back(std::move(c));
    }
    const json rename = json::parse(params.get_json(kRename));
    if (!rename.is_object()) {
        throw_usage(where, "/rename: ", node.describe(), ": expected an object {\"old\": \"new\"}");
    }
    for (auto it = rename.begin(); it != rename.end(); ++it) {
        if (!it.value().is_string() || it.value().get<std::string>().empty()) {
            throw_usage(
                where, "/rename/", it.key(), ": ", node.describe(), ": expected a new pass name");
        }
        const std::string to = it.value().get<std::string>();
        for (const auto &[other, target] : ops.renames) {
            if (target == to) {
                throw_usage(where,
                            "/rename/",
                            it.key(),
                            ": ",
                            node.describe(),
                            ": \"",
                            other,
                            "\" is renamed \"",
                            to,
                            "\" too");
            }
        }
        ops.renames.emplace_back(it.key(), to);
    }
    fill_into(ops, params, std::span<const Binding<Ops>>(kOpsFields));
    const std::string keep = params.get_string(kKeep);
    ops.keep_all = keep == "*";
    if (!ops.keep_all) {
        ops.keeps = split_list(keep);
    }
    return ops;
}

/// The storage of a pass a rename or a whole-pass copy writes under a new name: as the file held
/// it (half when every channel it came from was half, else float), not the new name's default
/// (float diffuse renamed albedo went out as half, half colour renamed beauty as float).
PixelStorage storage_as_read(const Frame &frame, const Pass &p)
{
    if (p.storage != PixelStorage::Auto || !frame.source) {
        return p.storage;
    }
    bool any = false, all_half = true;
    for (const ChannelOrigin &o : p.origin) {
        if (o.part < 0) {
            continue;  // a constant the reader made up
        }
        if (o.part >= int(frame.source->parts.size())) {
            return p.storage;
        }
        const OIIO::ImageSpec &spec = frame.source->parts[std::size_t(o.part)].spec;
        if (o.channel < 0 || o.channel >= spec.nchannels) {
            return p.storage;
        }
        any = true;
        all_half = all_half && spec.channelformat(o.channel).basetype == OIIO::TypeDesc::HALF;
    }
    return !any ? p.storage : all_half ? PixelStorage::Half : PixelStorage::Float;
}

void execute(NodeContext &ctx)
{
    const Ops ops = parse_ops(ctx.params(), ctx.node());
    const Frame &in = ctx.input("image");
    Frame &out = ctx.output();
    for (const Copy &c : ops.copies) {
        if (!c.whole_pass.empty()) {
            const Pass &p = in.pass(c.whole_pass, ctx.where());
            out.set(c.target, p.image, p.channels, storage_as_read(in, p));
            continue;
        }
        Image img = Image::uninitialized(in.width(), in.height(), int(c.channels.size()));
        std::vector<std::string> names;
        for (std::size_t k = 0; k < c.channels.size(); ++k) {
            const ChannelRef &r = c.channels[k];
            const int nch = img.channels();
            if (r.pass.empty()) {
                for (std::size_t i = 0; i < img.pixel_count(); ++i) {
                    img.data()[i * std::size_t(nch) + k] = r.constant;
                }
                names.push_back(std::to_string(k));
                continue;
            }
            const Pass &p = in.pass(r.pass, ctx.where());
            auto found = std::find(p.channels.begin(), p.channels.end(), r.suffix);
            if (found == p.channels.end()) {
                std::string have;
                for (const std::string &s : p.channels) {
                    have += (have.empty() ? "" : ", ") + s;
                }
                throw_runtime(ctx.where(),
                              ": pass \"",
                              r.pass,
                              "\" has no channel \"",
                              r.suffix,
                              "\" (have: ",
                              have,
                              ")");
            }
            const int src = int(found - p.channels.begin());
            const int sn = p.image->channels();
            for (std::size_t i = 0; i < img.pixel_count(); ++i) {
                img.data()[i * std::size_t(nch) + k] =
                    p.image->data()[i * std::size_t(sn) + std::size_t(src)];
            }
            names.push_back(r.suffix);
        }
        // Canonical targets take their canonical channel names; repeated names become indices.
        const pass::CanonicalPass *cp = pass::find_canonical(c.target);
        std::vector<std::string> sorted = names;
        std::sort(sorted.begin(), sorted.end());
        if ((cp && cp->channels.size() == names.size()) ||
            std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) {
            names.clear();
            if (!cp || cp->channels.size() != c.channels.size()) {
                for (std::size_t k = 0; k < c.channels.size(); ++k) {
                    names.push_back(std::to_string(k));
                }
            }
        }
        out.set(c.target, std::make_shared<const Image>(std::move(img)), names);
    }
    // Renames happen at once, as one shuffle: {"color": "color@right", "color@right": "color"}
    // swaps the two (one after the other, the second found the first's result and an eye was
    // lost).
    std::vector<Pass> renaming;
    for (const auto &[from, to] : ops.renames) {
        renaming.push_back(out.pass(from, ctx.where()));
    }
    for (const auto &[from, to] : ops.renames) {
        out.erase(from);
    }
    for (std::size_t r = 0; r < ops.renames.size(); ++r) {
        const auto &[from, to] = ops.renames[r];
        const Pass &p = renaming[r];
        if (to == pass::kDepth && p.channels.size() != 1) {
            // depth's channel is the file's bare Z: four channels under it read back as colour.
            throw_runtime(ctx.where(),
                          ": rename \"",
                          from,
                          "\" -> \"depth\": depth has one channel (Z), \"",
                          from,
                          "\" has ",
                          p.channels.size(),
                          "; copy one channel instead ({\"depth\": [\"",
                          from,
                          ".",
                          p.channels.front(),
                          "\"]})");
        }
        if (from != to && out.has(to)) {
            ctx.state().note_once(str_cat(ctx.node().describe(),
                                          ": rename \"",
                                          from,
                                          "\" -> \"",
                                          to,
                                          "\" replaces the pass \"",
                                          to,
                                          "\" the frame had"));
        }
        // A canonical name brings its channel names where the channel count is the canonical
        // pass's; otherwise the pass keeps its own (a 3-channel normal renamed "ao" stays
        // X, Y, Z rather than turning into bare indices).
        const pass::CanonicalPass *cp = pass::find_canonical(to);
        const bool canonical_names = cp && cp->channels.size() == p.channels.size();
        Pass renamed;
        renamed.image = p.image;
        renamed.channels =
            canonical_names ? default_channel_names(to, int(p.channels.size())) : p.channels;
        renamed.storage = storage_as_read(out, p);
        // The file's channels are written fresh under the new name; the constants the reader
        // made up (an RGB file's alpha) stay out of the file unless a node makes them vary.
        renamed.origin = p.origin;
        for (ChannelOrigin &o : renamed.origin) {
            if (o.part >= 0) {
                o = ChannelOrigin{kRenamedPart, -1, 1.0f, 0.0f};
            }
        }
        out.set_pass(to, std::move(renamed));
    }
    for (const std::string &r : ops.removes) {
        out.erase(r);
    }
    if (!ops.keep_all) {
        for (const std::string &name : out.pass_names()) {
            if (std::find(ops.keeps.begin(), ops.keeps.end(), name) == ops.keeps.end()) {
                out.erase(name);
            }
        }
    }
}

void plan(PlanContext &ctx)
{
    const Ops ops = parse_ops(ctx.params, ctx.node);
    PassSet need = ctx.downstream;
    if (!ops.keep_all) {
        PassSet kept;
        for (const std::string &k : ops.keeps) {
            if (need.contains(k)) {
                kept.add(k);
            }
        }
        need = kept;
    }
    for (const std::string &r : ops.removes) {
        need.remove(r);
    }
    if (!need.all) {  // the renames at once: a wanted new name asks for its old one
        std::vector<std::string> wanted;
        for (const auto &[from, to] : ops.renames) {
            if (need.names.count(to)) {
                wanted.push_back(from);
            }
        }
        for (const auto &[from, to] : ops.renames) {
            need.remove(to);
            need.remove(from);
        }
        for (const std::string &from : wanted) {
            need.add(from);
        }
    }
    for (auto it = ops.copies.rbegin(); it != ops.copies.rend(); ++it) {
        const bool wanted = need.contains(it->target);
        if (!need.all) {
            need.remove(it->target);
        }
        if (wanted) {
            if (!it->whole_pass.empty()) {
                need.add(it->whole_pass);
            }
            for (const ChannelRef &r : it->channels) {
                if (!r.pass.empty()) {
                    need.add(r.pass);
                }
            }
        }
    }
    ctx.inputs[0] = need;
}

void check(CheckContext &ctx)
{
    parse_ops(ctx.params, ctx.node);
}

}  // namespace

extern const NodeType kChannels{
    {"channels",
     "Select, rename and shuffle passes.",
     kInputs,
     kParams,
     "",
     /*sink=*/false,
     /*keeps_specular=*/true},
    &execute,
    &plan,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kChannels, kOpsFields, problems); }};

}  // namespace posthaste::nodes
