#pragma once
// Conversions between Python objects and the engine's values for the Python module: JSON
// parameters, header attributes, cameras and windows, and the module's exceptions.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>
#include <string>

#include "core/camera.h"
#include "core/error.h"
#include "core/frame.h"
#include "python/py_checks.h"

namespace posthaste::python {

namespace py = pybind11;

/// The name of v's type ("int", "str").
inline std::string type_name(py::handle v)
{
    return py::str(v.get_type().attr("__name__")).cast<std::string>();
}

/// v as a T, or a TypeError naming the argument and what it takes, on one line (pybind11 said
/// "Unable to cast Python instance to C++ type", or listed the signatures over several lines).
template <typename T>
T cast_arg(py::handle v, const std::string &who, const char *expected)
{
    try {
        return v.cast<T>();
    } catch (const py::cast_error &) {
        throw py::type_error(who + ": expected " + expected + ", got " + type_name(v) + " " +
                             py::repr(v).cast<std::string>());
    }
}

/// A pass name: a str, else a TypeError naming `who`; a ValueError naming the name for a null
/// character (the pass "a\0b" was read back as "a") or a lone surrogate.
inline std::string pass_name_arg(py::handle v, const std::string &who)
{
    if (!py::isinstance<py::str>(v)) {
        throw py::type_error(who + ": pass names are str, got " + type_name(v) + " " +
                             py::repr(v).cast<std::string>());
    }
    return checked_text(v, who + ": pass name " + repr_text(v));
}

/// A Python value (None, bool, int, float, str, list/tuple, dict with str keys, numpy scalars
/// and arrays) as JSON; `where` leads the TypeError for anything else.
nlohmann::json to_json(py::handle value, const std::string &where);
/// JSON as plain Python values.
py::object from_json(const nlohmann::json &value);

/// Header attributes as a dict: numbers and strings as Python values, arrays as lists,
/// matrices as 4x4 float32 arrays.
py::dict attributes_to_dict(const OIIO::ParamValueList &attributes);
/// A dict of attributes (the forms attributes_to_dict makes) into `out`; TypeError naming the
/// attribute for a value with no EXR type.
/// `dict` as header attributes into `out`. With `was` (the frame's attributes before), a value
/// given for an attribute `was` holds takes that attribute's type where it fits (the same
/// count of numbers or strings): Python has one float and one int, and a double, a time code,
/// a box or a one-string vector came back as a float, ints or a string.
void dict_to_attributes(py::handle dict,
                        OIIO::ParamValueList &out,
                        const OIIO::ParamValueList *was = nullptr);

/// The camera as a dict keyed by the EXR header's attribute names ("worldToCamera",
/// "aperture", ...) plus "origin"; matrices are 4x4 float32 arrays in OpenEXR's row-vector
/// convention (p @ M). Values the camera lacks are left out.
py::dict camera_to_dict(const Camera &camera);
Camera dict_to_camera(py::handle dict);

/// A window (x0, y0, x1, y1), exclusive maximum, as a tuple, and back (ValueError naming `what`).
py::tuple rect_to_tuple(const Rect &r);
Rect tuple_to_rect(py::handle value, const char *what);

/// Create the exception classes on module `m` (posthaste.Error and its GraphError,
/// ParameterError and RunError, each carrying `exit_code`) and translate engine Errors into
/// them with the CLI's one-line message.
void register_errors(py::module_ &m);

}  // namespace posthaste::python
