#pragma once
// Checks of the values Python hands the module, each failure a one-line TypeError or ValueError
// naming the item: text with no null character (the engine would see it cut there) and no lone
// surrogate (it has no UTF-8 form), numbers that fit the engine's and OpenEXR's types, pass and
// channel names, dict arguments.

#include <pybind11/pybind11.h>

#include <string>
#include <vector>

namespace posthaste::python {

namespace py = pybind11;

/// repr(v) as UTF-8 (a lone surrogate or a null comes escaped: '\ud800', 'a\x00b').
std::string repr_text(py::handle v);

/// The str `text` as UTF-8; a ValueError "<who>: not valid UTF-8 text (a file name's bytes?)"
/// for a lone surrogate, "<who>: embedded null character" for a null character.
std::string checked_text(py::handle text, const std::string &who);

/// `v` as text: a str checked as checked_text does, else a TypeError "<who>: expected
/// <expected>, got <type> <repr>".
std::string text_arg(py::handle v, const std::string &who, const char *expected = "a str");

/// A name given as a dict key or keyword (an attribute, a camera value, a node parameter, a
/// --set item): a str checked as checked_text does, with `what` and the key's repr leading
/// the message; anything else as its str().
std::string key_text(py::handle key, const std::string &what);

/// `v` as a dict: a dict, or a mapping (it has keys()) copied into one; else a TypeError
/// "<who>: expected <expected>, got <type> <repr>" (dict("a=1") said "dictionary update
/// sequence element #0 has length 1; 2 is required").
py::dict dict_arg(py::handle v, const std::string &who, const char *expected);

/// Attribute values: an int that fits 32 bits, a float that fits float32, a string without a
/// null (ValueError naming the attribute `name`).
int int_attribute(py::handle value, const std::string &name);
float float_attribute(py::handle value, const std::string &name);
std::string string_attribute(py::handle value, const std::string &name);

/// A camera value `key` (focalLength, ...): a real number (not a bool's, a complex's or a
/// string's) that float32 holds, finite.
float camera_number(py::handle value, const std::string &key);

/// A 4x4 matrix's values must be real numbers: a TypeError naming `key` for complex numbers
/// (numpy kept the real part, with only a ComplexWarning), strings (parsed as numbers) or
/// objects. Anything numpy cannot make an array of is left to the shape check.
void check_real_matrix(py::handle value, const std::string &key);

/// A pass's channel names: a list of str, each checked (`who` names the pass).
std::vector<std::string> channel_names_arg(py::handle channels, const std::string &who);

}  // namespace posthaste::python
