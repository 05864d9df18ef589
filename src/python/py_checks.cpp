// Checks of the values Python hands the module (py_checks.h).

#include "python/py_checks.h"

#include <cmath>
#include <limits>

namespace posthaste::python {
namespace {

std::string type_of(py::handle v)
{
    return py::str(v.get_type().attr("__name__")).cast<std::string>();
}

}  // namespace

std::string repr_text(py::handle v)
{
    // repr() escapes what is not printable (a lone surrogate, a null): its UTF-8 always exists.
    // A long one is cut in its middle (2**1100 has 332 digits).
    std::string s = py::repr(v).cast<std::string>();
    if (s.size() > 80) {
        // At characters' starts: half a UTF-8 character made the message itself fail.
        const auto start = [&](std::size_t i) {
            while (i > 0 && (static_cast<unsigned char>(s[i]) & 0xC0) == 0x80) {
                --i;
            }
            return i;
        };
        s = s.substr(0, start(40)) + "..." + s.substr(start(s.size() - 20)) + " (" +
            std::to_string(s.size()) + " bytes)";
    }
    return s;
}

std::string checked_text(py::handle text, const std::string &who)
{
    Py_ssize_t size = 0;
    const char *utf8 = PyUnicode_AsUTF8AndSize(text.ptr(), &size);
    if (utf8 == nullptr) {
        PyErr_Clear();  // a lone surrogate: os.fsdecode of a name that is not UTF-8
        throw py::value_error(who + ": not valid UTF-8 text (a file name's bytes?)");
    }
    std::string s(utf8, std::size_t(size));
    if (s.find('\0') != std::string::npos) {
        // As open() does: the engine would see the text up to the null, another name.
        throw py::value_error(who + ": embedded null character");
    }
    return s;
}

std::string text_arg(py::handle v, const std::string &who, const char *expected)
{
    if (!py::isinstance<py::str>(v)) {
        throw py::type_error(who + ": expected " + expected + ", got " + type_of(v) + " " +
                             repr_text(v));
    }
    return checked_text(v, who);
}

std::string key_text(py::handle key, const std::string &what)
{
    if (!py::isinstance<py::str>(key)) {
        return checked_text(py::str(key), what + " " + repr_text(key));
    }
    return checked_text(key, what + " " + repr_text(key));
}

py::dict dict_arg(py::handle v, const std::string &who, const char *expected)
{
    if (py::isinstance<py::dict>(v)) {
        return py::reinterpret_borrow<py::dict>(v);
    }
    if (!py::isinstance<py::str>(v) && py::hasattr(v, "keys")) {
        return py::dict(py::reinterpret_borrow<py::object>(v));
    }
    throw py::type_error(who + ": expected " + expected + ", got " + type_of(v) + " " +
                         repr_text(v));
}

int int_attribute(py::handle value, const std::string &name)
{
    // EXR's int attributes are 32 bits: a larger one would wrap (and one beyond 64 bits was
    // pybind11's "Unable to cast Python instance to C++ type").
    long long v = 0;
    try {
        v = value.cast<long long>();
    } catch (const py::cast_error &) {
        v = std::numeric_limits<long long>::max();
    }
    if (v < std::numeric_limits<int>::min() || v > std::numeric_limits<int>::max()) {
        throw py::value_error("attribute \"" + name + "\": " + repr_text(value) +
                              " does not fit an EXR int attribute (32 bits); give a float");
    }
    return int(v);
}

float float_attribute(py::handle value, const std::string &name)
{
    // A finite double that float cannot hold is an error (1e40 became infinity), and so is an
    // int beyond a double's range.
    double d = std::numeric_limits<double>::infinity();
    bool converted = true;
    try {
        d = value.cast<double>();
    } catch (const py::cast_error &) {
        converted = false;
    }
    if (!converted || (std::isfinite(d) && !std::isfinite(float(d)))) {
        throw py::value_error("attribute \"" + name + "\": " + repr_text(value) +
                              " does not fit an EXR float attribute (32 bits)");
    }
    return float(d);
}

std::string string_attribute(py::handle value, const std::string &name)
{
    return checked_text(value, "attribute \"" + name + "\"");
}

float camera_number(py::handle value, const std::string &key)
{
    const std::string who = "camera \"" + key + "\"";
    const py::object np = py::module_::import("numpy");
    // (np.number took complex128(1+2j) as 1.0, with only a ComplexWarning)
    if (!py::isinstance<py::float_>(value) && !py::isinstance<py::int_>(value) &&
        !py::isinstance(value, np.attr("integer")) && !py::isinstance(value, np.attr("floating"))) {
        throw py::type_error(who + ": expected a number, got " + repr_text(value));
    }
    double x = std::numeric_limits<double>::infinity();
    bool converted = true;
    try {
        x = value.cast<double>();
    } catch (const py::cast_error &) {
        converted = false;  // an int beyond a double's range
    }
    if (converted && !std::isfinite(x)) {
        throw py::value_error(who + ": not finite");
    }
    if (!converted || !std::isfinite(float(x))) {
        throw py::value_error(who + ": " + repr_text(value) + " does not fit a float (32 bits)");
    }
    return float(x);
}

void check_real_matrix(py::handle value, const std::string &key)
{
    py::object a;
    try {
        a = py::module_::import("numpy").attr("asarray")(value);
    } catch (const py::error_already_set &) {
        return;  // not an array (a ragged list): the shape check says so
    }
    const char kind = py::str(a.attr("dtype").attr("kind")).cast<std::string>().at(0);
    if (kind != 'f' && kind != 'i' && kind != 'u') {
        throw py::type_error("camera \"" + key + "\": expected a 4x4 matrix of real numbers, got " +
                             py::str(a.attr("dtype")).cast<std::string>() + " values");
    }
}

std::vector<std::string> channel_names_arg(py::handle channels, const std::string &who)
{
    const auto wrong = [&] {
        return py::type_error(
            who + ": channels: expected a list of names, got " +
            (py::isinstance<py::str>(channels) ? std::string("a str") : repr_text(channels)));
    };
    if (py::isinstance<py::str>(channels) || py::isinstance<py::bytes>(channels) ||
        !py::isinstance<py::sequence>(channels)) {
        throw wrong();
    }
    std::vector<std::string> names;
    for (py::handle item : channels.cast<py::sequence>()) {
        if (!py::isinstance<py::str>(item)) {
            throw wrong();
        }
        names.push_back(checked_text(item, who + ": channel name " + repr_text(item)));
    }
    return names;
}

}  // namespace posthaste::python
