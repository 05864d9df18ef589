// posthaste.pyi (py_module.h): the module's API for editors and type checkers, with one overload
// of node() per node type, its ports and parameters typed from their declarations and its
// docstring from their help.

#include <set>
#include <sstream>

#include "graph/node.h"
#include "nodes/registry.h"
#include "python/py_module.h"

namespace posthaste::python {
namespace {

const std::set<std::string> kKeywords = {
    "False",   "None",     "True",     "and",    "as",   "assert", "async",  "await",
    "break",   "class",    "continue", "def",    "del",  "elif",   "else",   "except",
    "finally", "for",      "from",     "global", "if",   "import", "in",     "is",
    "lambda",  "nonlocal", "not",      "or",     "pass", "raise",  "return", "try",
    "while",   "with",     "yield",    "type",   "frame"};

std::string python_type(const ParamSpec &p)
{
    switch (p.type) {
        case ParamType::Int:
            return "int";
        case ParamType::Real:
            return "float";
        case ParamType::Bool:
            return "bool";
        case ParamType::String:
            return p.file ? "str | os.PathLike[str]" : "str";
        case ParamType::Choice: {
            std::string out = "Literal[";
            bool first = true;
            for (const std::string &c : split_choices(p.choices)) {
                out += (first ? "\"" : ", \"") + c + "\"";
                first = false;
            }
            return out + "]";
        }
        case ParamType::Vec:
            return "Sequence[float]";
        case ParamType::Json:
            return "Any";
        case ParamType::Records:
            return "Sequence[Mapping[str, Any]]";
    }
    return "Any";
}

/// One line of a docstring for a parameter: name, type, default, range, unit, condition, help.
std::string param_doc(const ParamSpec &p)
{
    std::string line =
        "    " + std::string(p.name) + " (" + describe_type(p) + ", default " + describe_default(p);
    const std::string range = describe_range(p), when = describe_condition(p);
    if (!range.empty()) {
        line += ", range " + range;
    }
    if (!p.unit.empty()) {
        line += ", " + std::string(p.unit);
    }
    if (!when.empty()) {
        line += "; only when " + when;
    }
    line += "): " + std::string(p.help);
    std::string escaped;
    for (char c : line) {
        escaped += c == '\\' ? std::string("\\\\") : std::string(1, c);
    }
    return escaped + "\n";
}

void node_overload(std::ostringstream &os, const NodeType &t)
{
    const NodeSpec &s = t.spec;
    os << "@overload\ndef node(type: Literal[\"" << s.type << "\"], /";
    for (const PortSpec &p : s.inputs) {
        os << ", " << p.name << ": Frame" << (p.optional ? " | None = None" : "");
    }
    os << ", *, frame: int | None = None";
    for (const ParamSpec &p : s.params) {
        if (kKeywords.count(std::string(p.name))) {
            continue;
        }
        os << ", " << p.name << ": " << python_type(p) << (p.required ? "" : " = ...");
    }
    os << ") -> " << (s.sink ? "None" : "Frame") << ":\n    \"\"\"" << s.summary << "\n\n";
    for (const PortSpec &p : s.inputs) {
        os << "    input " << p.name << (p.optional ? " (optional)" : "") << ", reads "
           << (p.passes.empty() ? "-" : std::string(p.passes)) << (p.help.empty() ? "" : ": ")
           << p.help << "\n";
    }
    for (const ParamSpec &p : s.params) {
        os << param_doc(p);
    }
    os << "    \"\"\"\n\n";
}

const char *kHeader =
    R"(# posthaste.pyi: written by the module itself from its node catalog (posthaste._stub_text()).
"""posthaste: a node-graph compositor for multi-layer OpenEXR frames, from Python."""

import os
from typing import Any, Callable, Iterator, Literal, Mapping, Sequence, overload

import numpy as np
import numpy.typing as npt

__version__: str

class Error(Exception):
    """Every error of posthaste; str(e) is the command line's one-line message."""
    exit_code: int

class GraphError(Error):
    """The graph, a node type, an input or a call is invalid; nothing was computed (exit code 2)."""

class ParameterError(GraphError):
    """A node's parameter is unknown, of the wrong type, out of range or not applicable."""

class RunError(Error):
    """Reading, writing or evaluating failed (exit code 1)."""

Window = tuple[int, int, int, int]

class Passes:
    """The passes of a Frame: float32 arrays of shape (height, width, channels) over its memory."""
    def __getitem__(self, name: str) -> npt.NDArray[np.float32]: ...
    def __setitem__(self, name: str, array: npt.ArrayLike) -> None: ...
    def __delitem__(self, name: str) -> None: ...
    def __contains__(self, name: object) -> bool: ...
    def __iter__(self) -> Iterator[str]: ...
    def __len__(self) -> int: ...
    def keys(self) -> list[str]: ...
    def items(self) -> list[tuple[str, npt.NDArray[np.float32]]]: ...
    def values(self) -> list[npt.NDArray[np.float32]]: ...
    def get(self, name: str, default: Any = None) -> npt.NDArray[np.float32] | Any: ...

class Frame:
    """One frame: passes (numpy views of its memory), camera, header attributes, windows."""
    def __init__(self, passes: Mapping[str, npt.ArrayLike] | None = None,
                 camera: Mapping[str, Any] | None = None,
                 attributes: Mapping[str, Any] | None = None,
                 display_window: Window | None = None, data_window: Window | None = None,
                 number: int = 1, channels: Mapping[str, Sequence[str]] | None = None) -> None: ...
    @property
    def passes(self) -> Passes: ...
    def writable(self, name: str) -> npt.NDArray[np.float32]: ...
    def owns(self, name: str) -> bool: ...
    def set_pass(self, name: str, array: npt.ArrayLike, channels: Sequence[str] | None = None) -> None: ...
    def channels(self, name: str) -> list[str]: ...
    def copy(self) -> Frame: ...
    number: int
    @property
    def width(self) -> int: ...
    @property
    def height(self) -> int: ...
    display_window: Window
    data_window: Window
    camera: dict[str, Any]
    attributes: dict[str, Any]

class Graph:
    """A node graph (docs/GRAPHS.md), validated and planned."""
    @staticmethod
    def load(path: str | os.PathLike[str], set: Mapping[str, Any] | None = None) -> Graph: ...
    @staticmethod
    def from_dict(graph: Mapping[str, Any], base_dir: str = "", set: Mapping[str, Any] | None = None) -> Graph: ...
    def run(self, frames: str | int | Sequence[int] | None = None, set: Mapping[str, Any] | None = None,
            jobs: int = 0, threads: int = 0, progress: Callable[[int, int, int], Any] | None = None,
            skip_existing: bool = False, keep_going: bool = False, skip_bad_frames: bool = False,
            max_memory: str = "") -> dict[str, Any]: ...
    def evaluate(self, frame: int, outputs: str | Sequence[str] | None = None) -> dict[str, Frame]: ...
    @property
    def frames(self) -> list[int]: ...
    @property
    def nodes(self) -> list[tuple[str, str]]: ...
    def outputs(self, frame: int) -> list[str]: ...

def read(path: str | os.PathLike[str], frame: int | None = None, **params: Any) -> Frame: ...
def write(frame: Frame, path: str | os.PathLike[str], **params: Any) -> None: ...
def nodes() -> list[Any]: ...
def diff(a: Frame | str | os.PathLike[str], b: Frame | str | os.PathLike[str], **options: Any) -> dict[str, Any]: ...
def set_threads(threads: int) -> None: ...

)";

}  // namespace

std::string stub_text()
{
    std::ostringstream os;
    os << kHeader;
    for (const NodeType *t : all_node_types()) {
        node_overload(os, *t);
    }
    os << "def node(type: str, /, *frames: Frame | None, frame: int | None = None, **params: Any) "
          "-> Frame | None: ...\n";
    return os.str();
}

}  // namespace posthaste::python
