// The Python module `posthaste` (docs/PYTHON.md): frames as numpy arrays over their own memory,
// any node run on frames in memory, graphs run over frames, diffs; every error of the tool a
// posthaste.Error with the CLI's one-line message.

#include "python/py_module.h"

#include <malloc.h>
#include <pybind11/pybind11.h>

#include "core/parallel.h"
#include "core/simd.h"
#include "graph/run.h"
#include "python/py_convert.h"
#include "python/py_frame.h"

namespace py = pybind11;

PYBIND11_MODULE(posthaste, m)
{
    using namespace posthaste;
    if (const std::string bad = simd::environment_error(); !bad.empty()) {
        throw py::import_error(bad);
    }
    // Pass images are held to the same budget as in the CLI: a share of the available memory.
    apply_memory_budget("");
    // As the CLI does (src/cli/main.cpp): pass images are large and made anew by every node;
    // glibc would serve each with mmap and unmap it on free, so every call would page-fault its
    // images in again. Freed memory stays in the heap for the next call instead.
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    m.doc() = "posthaste: a node-graph compositor for multi-layer OpenEXR frames, from Python.";
    m.attr("__version__") = POSTHASTE_VERSION;
    python::register_errors(m);
    python::bind_frame(m);
    python::bind_nodes(m);
    python::bind_graph(m);
    m.def(
        "set_threads",
        [](py::handle given) {
            const int threads = python::cast_arg<int>(given, "set_threads(): threads", "an int");
            if (threads < 0 || threads > 1024) {
                // As the CLI's --threads: a pool of 100000 failed every later EXR read.
                throw py::value_error("threads: expected 0 (every core) to 1024, got " +
                                      std::to_string(threads));
            }
            set_thread_count(threads);
        },
        py::arg("threads"),
        "Worker threads for the nodes' parallel loops (0: every core), for the whole process.");
    m.def("_stub_text", &python::stub_text, "The text of posthaste.pyi.");
}
