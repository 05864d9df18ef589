// posthaste.node / read / write / nodes / diff (py_module.h): one node run on frames in memory,
// through a one-node graph, so parameters are validated, defaulted and reported exactly as in a
// graph file.

#include <pybind11/stl.h>

#include <filesystem>
#include <list>
#include <mutex>

#include "graph/graph.h"
#include "graph/param_json.h"
#include "metrics/diff.h"
#include "metrics/report.h"
#include "nodes/registry.h"
#include "python/py_convert.h"
#include "python/py_frame.h"
#include "python/py_module.h"

namespace posthaste::python {
namespace {

/// A parsed one-node graph: placeholder sources on the node's connected ports, the node
/// captured (it keeps every pass). Cached by type, ports and parameters, so a loop over frames
/// parses once and the node's state (look-up tables) lives across calls, as over a graph's frames.
struct NodeCall {
    Graph graph;
    int index = -1;
    std::vector<std::string> ports;
};

/// Each file a parameter names (a scene, a LUT), as its absolute path, size and modification
/// time: the cache key then changes when a file is edited between calls, or when a relative path
/// names another file from another working folder (the node's state, loaded from the file once,
/// was kept: an edited scene rendered as before).
void add_files_to_key(const nlohmann::json &value, std::string &key)
{
    if (value.is_string()) {
        std::error_code ec;
        const std::filesystem::path path(value.get<std::string>());
        if (path.empty() || !std::filesystem::is_regular_file(path, ec)) {
            return;
        }
        const auto size = std::filesystem::file_size(path, ec);
        const auto time = std::filesystem::last_write_time(path, ec);
        key += "\n" + std::filesystem::absolute(path, ec).string() + "@" + std::to_string(size) +
               ":" + std::to_string(time.time_since_epoch().count());
    } else if (value.is_structured()) {
        for (const auto &item : value) {
            add_files_to_key(item, key);
        }
    }
}

std::shared_ptr<const NodeCall> node_call(const std::string &type,
                                          const std::vector<std::string> &ports,
                                          const nlohmann::json &params)
{
    static std::mutex mutex;
    static std::map<std::string, std::shared_ptr<const NodeCall>> cache;
    std::string key = type + "\n" + params.dump();
    for (const std::string &p : ports) {
        key += "\n" + p;
    }
    add_files_to_key(params, key);
    {
        std::lock_guard lock(mutex);
        if (const auto it = cache.find(key); it != cache.end()) {
            return it->second;
        }
    }
    // The node first, so messages locate its parameters at /nodes/0.
    nlohmann::json g;
    g["nodes"] = nlohmann::json::array();
    nlohmann::json node = {{"id", type}, {"type", type}, {"params", params}};
    node["inputs"] = nlohmann::json::object();
    for (const std::string &p : ports) {
        node["inputs"][p] = p + "_input";
    }
    g["nodes"].push_back(node);
    for (const std::string &p : ports) {
        g["nodes"].push_back(
            {{"id", p + "_input"}, {"type", "read"}, {"params", {{"path", "memory.exr"}}}});
    }
    if (!require_node_type(type).spec.sink) {
        // A graph needs a sink; this one is never run (the node is captured instead).
        g["nodes"].push_back({{"id", "_sink"},
                              {"type", "write"},
                              {"inputs", {{"image", type}}},
                              {"params", {{"path", "memory.exr"}}}});
    }
    auto call = std::make_shared<NodeCall>(NodeCall{
        Graph::parse(g.dump(), "posthaste.node(\"" + type + "\")", nodes::catalog()), -1, ports});
    call->graph.set_capture(type);
    call->index = call->graph.find(type);
    std::lock_guard lock(mutex);
    if (cache.size() >= 256) {
        cache.clear();
    }
    cache[key] = call;
    return call;
}

}  // namespace

std::shared_ptr<PyFrame> run_node(
    const std::string &type,
    const std::vector<std::pair<std::string, std::shared_ptr<PyFrame>>> &inputs,
    const nlohmann::json &params,
    std::optional<int> frame)
{
    std::vector<std::string> ports;
    std::vector<std::shared_ptr<const Frame>> frames;
    for (const auto &[port, f] : inputs) {
        ports.push_back(port);
        frames.push_back(f->share());
    }
    const std::shared_ptr<const NodeCall> call = node_call(type, ports, params);
    Frame out;
    {
        py::gil_scoped_release release;
        int number = 1;
        if (frame) {
            number = *frame;
        } else if (!frames.empty()) {
            number = frames.front()->number;
        } else {
            const std::vector<int> found = call->graph.default_frames();
            number = found.empty() ? 1 : found.front();
        }
        call->graph.check_node(call->index, {number});
        out = call->graph.run_node(call->index, std::move(frames), call->ports, number);
    }
    return std::make_shared<PyFrame>(std::move(out));
}

std::shared_ptr<PyFrame> frame_arg(py::handle v, const std::string &who)
{
    if (!py::isinstance<PyFrame>(v)) {
        throw py::type_error(who + ": expected a posthaste.Frame, got " + type_name(v));
    }
    return v.cast<std::shared_ptr<PyFrame>>();
}

py::object node(const std::string &type, py::args frames, py::kwargs kwargs)
{
    const NodeType &t = require_node_type(type);
    std::vector<std::pair<std::string, std::shared_ptr<PyFrame>>> inputs;
    const auto &ports = t.spec.inputs;
    if (frames.size() > ports.size()) {
        throw_usage("posthaste.node(\"",
                    type,
                    "\"): ",
                    frames.size(),
                    " frames given, but it has ",
                    ports.size(),
                    " input port(s)");
    }
    std::size_t p = 0;
    for (py::handle f : frames) {
        if (!f.is_none()) {
            const std::string port(ports[p].name);
            inputs.emplace_back(
                port, frame_arg(f, "posthaste.node(\"" + type + "\"): input \"" + port + "\""));
        }
        ++p;
    }
    nlohmann::json params = nlohmann::json::object();
    std::optional<int> number;
    for (auto [key, value] : kwargs) {
        // (a null cut the name short: a GraphError with a path and no reason)
        const std::string k =
            checked_text(key, "posthaste.node(\"" + type + "\"): param " + repr_text(key));
        if (k == "frame") {
            if (!value.is_none()) {
                number = cast_arg<int>(
                    value, "posthaste.node(\"" + type + "\"): frame", "an int (32 bits)");
            }
            continue;
        }
        bool port = false;
        for (const PortSpec &ps : ports) {
            port = port || ps.name == k;
        }
        if (port && value.is_none()) {
            continue;  // an input left out (mask=None), as a positional None is
        }
        if (port && !py::isinstance<PyFrame>(value)) {
            // (it went on as a parameter: "unknown param", or "input not connected")
            throw py::type_error("posthaste.node(\"" + type + "\"): input \"" + k +
                                 "\": expected a Frame, got " +
                                 std::string(py::str(value.get_type().attr("__name__"))));
        }
        if (py::isinstance<PyFrame>(value)) {
            if (!port) {
                throw_usage("posthaste.node(\"", type, "\"): no input port \"", k, "\"");
            }
            for (const auto &given : inputs) {
                if (given.first == k) {
                    throw_usage("posthaste.node(\"", type, "\"): input \"", k, "\" given twice");
                }
            }
            inputs.emplace_back(k, value.cast<std::shared_ptr<PyFrame>>());
            continue;
        }
        params[k] = to_json(value, "posthaste.node(\"" + type + "\"): param \"" + k + "\"");
    }
    std::shared_ptr<PyFrame> out = run_node(type, inputs, params, number);
    if (t.spec.sink) {
        return py::none();
    }
    return py::cast(out);
}

py::object diff(py::handle a, py::handle b, py::kwargs kwargs)
{
    metrics::DiffOptions o;
    o.images = false;
    metrics::Thresholds &t = o.thresholds;
    const std::map<std::string, float *> floats = {{"fail", &t.fail},
                                                   {"fail_relative", &t.fail_relative},
                                                   {"fail_percent", &t.fail_percent},
                                                   {"hard_fail", &t.hard_fail},
                                                   {"warn", &t.warn},
                                                   {"warn_relative", &t.warn_relative},
                                                   {"warn_percent", &t.warn_percent},
                                                   {"hard_warn", &t.hard_warn},
                                                   {"pixels_per_degree", &o.pixels_per_degree}};
    for (auto [key, value] : kwargs) {
        const std::string k = checked_text(key, "posthaste.diff: option " + repr_text(key));
        const std::string who = "posthaste.diff: " + k;
        if (const auto it = floats.find(k); it != floats.end()) {
            *it->second = cast_arg<float>(value, who, "a number");
            if (!(*it->second >= 0.0f)) {  // NaN too: it turned a FAILURE into a WARNING
                throw_usage(who, ": must be a number of at least 0, got ", *it->second);
            }
        } else if (k == "allow_failures") {
            t.allow_failures = cast_arg<int>(value, who, "an int");
            if (t.allow_failures < 0) {
                throw_usage(who, ": must be 0 or more, got ", t.allow_failures);
            }
        } else if (k == "passes") {
            if (py::isinstance<py::str>(value)) {
                throw py::type_error(who + ": expected a list of pass names, got a str");
            }
            o.passes = cast_arg<std::vector<std::string>>(value, who, "a list of pass names");
        } else if (k == "flip") {
            const std::string m = cast_arg<std::string>(value, who, "hdr, ldr or off");
            if (m != "hdr" && m != "ldr" && m != "off") {
                throw_usage("posthaste.diff: flip: expected hdr, ldr or off, got \"", m, "\"");
            }
            o.flip = m == "hdr"   ? metrics::FlipMode::Hdr
                     : m == "ldr" ? metrics::FlipMode::Ldr
                                  : metrics::FlipMode::Off;
        } else {
            throw_usage("posthaste.diff: unknown option \"", k, "\"");
        }
    }
    auto frame_of = [](py::handle x) -> std::shared_ptr<const Frame> {
        if (py::isinstance<PyFrame>(x)) {
            return x.cast<std::shared_ptr<PyFrame>>()->share();
        }
        const nlohmann::json j = to_json(x, "posthaste.diff");
        if (!j.is_string()) {
            throw py::type_error("posthaste.diff: expected a posthaste.Frame or a path, got " +
                                 type_name(x));
        }
        const std::string path = j.get<std::string>();
        py::gil_scoped_release release;
        return std::make_shared<const Frame>(
            metrics::read_for_comparison(path, {}, 0, ReadOptions{}));
    };
    const std::shared_ptr<const Frame> fa = frame_of(a), fb = frame_of(b);
    std::string report;
    {
        py::gil_scoped_release release;
        report = metrics::to_json(metrics::diff_frames(*fa, *fb, o));
    }
    return from_json(nlohmann::json::parse(report));
}

/// The declared default as a Python value (a header-backed parameter's stand-in).
py::object default_value(const ParamSpec &p)
{
    const ParamValue v = default_param(p);
    switch (p.type) {
        case ParamType::Int:
            return py::int_(static_cast<long long>(v.number));
        case ParamType::Real:
            return py::float_(v.number);
        case ParamType::Bool:
            return py::bool_(v.number != 0.0);
        case ParamType::Vec:
            return py::cast(v.vec);
        case ParamType::Json: {
            const nlohmann::json j = nlohmann::json::parse(v.text, nullptr, false);
            return j.is_discarded() ? py::object(py::none()) : from_json(j);
        }
        case ParamType::Records:
            return py::list();
        default:
            return py::str(v.text);
    }
}

py::list node_infos()
{
    py::object ns = py::module_::import("types").attr("SimpleNamespace");
    std::function<py::object(const ParamSpec &)> param_info = [&](const ParamSpec &p) {
        py::dict d;
        d["name"] = std::string(p.name);
        static const char *kTypes[] = {
            "int", "real", "bool", "string", "choice", "vec", "json", "records"};
        d["type"] = kTypes[int(p.type)];
        d["description"] = describe_type(p);
        d["default"] = p.required ? py::none() : default_value(p);
        d["default_text"] = describe_default(p);
        d["required"] = p.required;
        d["min"] = std::isfinite(p.min) ? py::object(py::float_(p.min)) : py::none();
        d["max"] = std::isfinite(p.max) ? py::object(py::float_(p.max)) : py::none();
        d["choices"] =
            p.type == ParamType::Choice ? py::cast(split_choices(p.choices)) : py::none();
        d["unit"] = std::string(p.unit);
        d["help"] = std::string(p.help);
        const std::string when = describe_condition(p);
        d["only_when"] = when.empty() ? py::none() : py::object(py::str(when));
        d["header"] = p.header.empty() ? py::none() : py::object(py::str(std::string(p.header)));
        py::list fields;
        for (std::size_t i = 0; i < p.field_count; ++i) {
            fields.append(param_info(p.fields[i]));
        }
        d["fields"] = fields;
        return ns(**d);
    };
    py::list out;
    for (const NodeType *t : all_node_types()) {
        const NodeSpec &s = t->spec;
        py::list inputs, params;
        for (const PortSpec &p : s.inputs) {
            py::dict d;
            d["name"] = std::string(p.name);
            d["passes"] = split_list(p.passes);
            d["optional"] = p.optional;
            d["help"] = std::string(p.help);
            inputs.append(ns(**d));
        }
        for (const ParamSpec &p : s.params) {
            params.append(param_info(p));
        }
        py::dict d;
        d["type"] = std::string(s.type);
        d["summary"] = std::string(s.summary);
        d["inputs"] = inputs;
        d["params"] = params;
        d["makes"] = split_list(s.makes);
        d["sink"] = s.sink;
        d["maskable"] = s.maskable;
        out.append(ns(**d));
    }
    return out;
}

void bind_nodes(py::module_ &m)
{
    m.def(
        "node",
        [](py::handle type, py::args frames, py::kwargs kwargs) {
            // (a null cut the type short: unknown node type "gr")
            return node(text_arg(type, "posthaste.node: type", "a node type (str)"),
                        std::move(frames),
                        std::move(kwargs));
        },
        py::arg("type"),
        py::pos_only(),
        "Run node `type` on frames in memory: frames fill its input ports in order (or by port "
        "name as keywords), other keywords are its parameters, validated as in a graph; "
        "frame= sets the frame number (default: the first input's). Returns the output Frame "
        "(None for write).");
    m.def(
        "read",
        [](py::handle path, py::object frame, py::kwargs kwargs) {
            kwargs["path"] = path;
            kwargs["frame"] = frame;
            return node("read", py::args(), kwargs);
        },
        py::arg("path"),
        py::arg("frame") = py::none(),
        "Read a frame (a file, or a #### pattern at frame `frame`; default its first frame on "
        "disk) with read's parameters.");
    m.def(
        "write",
        [](py::handle frame, py::handle path, py::kwargs kwargs) {
            kwargs["path"] = path;
            py::tuple args = py::make_tuple(frame);
            node("write", py::args(args), kwargs);
        },
        py::arg("frame"),
        py::arg("path"),
        "Write a frame (EXR, PNG, JPEG...) with write's parameters.");
    m.def("nodes",
          &node_infos,
          "Every node type with its inputs and parameters (name, type, default, min, max, "
          "choices, unit, help).");
    m.def("diff",
          &diff,
          py::arg("a"),
          py::arg("b"),
          "Compare frame (or file) b against reference a as `posthaste diff` does; keywords: "
          "fail, warn, fail_relative, warn_relative, fail_percent, warn_percent, hard_fail, "
          "hard_warn, allow_failures, passes, flip (hdr|ldr|off), pixels_per_degree. Returns the "
          "report as a dict (verdict, exit_code, per pass metrics).");
}

}  // namespace posthaste::python
