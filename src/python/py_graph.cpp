// posthaste.Graph (py_module.h): a graph file or dict, run over frames or evaluated to frames in
// memory. A run goes on in a thread of its own while the calling thread waits without the GIL,
// calls the progress callable and checks for Ctrl-C between frames.

#include <pybind11/stl.h>

#include <chrono>
#include <condition_variable>
#include <limits>
#include <thread>

#include "graph/graph.h"
#include "graph/run.h"
#include "nodes/registry.h"
#include "python/py_convert.h"
#include "python/py_frame.h"
#include "python/py_module.h"

namespace posthaste::python {
namespace {

class PyGraph {
   public:
    static PyGraph load(const std::string &path, std::vector<std::string> overrides)
    {
        PyGraph g;
        g.path_ = path;
        g.overrides_ = std::move(overrides);
        g.graph_ = std::make_shared<Graph>(Graph::load(path, nodes::catalog(), g.overrides_));
        return g;
    }
    static PyGraph from_text(std::string text,
                             std::string base_dir,
                             std::vector<std::string> overrides)
    {
        PyGraph g;
        g.text_ = std::move(text);
        g.base_dir_ = std::move(base_dir);
        g.overrides_ = std::move(overrides);
        g.graph_ = std::make_shared<Graph>(Graph::parse(
            g.text_, "posthaste.Graph.from_dict", nodes::catalog(), g.overrides_, g.base_dir_));
        return g;
    }
    /// The graph with more overrides (parsed again), or this one's.
    std::shared_ptr<Graph> with(const std::vector<std::string> &more) const
    {
        if (more.empty()) {
            return graph_;
        }
        std::vector<std::string> all = overrides_;
        all.insert(all.end(), more.begin(), more.end());
        return std::make_shared<Graph>(
            path_.empty()
                ? Graph::parse(text_, "posthaste.Graph.from_dict", nodes::catalog(), all, base_dir_)
                : Graph::load(path_, nodes::catalog(), all));
    }
    const Graph &graph() const { return *graph_; }

   private:
    std::string path_, text_, base_dir_;
    std::vector<std::string> overrides_;
    std::shared_ptr<Graph> graph_;
};

/// {"node.param": value} as --set strings (a string value as it is, anything else as JSON).
std::vector<std::string> overrides_of(py::handle set)
{
    std::vector<std::string> out;
    if (set.is_none()) {
        return out;
    }
    // (a str or a list went to dict(), whose message did not name set=)
    for (auto [key, value] : dict_arg(set, "set", "a dict {\"node.param\": value}")) {
        const std::string k = key_text(key, "set: key");
        // A null cut "20\0garbage" to 20.
        out.push_back(k + "=" +
                      (py::isinstance<py::str>(value) ? checked_text(value, "set " + k)
                                                      : to_json(value, "set " + k).dump()));
    }
    return out;
}

std::string frames_of(py::handle frames)
{
    if (frames.is_none()) {
        return "";
    }
    if (py::isinstance<py::str>(frames)) {
        return checked_text(frames, "Graph.run: frames");
    }
    const auto frame_number = [](py::handle f) {
        // (a float, a string in a list or a number beyond 32 bits: pybind11's "Unable to cast")
        if (!py::isinstance<py::int_>(f) || py::isinstance<py::bool_>(f)) {
            throw py::type_error("Graph.run: frames: expected frame numbers (ints), got " +
                                 py::repr(f).cast<std::string>());
        }
        const long long n = f.cast<long long>();
        if (n < std::numeric_limits<int>::min() || n > std::numeric_limits<int>::max()) {
            throw py::value_error("Graph.run: frames: " + std::to_string(n) +
                                  " does not fit 32 bits");
        }
        return int(n);
    };
    if (py::isinstance<py::int_>(frames)) {
        return std::to_string(frame_number(frames));
    }
    if (!py::isinstance<py::sequence>(frames) || PyBytes_Check(frames.ptr()) ||
        PyByteArray_Check(frames.ptr()) || PyMemoryView_Check(frames.ptr())) {
        // (bytes are a sequence of ints: b"\x01\x02" ran frames 1 and 2)
        frame_number(frames);  // the type error
    }
    std::string out;
    for (py::handle f : frames.cast<py::sequence>()) {
        if (!out.empty()) {
            out += ',';  // (appended: "..." + string is GCC 12's -Wrestrict false positive)
        }
        out += std::to_string(frame_number(f));
    }
    if (out.empty()) {
        throw_usage("Graph.run: frames: an empty list");
    }
    return out;
}

struct RunEvents {
    std::mutex mutex;
    std::condition_variable changed;
    std::vector<std::pair<int, std::string>> frames;  ///< Finished frames not yet reported.
    bool finished = false;
    std::atomic<bool> stop{false};
};

py::dict run(const PyGraph &pg,
             py::handle frames,
             py::handle set,
             py::handle jobs_arg,
             py::handle threads_arg,
             py::object progress,
             py::handle skip_existing,
             py::handle keep_going,
             py::handle skip_bad_frames,
             py::handle max_memory)
{
    // Each argument's type checked here, so a wrong one is named on one line (pybind11 listed
    // the signature over several lines and named none).
    const int jobs = cast_arg<int>(jobs_arg, "Graph.run: jobs", "an int (32 bits)");
    const int threads = cast_arg<int>(threads_arg, "Graph.run: threads", "an int (32 bits)");
    RunSettings rs;
    rs.skip_existing = cast_arg<bool>(skip_existing, "Graph.run: skip_existing", "a bool");
    rs.keep_going = cast_arg<bool>(keep_going, "Graph.run: keep_going", "a bool");
    rs.skip_bad_frames = cast_arg<bool>(skip_bad_frames, "Graph.run: skip_bad_frames", "a bool");
    rs.max_memory = text_arg(max_memory, "Graph.run: max_memory");
    if (threads < 0 || threads > 1024) {
        throw py::value_error("threads: expected 0 (every core) to 1024, got " +
                              std::to_string(threads));
    }
    if (jobs < -1 || jobs > 256) {
        throw py::value_error("jobs: expected 0 (the default), 1 to 256 or -1 (auto), got " +
                              std::to_string(jobs));
    }
    const std::shared_ptr<Graph> graph = pg.with(overrides_of(set));
    rs.frames = frames_of(frames);
    rs.jobs = jobs;
    rs.threads = threads;
    rs.quiet = true;
    const std::size_t total = rs.frames.empty() ? graph->default_frames().size()
                                                : parse_frame_list(rs.frames, "frames").size();
    auto events = std::make_shared<RunEvents>();
    rs.on_frame = [events](int frame, double, double, const std::string &error) {
        std::lock_guard lock(events->mutex);
        events->frames.emplace_back(frame, error);
        events->changed.notify_all();
    };
    rs.should_stop = [events] { return events->stop.load(); };
    std::map<std::string, double> node_seconds;
    std::vector<int> written;
    rs.node_seconds = &node_seconds;
    rs.frames_written = &written;

    std::exception_ptr failure;
    const auto start = std::chrono::steady_clock::now();
    std::thread worker([&] {
        try {
            run_graph(*graph, rs);
        } catch (...) {
            failure = std::current_exception();
        }
        std::lock_guard lock(events->mutex);
        events->finished = true;
        events->changed.notify_all();
    });
    std::optional<py::error_already_set> pending;  // Ctrl-C, or the progress callable's error
    std::size_t done = 0;
    for (bool finished = false; !finished;) {
        std::vector<std::pair<int, std::string>> batch;
        {
            py::gil_scoped_release release;
            std::unique_lock lock(events->mutex);
            events->changed.wait_for(lock, std::chrono::milliseconds(50), [&] {
                return events->finished || !events->frames.empty();
            });
            batch.swap(events->frames);
            finished = events->finished;
        }
        for (const auto &[frame, error] : batch) {
            ++done;
            if (!progress.is_none() && !pending) {
                try {
                    progress(frame, done, total);
                } catch (py::error_already_set &e) {
                    pending = std::move(e);
                    events->stop = true;
                }
            }
        }
        if (!pending && PyErr_CheckSignals() != 0) {
            pending = py::error_already_set();
            events->stop = true;
        }
    }
    worker.join();
    if (pending) {
        throw std::move(*pending);
    }
    if (failure) {
        std::rethrow_exception(failure);
    }
    py::dict out;
    out["frames"] = written;
    out["seconds"] =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    out["node_seconds"] = node_seconds;
    return out;
}

py::dict evaluate(const PyGraph &pg, py::handle frame_arg, py::handle outputs)
{
    const int frame = cast_arg<int>(frame_arg, "Graph.evaluate: frame", "an int (32 bits)");
    const Graph &g = pg.graph();
    std::vector<int> targets;
    if (outputs.is_none()) {
        for (std::size_t i = 0; i < g.nodes().size(); ++i) {
            if (g.nodes()[i].type->spec.sink) {
                targets.push_back(int(i));
            }
        }
    } else {
        // A single id is one output; a string is a sequence too, of one-letter ids.
        // Each id checked: a null cut it short, a lone surrogate was pybind11's "Unable to cast".
        const std::string who = "Graph.evaluate: outputs";
        std::vector<std::string> ids;
        if (py::isinstance<py::str>(outputs)) {
            ids.push_back(checked_text(outputs, who));
        } else if (py::isinstance<py::sequence>(outputs) && !PyBytes_Check(outputs.ptr())) {
            for (py::handle id : outputs.cast<py::sequence>()) {
                ids.push_back(text_arg(id, who, "node ids"));
            }
        } else {
            throw py::type_error(who + ": expected node ids, got " + repr_text(outputs));
        }
        for (const std::string &id : ids) {
            const int i = g.find(id);
            if (i < 0) {
                throw_usage(g.origin(), ": no node \"", id, "\"");
            }
            targets.push_back(i);
        }
    }
    std::vector<std::shared_ptr<const Frame>> frames;
    {
        py::gil_scoped_release release;
        g.check({frame});
        frames = g.evaluate_outputs(frame, targets);
    }
    py::dict out;
    for (std::size_t i = 0; i < targets.size(); ++i) {
        out[py::str(g.nodes()[std::size_t(targets[i])].identity.id)] =
            std::make_shared<PyFrame>(*frames[i]);
    }
    return out;
}

}  // namespace

void bind_graph(py::module_ &m)
{
    py::class_<PyGraph>(m, "Graph", "A node graph (docs/GRAPHS.md), validated and planned.")
        .def_static(
            "load",
            [](py::handle path, py::handle set) {
                const nlohmann::json p = to_json(path, "Graph.load");
                if (!p.is_string()) {
                    throw py::type_error("Graph.load: path: expected a str or os.PathLike, got " +
                                         py::repr(path).cast<std::string>());
                }
                return PyGraph::load(p.get<std::string>(), overrides_of(set));
            },
            py::arg("path"),
            py::arg("set") = py::none(),
            "Load a graph file; set={\"node.param\": value} overrides parameters as --set does.")
        .def_static(
            "from_dict",
            [](py::handle d, py::handle base_dir, py::handle set) {
                return PyGraph::from_text(to_json(d, "Graph.from_dict").dump(),
                                          text_arg(base_dir, "Graph.from_dict: base_dir"),
                                          overrides_of(set));
            },
            py::arg("graph"),
            py::arg("base_dir") = "",
            py::arg("set") = py::none(),
            "A graph from a dict of the graph file's form; relative paths resolve against "
            "base_dir.")
        .def("run",
             &run,
             py::arg("frames") = py::none(),
             py::arg("set") = py::none(),
             py::arg("jobs") = 0,
             py::arg("threads") = 0,
             py::arg("progress") = py::none(),
             py::arg("skip_existing") = false,
             py::arg("keep_going") = false,
             py::arg("skip_bad_frames") = false,
             py::arg("max_memory") = "",
             "Run over frames (\"1-48\", a list, or the graph's own) as `posthaste run` does, "
             "writing its outputs. progress(frame, done, total) is called on this thread after "
             "each frame; Ctrl-C stops between frames (KeyboardInterrupt). Returns {frames, "
             "seconds, node_seconds}.")
        .def("evaluate",
             &evaluate,
             py::arg("frame"),
             py::arg("outputs") = py::none(),
             "Evaluate one frame without writing: {id: Frame} for the write nodes (the frame each "
             "would write), or for the node ids in `outputs`.")
        .def_property_readonly("frames",
                               [](const PyGraph &g) { return g.graph().default_frames(); })
        .def_property_readonly("nodes",
                               [](const PyGraph &g) {
                                   py::list out;
                                   for (const GraphNode &n : g.graph().nodes()) {
                                       out.append(py::make_tuple(n.identity.id, n.identity.type));
                                   }
                                   return out;
                               })
        .def(
            "outputs",
            [](const PyGraph &g, py::handle frame) {
                return g.graph().outputs(
                    cast_arg<int>(frame, "Graph.outputs: frame", "an int (32 bits)"));
            },
            py::arg("frame"),
            "The files the graph writes for a frame.");
}

}  // namespace posthaste::python
