#include "graph/graph.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/json_error.h"
#include "graph/node_registry.h"
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

std::string json_kind(const json &v)
{
    switch (v.type()) {
        case json::value_t::null:
            return "null";
        case json::value_t::boolean:
            return v.get<bool>() ? "true" : "false";
        case json::value_t::string:
            return "\"" + v.get<std::string>() + "\"";
        case json::value_t::number_integer:
        case json::value_t::number_unsigned:
        case json::value_t::number_float:
            return v.dump();
        case json::value_t::array:
            return "an array";
        case json::value_t::object:
            return "an object";
        default:
            return "?";
    }
}

/// Convert and check one parameter value. `where` prefixes the message.
ParamValue convert_param(const ParamSpec &spec, const json &v, const std::string &where)
{
    ParamValue out;
    out.given = true;
    auto fail = [&](const std::string &expected) {
        throw_usage(where, ": expected ", expected, ", got ", json_kind(v));
    };
    auto check_range = [&](double x) {
        if (x < spec.min || x > spec.max) {
            const std::string range = describe_range(spec);
            fail(describe_type(spec) + " in " + (range.empty() ? "range" : range));
        }
    };
    switch (spec.type) {
        case ParamType::Int: {
            if (!v.is_number()) {
                fail("integer" + (describe_range(spec).empty() ? "" : " " + describe_range(spec)));
            }
            const double x = v.get<double>();
            if (x != std::floor(x) || std::abs(x) > 2147483647.0) {
                fail("integer");
            }
            check_range(x);
            out.number = x;
            break;
        }
        case ParamType::Real: {
            if (!v.is_number()) {
                fail("number" + (describe_range(spec).empty() ? "" : " " + describe_range(spec)));
            }
            const double x = v.get<double>();
            if (!std::isfinite(x)) {
                fail("finite number");
            }
            check_range(x);
            out.number = x;
            break;
        }
        case ParamType::Bool:
            if (!v.is_boolean()) {
                fail("true or false");
            }
            out.number = v.get<bool>() ? 1.0 : 0.0;
            break;
        case ParamType::String:
            if (!v.is_string()) {
                fail("string");
            }
            out.text = v.get<std::string>();
            break;
        case ParamType::Choice: {
            const std::vector<std::string> words = split_choices(spec.choices);
            if (!v.is_string()) {
                fail("one of " + std::string(spec.choices));
            }
            out.text = v.get<std::string>();
            if (std::find(words.begin(), words.end(), out.text) == words.end()) {
                throw_usage(where,
                            ": expected one of ",
                            spec.choices,
                            ", got \"",
                            out.text,
                            "\"",
                            did_you_mean(out.text, words));
            }
            break;
        }
        case ParamType::Vec: {
            const std::string expected = "array of " + std::to_string(spec.vec_size) + " numbers";
            if (v.is_number() && spec.vec_size > 0) {
                // A single number broadcasts: "color": 0.5 is [0.5, 0.5, 0.5].
                const double x = v.get<double>();
                if (!std::isfinite(x)) {
                    fail(expected);
                }
                check_range(x);
                out.vec.assign(std::size_t(spec.vec_size), x);
                break;
            }
            if (!v.is_array() || int(v.size()) != spec.vec_size) {
                fail(expected);
            }
            for (const json &e : v) {
                if (!e.is_number() || !std::isfinite(e.get<double>())) {
                    fail(expected);
                }
                check_range(e.get<double>());
                out.vec.push_back(e.get<double>());
            }
            break;
        }
        case ParamType::Json:
            out.text = v.dump();
            break;
    }
    return out;
}

ParamValue default_param(const ParamSpec &spec)
{
    ParamValue out;
    out.number = spec.default_number;
    out.text = std::string(spec.default_text);
    for (int i = 0; i < spec.vec_size; ++i) {
        out.vec.push_back(spec.default_vec[std::size_t(i)]);
    }
    return out;
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
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw_usage(path, ": cannot open graph file");
    }
    std::ostringstream os;
    os << in.rdbuf();
    return os.str();
}

/// Line and column (1-based) of a byte offset, for JSON syntax errors.
std::string line_column(const std::string &text, std::size_t offset)
{
    int line = 1, col = 1;
    for (std::size_t i = 0; i < std::min(offset, text.size()); ++i) {
        if (text[i] == '\n') {
            ++line;
            col = 1;
        } else {
            ++col;
        }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

}  // namespace

int edit_distance(std::string_view a, std::string_view b)
{
    std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) {
        prev[j] = int(j);
    }
    for (std::size_t i = 1; i <= a.size(); ++i) {
        cur[0] = int(i);
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const int sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
        }
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

std::string did_you_mean(std::string_view word, const std::vector<std::string> &candidates)
{
    int best = 1 << 30;
    std::string best_word;
    for (const std::string &c : candidates) {
        const int d = edit_distance(word, c);
        if (d < best) {
            best = d;
            best_word = c;
        }
    }
    if (best_word.empty() || best > std::max<int>(2, int(word.size()) / 3)) {
        return "";
    }
    return " (did you mean \"" + best_word + "\"?)";
}

std::vector<int> parse_frame_list(const std::string &text, const std::string &what)
{
    std::vector<int> frames;
    auto bad = [&](const std::string &why) {
        throw_usage(what,
                    ": invalid frame list \"",
                    text,
                    "\": ",
                    why,
                    " (expected e.g. 1-48, 1-48x2, 1,5,10-20)");
    };
    auto parse_int = [&](const std::string &s) -> long long {
        if (s.empty()) {
            bad("missing number");
        }
        std::size_t pos = 0;
        long long v = 0;
        try {
            v = std::stoll(s, &pos);
        } catch (const std::exception &) {
            bad("\"" + s + "\" is not a number");
        }
        if (pos != s.size()) {
            bad("\"" + s + "\" is not a number");
        }
        if (v < -100000000 || v > 100000000) {
            bad("frame number " + s + " out of range");
        }
        return v;
    };
    for (const std::string &item : split_list(text)) {
        std::string range = item, step_text;
        if (auto x = item.find('x'); x != std::string::npos) {
            range = item.substr(0, x);
            step_text = item.substr(x + 1);
        }
        // A '-' after the first character separates the range ends (allows "-5--1").
        const std::size_t dash = range.find('-', 1);
        const long long a = parse_int(dash == std::string::npos ? range : range.substr(0, dash));
        const long long b = dash == std::string::npos ? a : parse_int(range.substr(dash + 1));
        const long long step = step_text.empty() ? 1 : parse_int(step_text);
        if (step <= 0) {
            bad("step must be positive");
        }
        if (b < a) {
            bad("range end " + std::to_string(b) + " is before its start " + std::to_string(a));
        }
        if ((b - a) / step + frames.size() > 1000000) {
            bad("more than 1000000 frames");
        }
        for (long long f = a; f <= b; f += step) {
            frames.push_back(int(f));
        }
    }
    if (frames.empty()) {
        bad("no frames");
    }
    return frames;
}

Graph Graph::load(const std::string &path, const std::vector<std::string> &overrides)
{
    const std::string folder = std::filesystem::path(path).parent_path().string();
    return parse(read_text_file(path), path, overrides, folder.empty() ? "." : folder);
}

Graph Graph::parse(const std::string &text,
                   const std::string &origin,
                   const std::vector<std::string> &overrides,
                   const std::string &base_dir)
{
    Graph g;
    g.origin_ = origin;
    g.base_dir_ = base_dir;
    json doc;
    try {
        doc = json::parse(text);
    } catch (const json::parse_error &e) {
        // nlohmann's text repeats the position: keep only what went wrong.
        std::string what = e.what();
        if (auto p = what.find(": syntax error"); p != std::string::npos) {
            what = what.substr(p + 2);
        } else if (auto q = what.rfind("]"); q != std::string::npos) {
            what = what.substr(q + 2);
        }
        throw_usage(origin,
                    ": ",
                    line_column(text, e.byte == 0 ? 0 : e.byte - 1),
                    ": invalid JSON: ",
                    what);
    } catch (const json::exception &e) {
        const std::string what = json_error_text(e.what());
        throw_usage(origin, ":", json_overflow_where(text, what), ": invalid JSON: ", what);
    }
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
            throw_usage(
                origin, ":/frames: expected a frame list string like \"1-48\", got ", json_kind(f));
        }
        parse_frame_list(g.frames_, origin + ":/frames");
    }
    if (doc.contains("base_dir")) {
        const json &b = doc["base_dir"];
        if (!b.is_string() || b.get<std::string>().empty()) {
            throw_usage(origin, ":/base_dir: expected a folder path string, got ", json_kind(b));
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

    // Pass 1: ids and types.
    const json &nodes = doc["nodes"];
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
        if (!n.contains("id") || !n["id"].is_string() || !valid_id(n["id"].get<std::string>())) {
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
        const NodeType *nt = find_node_type(type);
        if (!nt) {
            std::vector<std::string> known;
            for (const NodeType *t : all_node_types()) {
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

    // Pass 2: inputs and parameters.
    for (std::size_t i = 0; i < nodes.size(); ++i) {
        GraphNode &gn = g.nodes_[i];
        const json &n = nodes[i];
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
            ParamValue v =
                convert_param(*ps, it.value(), ppath + ": " + who + ": param \"" + it.key() + "\"");
            if (ps->file && !v.text.empty() && !g.base_dir_.empty() &&
                std::filesystem::path(v.text).is_relative()) {
                v.text = (std::filesystem::path(g.base_dir_) / v.text).lexically_normal().string();
            }
            values[it.key()] = std::move(v);
        }
        gn.params = NodeParams(gn.type, std::move(values));
    }

    // Overrides from the command line go through the same conversion and checks.
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
            v = text_value;
        } else {
            v = json::parse(text_value, nullptr, /*allow_exceptions=*/false);
            if (v.is_discarded()) {
                v = text_value;
            }
        }
        std::map<std::string, ParamValue> values = gn.params.values();
        values[name] = convert_param(
            *ps, v, where + ": " + gn.identity.describe() + ": param \"" + name + "\"");
        gn.params = NodeParams(gn.type, std::move(values));
    }

    // Required parameters.
    for (GraphNode &gn : g.nodes_) {
        for (const ParamSpec &p : gn.type->spec.params) {
            if (p.required && !gn.params.given(p)) {
                throw_usage(gn.identity.json_path,
                            "/params: ",
                            gn.identity.describe(),
                            ": required param \"",
                            p.name,
                            "\" is missing");
            }
        }
    }

    // Consumers, topological order and cycles.
    const int count = int(g.nodes_.size());
    for (int i = 0; i < count; ++i) {
        for (int src : g.nodes_[std::size_t(i)].inputs) {
            if (src >= 0) {
                g.nodes_[std::size_t(src)].consumers.push_back(i);
            }
        }
    }
    std::vector<int> state(std::size_t(count), 0);  // 0 new, 1 on stack, 2 done
    std::vector<int> stack;
    std::function<void(int)> visit = [&](int i) {
        state[std::size_t(i)] = 1;
        stack.push_back(i);
        for (int src : g.nodes_[std::size_t(i)].inputs) {
            if (src < 0) {
                continue;
            }
            if (state[std::size_t(src)] == 1) {
                std::string cycle;
                auto it = std::find(stack.begin(), stack.end(), src);
                for (; it != stack.end(); ++it) {
                    cycle += g.nodes_[std::size_t(*it)].identity.id + " <- ";
                }
                cycle += g.nodes_[std::size_t(src)].identity.id;
                throw_usage(g.nodes_[std::size_t(src)].identity.json_path,
                            "/inputs: node \"",
                            g.nodes_[std::size_t(src)].identity.id,
                            "\" is in a cycle: ",
                            cycle);
            }
            if (state[std::size_t(src)] == 0) {
                visit(src);
            }
        }
        stack.pop_back();
        state[std::size_t(i)] = 2;
        g.order_.push_back(i);
    };
    for (int i = 0; i < count; ++i) {
        if (state[std::size_t(i)] == 0) {
            visit(i);
        }
    }
    // Evaluation order: of the nodes whose inputs are ready, the one with the fewest nodes
    // downstream runs first, so short branches (a preview of the render, a hatching pass)
    // finish and free their frames before the long chain holds them (peak memory).
    {
        std::vector<int> downstream(std::size_t(count), 0);
        for (int i = 0; i < count; ++i) {
            std::vector<char> seen(std::size_t(count), 0);
            std::vector<int> todo = g.nodes_[std::size_t(i)].consumers;
            while (!todo.empty()) {
                const int c = todo.back();
                todo.pop_back();
                if (!seen[std::size_t(c)]) {
                    seen[std::size_t(c)] = 1;
                    ++downstream[std::size_t(i)];
                    for (int d : g.nodes_[std::size_t(c)].consumers) {
                        todo.push_back(d);
                    }
                }
            }
        }
        std::vector<char> done(std::size_t(count), 0);
        std::vector<int> order;
        while (int(order.size()) < count) {
            int best = -1;
            for (int i = 0; i < count; ++i) {
                if (done[std::size_t(i)]) {
                    continue;
                }
                bool ready = true;
                for (int src : g.nodes_[std::size_t(i)].inputs) {
                    ready = ready && (src < 0 || done[std::size_t(src)]);
                }
                if (ready &&
                    (best < 0 || downstream[std::size_t(i)] < downstream[std::size_t(best)])) {
                    best = i;
                }
            }
            done[std::size_t(best)] = 1;
            order.push_back(best);
        }
        g.order_ = std::move(order);
    }
    bool has_sink = false;
    for (const GraphNode &gn : g.nodes_) {
        has_sink = has_sink || gn.type->spec.sink;
    }
    if (!has_sink) {
        throw_usage(origin,
                    ":/nodes: the graph has no sink (write) node, so it would produce "
                    "nothing");
    }
    g.plan();
    return g;
}

int Graph::find(const std::string &id) const
{
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        if (nodes_[i].identity.id == id) {
            return int(i);
        }
    }
    return -1;
}

void Graph::set_capture(const std::string &id)
{
    capture_ = find(id);
    if (capture_ < 0) {
        throw_usage(origin_, ": no node \"", id, "\"");
    }
    plan();
}

void Graph::plan()
{
    const std::size_t count = nodes_.size();
    live_.assign(count, false);
    for (GraphNode &gn : nodes_) {
        gn.requested = PassSet{};
        gn.input_passes.assign(gn.inputs.size(), PassSet{});
    }
    // Reverse topological order: consumers are planned before their producers.
    for (auto it = order_.rbegin(); it != order_.rend(); ++it) {
        const int i = *it;
        GraphNode &gn = nodes_[std::size_t(i)];
        bool live = gn.type->spec.sink || i == capture_;
        for (int c : gn.consumers) {
            live = live || live_[std::size_t(c)];
        }
        live_[std::size_t(i)] = live;
        if (!live) {
            continue;
        }
        if (i == capture_) {
            gn.requested.all = true;
        }
        const NodeSpec &spec = gn.type->spec;
        std::vector<bool> connected;
        for (std::size_t p = 0; p < spec.inputs.size(); ++p) {
            connected.push_back(gn.inputs[p] >= 0);
            for (const std::string &pass : split_list(spec.inputs[p].passes)) {
                gn.input_passes[p].add(pass);
            }
        }
        if (!spec.inputs.empty()) {
            PassSet through = gn.requested;
            for (const std::string &made : split_list(spec.makes)) {
                through.remove(made);
            }
            gn.input_passes[0].add(through);
            for (const ParamSpec &ps : spec.params) {
                if (ps.passes) {
                    for (const std::string &pass : split_list(gn.params.get_string(ps))) {
                        gn.input_passes[0].add(pass);
                    }
                }
            }
        }
        if (gn.type->plan) {
            PlanContext ctx{gn.params, gn.identity, gn.requested, gn.input_passes, connected};
            gn.type->plan(ctx);
        }
        for (std::size_t p = 0; p < gn.inputs.size(); ++p) {
            if (gn.inputs[p] >= 0) {
                nodes_[std::size_t(gn.inputs[p])].requested.add(gn.input_passes[p]);
            }
        }
    }
}

std::vector<std::string> Graph::outputs(int frame) const
{
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const GraphNode &gn = nodes_[i];
        if (!live_[i] || gn.identity.type != "write") {
            continue;
        }
        if (auto it = gn.params.values().find("path"); it != gn.params.values().end()) {
            paths.push_back(expand_frame_pattern(it->second.text, frame));
        }
    }
    return paths;
}

std::vector<int> Graph::default_frames() const
{
    if (!frames_.empty()) {
        return parse_frame_list(frames_, origin_ + ":/frames");
    }
    for (int i : order_) {
        const GraphNode &gn = nodes_[std::size_t(i)];
        if (live_[std::size_t(i)] && gn.type->discover_frames) {
            std::vector<int> found = gn.type->discover_frames(gn.params);
            if (!found.empty()) {
                return found;
            }
        }
    }
    return {1};
}

void Graph::check(const std::vector<int> &frames) const
{
    for (int i : order_) {
        const GraphNode &gn = nodes_[std::size_t(i)];
        if (!live_[std::size_t(i)] || !gn.type->check) {
            continue;
        }
        std::vector<bool> connected;
        for (int src : gn.inputs) {
            connected.push_back(src >= 0);
        }
        CheckContext ctx{gn.params, gn.identity, gn.requested, frames, connected};
        gn.type->check(ctx);
    }
}

NodeTimes Graph::make_times() const
{
    NodeTimes t;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        t.nanoseconds.push_back(std::make_unique<std::atomic<long long>>(0));
    }
    return t;
}

const std::vector<int> &Graph::sequence_frames() const
{
    std::call_once(sequence_->once, [&] { sequence_->frames = default_frames(); });
    return sequence_->frames;
}

Frame Graph::evaluate(int frame, NodeTimes *times) const
{
    Frame captured;
    run_nodes(frame, times, -1, &captured);
    return captured;
}

std::shared_ptr<const Frame> Graph::run_nodes(int frame,
                                              NodeTimes *times,
                                              int target,
                                              Frame *captured) const
{
    const std::size_t count = nodes_.size();
    // The nodes to run: the live ones, or the target and its ancestors.
    std::vector<bool> run = live_;
    if (target >= 0) {
        run.assign(count, false);
        std::vector<int> stack = {target};
        while (!stack.empty()) {
            const int i = stack.back();
            stack.pop_back();
            if (run[std::size_t(i)]) {
                continue;
            }
            run[std::size_t(i)] = true;
            for (int src : nodes_[std::size_t(i)].inputs) {
                if (src >= 0) {
                    stack.push_back(src);
                }
            }
        }
    }
    std::vector<std::shared_ptr<const Frame>> results(count);
    std::vector<int> remaining(count, 0);
    for (std::size_t i = 0; i < count; ++i) {
        for (int c : nodes_[i].consumers) {
            remaining[i] += run[std::size_t(c)] ? 1 : 0;
        }
    }
    if (target >= 0) {
        ++remaining[std::size_t(target)];  // kept for the caller
    }
    for (int i : order_) {
        const GraphNode &gn = nodes_[std::size_t(i)];
        if (!run[std::size_t(i)]) {
            continue;
        }
        std::vector<std::shared_ptr<const Frame>> inputs;
        std::vector<std::string> ports;
        for (std::size_t p = 0; p < gn.inputs.size(); ++p) {
            inputs.push_back(gn.inputs[p] >= 0 ? results[std::size_t(gn.inputs[p])] : nullptr);
            ports.emplace_back(gn.type->spec.inputs[p].name);
        }
        NodeContext ctx(gn.identity,
                        gn.params,
                        std::move(inputs),
                        std::move(ports),
                        gn.requested,
                        frame,
                        *gn.state);
        const FrameHistory history{
            [this]() -> const std::vector<int> & { return sequence_frames(); },
            [this, i](std::size_t port, int other) -> std::shared_ptr<const Frame> {
                const int src = nodes_[std::size_t(i)].inputs[port];
                if (src < 0) {
                    return nullptr;
                }
                // Isolated: while this thread waits inside the upstream nodes' parallel loops it
                // must not pick up another frame's task, which could wait on what this one is
                // computing (a node's cache of earlier frames).
                std::shared_ptr<const Frame> out;
                tbb::this_task_arena::isolate(
                    [&] { out = run_nodes(other, nullptr, src, nullptr); });
                return out;
            }};
        ctx.set_history(&history);
        const auto t0 = std::chrono::steady_clock::now();
        if (target < 0 || !gn.type->spec.sink) {
            try {
                gn.type->execute(ctx);
            } catch (const Error &) {
                throw;
            } catch (const std::exception &e) {
                throw_runtime(ctx.where(), ": ", e.what());
            }
        }
        const auto t1 = std::chrono::steady_clock::now();
        if (times) {
            *times->nanoseconds[std::size_t(i)] +=
                std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count();
        }
        if (captured && i == capture_) {
            *captured = ctx.output();
        }
        if (remaining[std::size_t(i)] > 0) {
            // Keep only the passes some consumer asked for (a view's "pass@view" goes with its
            // pass): a G-buffer pass nobody downstream reads is freed now, not when the last
            // frame that carried it along is.
            Frame out = ctx.take_output();
            if (!gn.requested.all) {
                for (const std::string &name : out.pass_names()) {
                    const std::string base = name.substr(0, name.find('@'));
                    if (!gn.requested.contains(name) && !gn.requested.contains(base)) {
                        out.erase(name);
                    }
                }
            }
            results[std::size_t(i)] = std::make_shared<const Frame>(std::move(out));
        }
        // Free each input after its last consumer.
        for (int src : gn.inputs) {
            if (src >= 0 && --remaining[std::size_t(src)] == 0) {
                results[std::size_t(src)].reset();
            }
        }
    }
    return target >= 0 ? results[std::size_t(target)] : nullptr;
}

}  // namespace posthaste
