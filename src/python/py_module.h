#pragma once
// The pieces of the Python module `posthaste` (docs/PYTHON.md), one file each: Frame
// (py_frame.cpp), node/read/write/nodes/diff (py_nodes.cpp), Graph (py_graph.cpp), the type
// stubs (py_stub.cpp) and the module itself (py_module.cpp).

#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace posthaste::python {

namespace py = pybind11;
class PyFrame;

/// Run node `type` on frames (port name, frame) with JSON parameters, the GIL released while
/// it runs; `frame`: the frame number (default: the first input's, or a source's first frame).
std::shared_ptr<PyFrame> run_node(
    const std::string &type,
    const std::vector<std::pair<std::string, std::shared_ptr<PyFrame>>> &inputs,
    const nlohmann::json &params,
    std::optional<int> frame);

void bind_nodes(py::module_ &m);
void bind_graph(py::module_ &m);
/// The text of posthaste.pyi: the module's API with one overload of node() per node type.
std::string stub_text();

}  // namespace posthaste::python
