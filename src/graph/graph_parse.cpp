// Graph::parse in steps: the JSON syntax, the top-level keys, the nodes' ids and types, their
// inputs, their parameters, the command line's --set overrides, the required parameters, and the
// evaluation order with its cycle check. Every refusal is a one-line usage error naming the file,
// JSON path, node and parameter.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/json_error.h"
#include "graph/graph.h"
#include "graph/graph_order.h"
#include "graph/node_catalog.h"
#include "graph/param_json.h"
#include "io/sequence.h"

namespace posthaste {

using json = nlohmann::json;

namespace {

bool valid_id(const std::string &id)
{
    if (id.empty()) {
        return false;
    }
    return std::all_of(id.begin(), id.end(), [](char c) {
        return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-';
    });
}

std::vector<std::string> param_names(const NodeType &type)
{
    std::vector<std::string> names;
    for (const ParamSpec &p : type.spec.params) {
        names.emplace_back(p.name);
    }
    return names;
}

const ParamSpec *find_param(const NodeType &type, const std::string &name)
{
    for (const ParamSpec &p : type.spec.params) {
        if (p.name == name) {
            return &p;
        }
    }
    return nullptr;
}

std::string read_text_file(const std::string &path)
{
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) {
        throw_usage(path, ": is a directory, not a graph file");  // (it read as empty JSON)
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw_usage(path, ": cannot open graph file");
    }
    std::ostringstream os;
    os << in.rdbuf();
    return os.str();
}

}  // namespace

/// The steps of Graph::parse (a friend of Graph).
struct GraphBuilder {
    /// The top-level keys: "frames", "base_dir" (moves g.base_dir_) and the graph-wide
    /// "aliases" (returned).
    static json top_level(Graph &g, const json &doc, const std::string &origin)
    {
        const std::string base_dir = g.base_dir_;
        if (!doc.is_object()) {
            throw_usage(origin, ": expected a JSON object with a \"nodes\" array");
        }
        static const std::vector<std::string> kTopKeys = {
            "nodes", "frames", "aliases", "base_dir", "description", "comment"};
        for (auto it = doc.begin(); it != doc.end(); ++it) {
            if (std::find(kTopKeys.begin(), kTopKeys.end(), it.key()) == kTopKeys.end()) {
                throw_usage(origin,
                            ":/",
                            it.key(),
                            ": unknown key \"",
                            it.key(),
                            "\"",
                            did_you_mean(it.key(), kTopKeys));
            }
        }
        if (!doc.contains("nodes") || !doc["nodes"].is_array() || doc["nodes"].empty()) {
            throw_usage(origin, ":/nodes: expected a non-empty array of nodes");
        }
        if (doc.contains("frames")) {
            const json &f = doc["frames"];
            if (f.is_number_integer()) {
                g.frames_ = std::to_string(f.get<int>());
            } else if (f.is_string()) {
                g.frames_ = f.get<std::string>();
            } else {
                throw_usage(origin,
                            ":/frames: expected a frame list string like \"1-48\", got ",
                            json_kind(f));
            }
            parse_frame_list(g.frames_, origin + ":/frames");
        }
        if (doc.contains("base_dir")) {
            const json &b = doc["base_dir"];
            if (!b.is_string() || b.get<std::string>().empty()) {
                throw_usage(
                    origin, ":/base_dir: expected a folder path string, got ", json_kind(b));
            }
            const std::filesystem::path dir(b.get<std::string>());
            g.base_dir_ = dir.is_absolute() || base_dir.empty()
                              ? dir.string()
                              : (std::filesystem::path(base_dir) / dir).lexically_normal().string();
        }
        json aliases = json::array();
        if (doc.contains("aliases")) {
            if (!doc["aliases"].is_array()) {
                throw_usage(origin,
                            ":/aliases: expected an array of alias rules, got ",
                            json_kind(doc["aliases"]));
            }
            aliases = doc["aliases"];
        }

        return aliases;
    }

    /// Pass 1: every node's id and type, in file order; returns the ids.
    static std::vector<std::string> identities(Graph &g,
                                               const json &nodes,
                                               const std::string &origin,
                                               const NodeCatalog &types)
    {
        // Pass 1: ids and types.
        std::vector<std::string> ids;
        for (std::size_t i = 0; i < nodes.size(); ++i) {
            const std::string path = origin + ":/nodes/" + std::to_string(i);
            const json &n = nodes[i];
            if (!n.is_object()) {
                throw_usage(path, ": expected a node object, got ", json_kind(n));
            }
            static const std::vector<std::string> kNodeKeys = {
                "id", "type", "inputs", "params", "comment"};
            for (auto it = n.begin(); it != n.end(); ++it) {
                if (std::find(kNodeKeys.begin(), kNodeKeys.end(), it.key()) == kNodeKeys.end()) {
                    throw_usage(path,
                                "/",
                                it.key(),
                                ": unknown key \"",
                                it.key(),
                                "\"",
                                did_you_mean(it.key(), kNodeKeys));
                }
            }
            if (!n.contains("id") || !n["id"].is_string() ||
                !valid_id(n["id"].get<std::string>())) {
                throw_usage(path,
                            "/id: expected a node id of letters, digits, '_' or '-', got ",
                            n.contains("id") ? json_kind(n["id"]) : "nothing");
            }
            const std::string id = n["id"].get<std::string>();
            if (std::find(ids.begin(), ids.end(), id) != ids.end()) {
                throw_usage(path, "/id: duplicate node id \"", id, "\"");
            }
            ids.push_back(id);
            if (!n.contains("type") || !n["type"].is_string()) {
                throw_usage(path, "/type: node \"", id, "\": expected a node type string");
            }
            const std::string type = n["type"].get<std::string>();
            const NodeType *nt = types.find(type);
            if (!nt) {
                std::vector<std::string> known;
                for (const NodeType *t : types.all()) {
                    known.emplace_back(t->spec.type);
                }
                throw_usage(path,
                            "/type: node \"",
                            id,
                            "\": unknown node type \"",
                            type,
                            "\"",
                            did_you_mean(type, known));
            }
            GraphNode gn;
            gn.identity = {id, type, path};
            gn.type = nt;
            g.nodes_.push_back(std::move(gn));
        }

        return ids;
    }

    /// A node's "inputs": each port names another node; required ports must be connected.
    static void inputs(GraphNode &gn, const json &n, const std::vector<std::string> &ids)
    {
        const std::string &path = gn.identity.json_path;
        const std::string who = gn.identity.describe();
        const NodeSpec &spec = gn.type->spec;
        gn.inputs.assign(spec.inputs.size(), -1);
        std::vector<std::string> ports;
        for (const PortSpec &p : spec.inputs) {
            ports.emplace_back(p.name);
        }
        if (n.contains("inputs")) {
            const json &in = n["inputs"];
            if (!in.is_object()) {
                throw_usage(path,
                            "/inputs: ",
                            who,
                            ": expected an object mapping input ports to node ids, got ",
                            json_kind(in));
            }
            for (auto it = in.begin(); it != in.end(); ++it) {
                const auto port = std::find(ports.begin(), ports.end(), it.key());
                if (port == ports.end()) {
                    throw_usage(
                        path,
                        "/inputs/",
                        it.key(),
                        ": ",
                        who,
                        ": unknown input \"",
                        it.key(),
                        "\"",
                        ports.empty() ? std::string(" (this node takes no inputs)")
                                      : did_you_mean(it.key(), ports) + " (inputs: " +
                                            [&] {
                                                std::string s;
                                                for (auto &p : ports) {
                                                    s += (s.empty() ? "" : ", ") + p;
                                                }
                                                return s;
                                            }() +
                                            ")");
                }
                if (!it.value().is_string()) {
                    throw_usage(path,
                                "/inputs/",
                                it.key(),
                                ": ",
                                who,
                                ": expected the id of another node, got ",
                                json_kind(it.value()));
                }
                const std::string src = it.value().get<std::string>();
                const auto found = std::find(ids.begin(), ids.end(), src);
                if (found == ids.end()) {
                    throw_usage(path,
                                "/inputs/",
                                it.key(),
                                ": ",
                                who,
                                ": input \"",
                                it.key(),
                                "\" names unknown node \"",
                                src,
                                "\"",
                                did_you_mean(src, ids));
                }
                gn.inputs[std::size_t(port - ports.begin())] = int(found - ids.begin());
            }
        }
        for (std::size_t p = 0; p < spec.inputs.size(); ++p) {
            if (gn.inputs[p] < 0 && !spec.inputs[p].optional) {
                throw_usage(path,
                            "/inputs: ",
                            who,
                            ": required input \"",
                            spec.inputs[p].name,
                            "\" is not connected");
            }
        }
    }

    /// A node's "params", through each parameter's declared conversion; the graph-wide aliases
    /// reach every node that declares an "aliases" parameter; file parameters resolve against
    /// the graph's base folder.
    static void params(const Graph &g, GraphNode &gn, const json &n, const json &aliases)
    {
        const std::string &path = gn.identity.json_path;
        const std::string who = gn.identity.describe();
        const NodeSpec &spec = gn.type->spec;
        std::map<std::string, ParamValue> values;
        for (const ParamSpec &p : spec.params) {
            values[std::string(p.name)] = default_param(p);
        }
        json params = n.contains("params") ? n["params"] : json::object();
        if (!params.is_object()) {
            throw_usage(path,
                        "/params: ",
                        who,
                        ": expected an object of parameters, got ",
                        json_kind(params));
        }
        // Graph-wide aliases reach every node that declares an "aliases" parameter.
        if (!aliases.empty() && find_param(*gn.type, "aliases")) {
            json merged = params.contains("aliases") && params["aliases"].is_array()
                              ? params["aliases"]
                              : json::array();
            for (const json &a : aliases) {
                merged.push_back(a);
            }
            params["aliases"] = merged;
        }
        for (auto it = params.begin(); it != params.end(); ++it) {
            const ParamSpec *ps = find_param(*gn.type, it.key());
            const std::string ppath = path + "/params/" + it.key();
            if (!ps) {
                throw_usage(ppath,
                            ": ",
                            who,
                            ": unknown param \"",
                            it.key(),
                            "\"",
                            did_you_mean(it.key(), param_names(*gn.type)));
            }
            ParamValue v = convert_param(*ps, it.value(), ppath, who);
            if (ps->file && !v.text.empty() && !g.base_dir_.empty() &&
                std::filesystem::path(v.text).is_relative()) {
                v.text = (std::filesystem::path(g.base_dir_) / v.text).lexically_normal().string();
            }
            values[it.key()] = std::move(v);
        }
        gn.params = NodeParams(gn.type, std::move(values));
    }

    /// --set node.param=value, through the same conversion and checks.
    static void overrides(Graph &g,
                          const std::vector<std::string> &overrides,
                          const std::vector<std::string> &ids)
    {
        for (const std::string &o : overrides) {
            const std::string where = "--set " + o;
            const auto eq = o.find('=');
            const auto dot = o.find('.');
            if (eq == std::string::npos || dot == std::string::npos || dot > eq) {
                throw_usage(where, ": expected node.param=value");
            }
            const std::string id = o.substr(0, dot);
            const std::string name = o.substr(dot + 1, eq - dot - 1);
            const std::string text_value = o.substr(eq + 1);
            const auto found = std::find(ids.begin(), ids.end(), id);
            if (found == ids.end()) {
                throw_usage(where, ": unknown node \"", id, "\"", did_you_mean(id, ids));
            }
            GraphNode &gn = g.nodes_[std::size_t(found - ids.begin())];
            const ParamSpec *ps = find_param(*gn.type, name);
            if (!ps) {
                throw_usage(where,
                            ": ",
                            gn.identity.describe(),
                            ": unknown param \"",
                            name,
                            "\"",
                            did_you_mean(name, param_names(*gn.type)));
            }
            json v;
            if (ps->type == ParamType::String || ps->type == ParamType::Choice) {
                // Plain text, or a JSON string ("height" in quotes: the quotes were kept).
                v = text_value;
                if (text_value.size() >= 2 && text_value.front() == '"' &&
                    text_value.back() == '"') {
                    const json s = json::parse(text_value, nullptr, /*allow_exceptions=*/false);
                    if (s.is_string()) {
                        v = s;
                    }
                }
            } else if (json_depth(text_value) > kMaxJsonDepth) {
                throw_usage(where,
                            ": ",
                            gn.identity.describe(),
                            ": param \"",
                            name,
                            "\": the value nests more than ",
                            kMaxJsonDepth,
                            " levels deep");
            } else {
                v = json::parse(text_value, nullptr, /*allow_exceptions=*/false);
                if (v.is_discarded()) {
                    v = text_value;
                }
            }
            std::map<std::string, ParamValue> values = gn.params.values();
            values[name] = convert_param(*ps, v, where, gn.identity.describe());
            gn.params = NodeParams(gn.type, std::move(values));
        }
    }

    /// Every required parameter is given.
    static void required(const Graph &g)
    {
        // Required parameters.
        for (const GraphNode &gn : g.nodes_) {
            for (const ParamSpec &p : gn.type->spec.params) {
                const ParamSpec *control = p.when_param.empty()
                                               ? nullptr
                                               : find_param(*gn.type, std::string(p.when_param));
                const bool applies =
                    !control ||
                    condition_holds(p, *control, gn.params.values().at(std::string(control->name)));
                if (p.required && applies && !gn.params.given(p)) {
                    throw_usage(gn.identity.json_path,
                                "/params: ",
                                gn.identity.describe(),
                                ": required param \"",
                                p.name,
                                "\" is missing");
                }
            }
        }
    }

    /// Parameters given where they do not apply (ParamSpec::only_when): refused, naming the
    /// parameter that rules it out and its value.
    static void applicable(const Graph &g)
    {
        for (const GraphNode &gn : g.nodes_) {
            for (const ParamSpec &p : gn.type->spec.params) {
                if (p.when_param.empty() || !gn.params.given(p)) {
                    continue;
                }
                const ParamSpec *control = find_param(*gn.type, std::string(p.when_param));
                if (!control) {
                    throw_runtime(gn.identity.describe(),
                                  ": internal: param \"",
                                  p.name,
                                  "\" depends on an undeclared param \"",
                                  p.when_param,
                                  "\"");
                }
                const std::string word =
                    condition_word(*control, gn.params.values().at(std::string(control->name)));
                const std::vector<std::string> words = split_choices(p.when_values);
                if (std::find(words.begin(), words.end(), word) == words.end()) {
                    throw_usage(gn.identity.json_path,
                                "/params/",
                                p.name,
                                ": ",
                                gn.identity.describe(),
                                ": param \"",
                                p.name,
                                "\" applies only when ",
                                describe_condition(p),
                                ", not ",
                                word);
                }
            }
        }
    }

    /// Consumers, the cycle check, and the evaluation order; a graph must have a sink.
    static void order(Graph &g, const std::string &origin)
    {
        g.order_ = evaluation_order(g.nodes_);
        bool has_sink = false;
        for (const GraphNode &gn : g.nodes_) {
            has_sink = has_sink || gn.type->spec.sink;
        }
        if (!has_sink) {
            throw_usage(origin,
                        ":/nodes: the graph has no sink (write) node, so it would produce "
                        "nothing");
        }
        g.check_sink_paths(1);
    }
};

// Two sinks with one path would write over each other's files, frame by frame: the same file
// for a frame, however spelled (a.####.exr and a.%04d.exr, relative and absolute; f.###.exr and
// f.####.exr from frame 1000 on, so a run checks its frames' largest number too).
void Graph::check_sink_paths(int frame) const
{
    std::map<std::string, const GraphNode *> paths;
    for (const GraphNode &gn : nodes_) {
        const auto it = gn.params.values().find("path");
        if (!gn.type->spec.sink || it == gn.params.values().end() || it->second.text.empty()) {
            continue;
        }
        std::error_code ec;
        const std::filesystem::path file(expand_frame_pattern(it->second.text, frame));
        const std::filesystem::path absolute = std::filesystem::absolute(file, ec);
        const std::string key = (ec ? file : absolute).lexically_normal().string();
        const auto [first, fresh] = paths.emplace(key, &gn);
        if (!fresh) {
            throw_usage(gn.identity.json_path,
                        "/params/path: ",
                        gn.identity.describe(),
                        ": writes the same files as ",
                        first->second->identity.describe(),
                        " (",
                        quoted(it->second.text),
                        frame == 1 ? "" : str_cat(" at frame ", frame),
                        ")");
        }
    }
}

Graph Graph::load(const std::string &path,
                  const NodeCatalog &types,
                  const std::vector<std::string> &overrides)
{
    // A graph from a pipe (/dev/stdin, <(...)) resolves its relative paths against the current
    // folder, as a command line's do: against /dev or /dev/fd they named nothing.
    std::error_code ec;
    const std::string folder = std::filesystem::is_regular_file(path, ec)
                                   ? std::filesystem::path(path).parent_path().string()
                                   : "";
    return parse(read_text_file(path), path, types, overrides, folder.empty() ? "." : folder);
}

Graph Graph::parse(const std::string &text,
                   const std::string &origin,
                   const NodeCatalog &types,
                   const std::vector<std::string> &overrides,
                   const std::string &base_dir)
{
    Graph g;
    g.origin_ = origin;
    g.base_dir_ = base_dir;
    const json doc = parse_json_document(text, origin);
    const json aliases = GraphBuilder::top_level(g, doc, origin);
    const json &nodes = doc["nodes"];
    const std::vector<std::string> ids = GraphBuilder::identities(g, nodes, origin, types);
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        GraphBuilder::inputs(g.nodes_[i], nodes[i], ids);
        GraphBuilder::params(g, g.nodes_[i], nodes[i], aliases);
    }
    GraphBuilder::overrides(g, overrides, ids);
    GraphBuilder::required(g);
    GraphBuilder::applicable(g);
    GraphBuilder::order(g, origin);
    g.plan();
    return g;
}

}  // namespace posthaste
