// Conversions between Python objects and the engine's values (py_convert.h).

#include "python/py_convert.h"

#include <OpenImageIO/typedesc.h>
#include <pybind11/stl.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <vector>

#include "core/json_error.h"
#include "core/text.h"
#include "io/io_detail.h"
#include "python/py_checks.h"

namespace posthaste::python {
namespace {

py::array_t<float> matrix_to_array(const glm::mat4 &m)
{
    // glm's column-major memory is Imath's row-major M44f: row i of the array is Imath's x[i].
    py::array_t<float> a({4, 4});
    std::memcpy(a.mutable_data(), glm::value_ptr(m), 16 * sizeof(float));
    return a;
}

glm::mat4 array_to_matrix(py::handle value, const std::string &key)
{
    check_real_matrix(value, key);
    py::array_t<float, py::array::c_style | py::array::forcecast> a;
    try {
        a = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(value);
    } catch (const py::error_already_set &) {
        a = {};
    }
    if (!a || a.ndim() != 2 || a.shape(0) != 4 || a.shape(1) != 4) {
        throw py::value_error("camera \"" + key + "\": expected a 4x4 matrix");
    }
    glm::mat4 m;
    std::memcpy(glm::value_ptr(m), a.data(), 16 * sizeof(float));
    for (int i = 0; i < 16; ++i) {
        if (!std::isfinite(glm::value_ptr(m)[i])) {
            throw py::value_error("camera \"" + key + "\": the matrix holds a non-finite value");
        }
    }
    return m;
}

struct MatrixMember {
    const char *name;
    std::optional<glm::mat4> Camera::*member;
};
constexpr MatrixMember kMatrices[] = {
    {attr::kWorldToCamera, &Camera::world_to_camera},
    {attr::kWorldToNDC, &Camera::world_to_ndc},
    {attr::kPrevWorldToCamera, &Camera::prev_world_to_camera},
    {attr::kPrevWorldToNDC, &Camera::prev_world_to_ndc},
};

}  // namespace

nlohmann::json to_json(py::handle v, const std::string &where)
{
    // A bound as the graph file's (a list nested 100000 deep overflowed the stack).
    thread_local int depth = 0;
    const struct Level {
        Level() { ++depth; }
        ~Level() { --depth; }
    } level;
    if (depth > kMaxJsonDepth) {
        throw py::value_error(str_cat(where, ": nests more than ", kMaxJsonDepth, " levels deep"));
    }
    if (v.is_none()) {
        return nullptr;
    }
    if (py::isinstance<py::bool_>(v) ||
        py::isinstance(v, py::module_::import("numpy").attr("bool_"))) {
        return v.cast<bool>();
    }
    if (py::isinstance<py::int_>(v) ||
        py::isinstance(v, py::module_::import("numpy").attr("integer"))) {
        try {
            return v.cast<long long>();
        } catch (const py::cast_error &) {
            throw py::value_error(where + ": " + py::repr(v).cast<std::string>() +
                                  " does not fit 64 bits");
        }
    }
    if (py::isinstance<py::float_>(v) ||
        py::isinstance(v, py::module_::import("numpy").attr("floating"))) {
        const double d = v.cast<double>();
        if (!std::isfinite(d)) {
            // JSON has no NaN or infinity: it became null, and the error said "got null".
            throw py::value_error(where + ": expected a finite number, got " +
                                  py::repr(v).cast<std::string>());
        }
        return d;
    }
    if (py::isinstance<py::str>(v) || py::hasattr(v, "__fspath__")) {
        // A path whose __fspath__ gives bytes was the text "b'/...'": decoded as open() does.
        return checked_text(py::isinstance<py::str>(v)
                                ? py::reinterpret_borrow<py::object>(v)
                                : py::module_::import("os").attr("fsdecode")(v),
                            where);
    }
    if (py::isinstance<py::dict>(v)) {
        nlohmann::json out = nlohmann::json::object();
        for (auto [key, value] : v.cast<py::dict>()) {
            if (!py::isinstance<py::str>(key)) {
                throw py::type_error(where + ": dict keys must be strings, got " +
                                     std::string(py::str(key.get_type().attr("__name__"))));
            }
            const std::string k = checked_text(key, where + ": key " + repr_text(key));
            out[k] = to_json(value, where + "/" + k);
        }
        return out;
    }
    if (py::isinstance<py::array>(v)) {
        return to_json(v.attr("tolist")(), where);
    }
    if (py::isinstance<py::list>(v) || py::isinstance<py::tuple>(v)) {
        nlohmann::json out = nlohmann::json::array();
        std::size_t i = 0;
        for (py::handle item : v) {
            out.push_back(to_json(item, where + "/" + std::to_string(i++)));
        }
        return out;
    }
    throw py::type_error(where + ": a " + std::string(py::str(v.get_type().attr("__name__"))) +
                         " has no JSON form (give numbers, strings, lists or dicts)");
}

py::object from_json(const nlohmann::json &v)
{
    switch (v.type()) {
        case nlohmann::json::value_t::null:
            return py::none();
        case nlohmann::json::value_t::boolean:
            return py::bool_(v.get<bool>());
        case nlohmann::json::value_t::number_integer:
        case nlohmann::json::value_t::number_unsigned:
            return py::int_(v.get<long long>());
        case nlohmann::json::value_t::number_float:
            return py::float_(v.get<double>());
        case nlohmann::json::value_t::string:
            return py::str(v.get<std::string>());
        case nlohmann::json::value_t::array: {
            py::list out;
            for (const nlohmann::json &item : v) {
                out.append(from_json(item));
            }
            return out;
        }
        case nlohmann::json::value_t::object: {
            py::dict out;
            for (const auto &[key, item] : v.items()) {
                out[py::str(key)] = from_json(item);
            }
            return out;
        }
        default:
            return py::none();
    }
}

py::dict attributes_to_dict(const OIIO::ParamValueList &attributes)
{
    py::dict out;
    for (const OIIO::ParamValue &p : attributes) {
        const OIIO::TypeDesc t = p.type();
        const int n = p.nvalues() * int(t.aggregate) * std::max(1, t.arraylen);
        py::object value;
        if (t == OIIO::TypeMatrix44) {
            glm::mat4 m;
            std::memcpy(glm::value_ptr(m), p.data(), sizeof(m));
            value = matrix_to_array(m);
        } else if (t.basetype == OIIO::TypeDesc::STRING) {
            py::list items;
            for (int i = 0; i < n; ++i) {
                items.append(py::str(static_cast<const OIIO::ustring *>(p.data())[i].string()));
            }
            value = n == 1 ? py::object(items[0]) : py::object(items);
        } else if (t.basetype == OIIO::TypeDesc::UNKNOWN || t.basetype == OIIO::TypeDesc::PTR) {
            continue;  // opaque data has no Python form here
        } else {
            // Each value converted from its own base type (TypeDesc's conversion, as OIIO does).
            py::list items;
            const bool real = t.basetype == OIIO::TypeDesc::FLOAT ||
                              t.basetype == OIIO::TypeDesc::DOUBLE ||
                              t.basetype == OIIO::TypeDesc::HALF;
            const OIIO::TypeDesc element(OIIO::TypeDesc::BASETYPE(t.basetype));
            const auto *bytes = static_cast<const unsigned char *>(p.data());
            for (int i = 0; i < n; ++i) {
                const void *src = bytes + std::size_t(i) * element.size();
                if (t.basetype == OIIO::TypeDesc::DOUBLE) {
                    items.append(py::float_(static_cast<const double *>(src)[0]));
                } else if (real) {
                    float x = 0.0f;
                    OIIO::convert_type(element, src, OIIO::TypeFloat, &x);
                    items.append(py::float_(x));
                } else {
                    int x = 0;
                    OIIO::convert_type(element, src, OIIO::TypeInt, &x);
                    items.append(py::int_(x));
                }
            }
            value = n == 1 ? py::object(items[0]) : py::object(items);
        }
        out[py::str(p.name().string())] = value;
    }
    return out;
}

namespace {

/// `value` (a number, a string, or a list of them) in the type of `old`, when it has as many
/// values of a kind that type holds exactly: false otherwise.
bool in_type_of(const OIIO::ParamValue &old,
                const std::string &name,
                py::handle value,
                OIIO::ParamValueList &out)
{
    const OIIO::TypeDesc t = old.type();
    const auto base = OIIO::TypeDesc::BASETYPE(t.basetype);
    const std::size_t count = t.basevalues() * std::size_t(std::max(old.nvalues(), 1));
    std::vector<py::handle> items;
    if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
        for (py::handle item : value.cast<py::sequence>()) {
            items.push_back(item);
        }
    } else if (py::isinstance<py::str>(value) || py::isinstance<py::int_>(value) ||
               py::isinstance<py::float_>(value)) {
        items.push_back(value);
    } else {
        return false;
    }
    if (items.size() != count || count == 0) {
        return false;
    }
    const int n = std::max(old.nvalues(), 1);
    if (base == OIIO::TypeDesc::STRING) {
        std::vector<OIIO::ustring> v;
        for (py::handle item : items) {
            if (!py::isinstance<py::str>(item)) {
                return false;
            }
            v.emplace_back(string_attribute(item, name));
        }
        out.push_back(OIIO::ParamValue(name, t, n, v.data()));
        return true;
    }
    const bool whole = base == OIIO::TypeDesc::INT || base == OIIO::TypeDesc::UINT;
    if (!whole && base != OIIO::TypeDesc::FLOAT && base != OIIO::TypeDesc::DOUBLE) {
        return false;
    }
    std::vector<unsigned char> bytes(t.size() * std::size_t(n));
    for (std::size_t i = 0; i < items.size(); ++i) {
        py::handle item = items[i];
        if (py::isinstance<py::bool_>(item) ||
            !(py::isinstance<py::int_>(item) || py::isinstance<py::float_>(item))) {
            return false;
        }
        if (whole) {
            if (!py::isinstance<py::int_>(item)) {
                return false;
            }
            long long v = 0;
            try {
                v = item.cast<long long>();
            } catch (const py::cast_error &) {
                return false;  // beyond 64 bits: refused as a new int is
            }
            const bool fits =
                base == OIIO::TypeDesc::INT
                    ? v >= std::numeric_limits<int>::min() && v <= std::numeric_limits<int>::max()
                    : v >= 0 && v <= std::numeric_limits<unsigned>::max();
            if (!fits) {
                return false;
            }
            const std::int32_t i32 = std::int32_t(std::uint32_t(v));
            std::memcpy(bytes.data() + i * 4, &i32, 4);
        } else if (base == OIIO::TypeDesc::DOUBLE) {
            double d = 0.0;
            try {
                d = item.cast<double>();
            } catch (const py::cast_error &) {
                return false;  // an int beyond a double's range: refused as a new value is
            }
            std::memcpy(bytes.data() + i * 8, &d, 8);
        } else {
            const float f = float_attribute(item, name);
            std::memcpy(bytes.data() + i * 4, &f, 4);
        }
    }
    out.push_back(OIIO::ParamValue(name, t, n, bytes.data()));
    return true;
}

}  // namespace

void dict_to_attributes(py::handle dict, OIIO::ParamValueList &out, const OIIO::ParamValueList *was)
{
    if (dict.is_none()) {
        return;
    }
    if (!py::isinstance<py::dict>(dict)) {
        throw py::type_error("attributes: expected a dict");
    }
    const py::object np = py::module_::import("numpy");
    for (auto [key, v] : dict.cast<py::dict>()) {
        const std::string name = key_text(key, "attribute");
        // numpy's scalars as Python's (np.float32(2) is a float).
        py::object value = py::reinterpret_borrow<py::object>(v);
        if (py::isinstance(value, np.attr("bool_"))) {
            value = py::bool_(value.cast<bool>());
        } else if (py::isinstance(value, np.attr("integer"))) {
            value = py::int_(value.cast<long long>());
        } else if (py::isinstance(value, np.attr("floating"))) {
            value = py::float_(value.cast<double>());
        }
        bool camera_key = false;
        for (const MatrixMember &m : kMatrices) {
            camera_key = camera_key || name == m.name;
        }
        for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
            camera_key = camera_key || name == a.name;
        }
        if (camera_key) {
            // Written as an attribute it would replace the camera's value in the file.
            throw py::value_error("attribute \"" + name +
                                  "\" is a camera value: give it in camera=");
        }
        if (name.empty() || !io_detail::is_frame_attribute(name) ||
            name.find('\0') != std::string::npos) {
            // The writer sets these from the layout and write's parameters: kept here, they
            // were dropped on write without a word.
            throw py::value_error("attribute \"" + name +
                                  "\" is not the picture's: the write sets it from the file's "
                                  "layout and its parameters");
        }
        if (const OIIO::ParamValue *old =
                was ? was->find_pv(name, OIIO::TypeUnknown, true) : nullptr;
            old && in_type_of(*old, name, value, out)) {
            continue;
        }
        if (py::isinstance<py::bool_>(value) || py::isinstance<py::int_>(value)) {
            out.push_back(OIIO::ParamValue(name, int_attribute(value, name)));
        } else if (py::isinstance<py::float_>(value)) {
            out.push_back(OIIO::ParamValue(name, float_attribute(value, name)));
        } else if (py::isinstance<py::str>(value)) {
            out.push_back(OIIO::ParamValue(name, string_attribute(value, name)));
        } else if (py::isinstance<py::array>(value) &&
                   py::array(value.cast<py::array>()).ndim() == 2) {
            const glm::mat4 m = array_to_matrix(value, name);
            out.push_back(OIIO::ParamValue(name, OIIO::TypeMatrix44, 1, glm::value_ptr(m)));
        } else if (py::isinstance<py::list>(value) || py::isinstance<py::tuple>(value)) {
            const py::sequence seq = value.cast<py::sequence>();
            bool ints = true, floats = true, strings = true;
            for (py::handle item : seq) {
                ints = ints && py::isinstance<py::int_>(item);
                floats =
                    floats && (py::isinstance<py::int_>(item) || py::isinstance<py::float_>(item));
                strings = strings && py::isinstance<py::str>(item);
            }
            const int n = int(py::len(seq));
            if (ints && n > 0 && n != 2 && n != 3) {
                // OpenEXR's int types: one, or a vector of 2 or 3 (the write dropped the rest).
                throw py::value_error("attribute \"" + name +
                                      "\": OpenEXR holds 2 or 3 ints (a "
                                      "vector), not " +
                                      std::to_string(n) +
                                      "; give floats (a floatvector) or one int");
            }
            if (n > 0 && ints) {
                std::vector<int> v;
                for (py::handle item : seq) {
                    v.push_back(int_attribute(item, name));
                }
                out.push_back(
                    OIIO::ParamValue(name, OIIO::TypeDesc(OIIO::TypeDesc::INT, n), 1, v.data()));
            } else if (n > 0 && floats) {
                std::vector<float> v;
                for (py::handle item : seq) {
                    v.push_back(float_attribute(item, name));
                }
                out.push_back(
                    OIIO::ParamValue(name, OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, n), 1, v.data()));
            } else if (n > 0 && strings) {
                std::vector<OIIO::ustring> v;
                for (py::handle item : seq) {
                    v.emplace_back(string_attribute(item, name));
                }
                out.push_back(
                    OIIO::ParamValue(name, OIIO::TypeDesc(OIIO::TypeDesc::STRING, n), 1, v.data()));
            } else {
                throw py::type_error("attributes \"" + name +
                                     "\": a list must hold only numbers or only strings");
            }
        } else {
            throw py::type_error("attributes \"" + name + "\": a " +
                                 std::string(py::str(value.get_type().attr("__name__"))) +
                                 " has no EXR attribute type");
        }
    }
}

py::dict camera_to_dict(const Camera &camera)
{
    py::dict out;
    for (const MatrixMember &m : kMatrices) {
        if (camera.*m.member) {
            out[m.name] = matrix_to_array(*(camera.*m.member));
        }
    }
    for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
        if (camera.*a.member) {
            out[a.name] = py::float_(*(camera.*a.member));
        }
    }
    if (!camera.origin.empty()) {
        out["origin"] = py::str(camera.origin);
    }
    return out;
}

Camera dict_to_camera(py::handle dict)
{
    Camera camera;
    if (dict.is_none()) {
        return camera;
    }
    if (!py::isinstance<py::dict>(dict)) {
        throw py::type_error("camera: expected a dict keyed by header attribute names");
    }
    for (auto [key, value] : dict.cast<py::dict>()) {
        const std::string k = key_text(key, "camera: key");
        bool known = false;
        for (const MatrixMember &m : kMatrices) {
            if (k == m.name) {
                camera.*m.member = array_to_matrix(value, k);
                known = true;
            }
        }
        for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
            if (k == a.name) {
                camera.*a.member = camera_number(value, k);
                known = true;
            }
        }
        if (k == "origin") {
            if (!py::isinstance<py::str>(value)) {
                throw py::type_error("camera \"origin\": expected a string, got " +
                                     py::repr(value).cast<std::string>());
            }
            camera.origin = checked_text(value, "camera \"origin\"");
            known = true;
        }
        if (!known) {
            std::string names;
            for (const MatrixMember &m : kMatrices) {
                names += std::string(names.empty() ? "" : ", ") + m.name;
            }
            for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
                names += std::string(", ") + a.name;
            }
            throw py::value_error("camera: unknown key \"" + k + "\" (known: " + names +
                                  ", origin)");
        }
    }
    if (camera.origin.empty() && (camera.world_to_camera || camera.world_to_ndc)) {
        camera.origin = "python";
    }
    return camera;
}

py::tuple rect_to_tuple(const Rect &r)
{
    return py::make_tuple(r.x0, r.y0, r.x1, r.y1);
}

Rect tuple_to_rect(py::handle value, const char *what)
{
    std::vector<long long> v;
    try {
        v = value.cast<std::vector<long long>>();
    } catch (const py::cast_error &) {
        v.clear();
    }
    if (v.size() != 4) {
        throw py::value_error(std::string(what) + ": expected (x0, y0, x1, y1)");
    }
    const long long limit = 1ll << 30;
    for (long long x : v) {
        if (x < -limit || x > limit) {
            throw py::value_error(std::string(what) + ": coordinate out of range");
        }
    }
    if (v[2] - v[0] > limit || v[3] - v[1] > limit) {
        // (a width of 2^31 overflowed, and reformat's resize crashed)
        throw py::value_error(std::string(what) + ": wider or taller than 2^30");
    }
    const Rect r{int(v[0]), int(v[1]), int(v[2]), int(v[3])};
    if (r.empty()) {
        throw py::value_error(std::string(what) + ": empty (x1 must exceed x0 and y1 exceed y0)");
    }
    return r;
}

void register_errors(py::module_ &m)
{
    static py::handle base, graph_error, param_error, run_error;
    base = PyErr_NewExceptionWithDoc(
        "posthaste.Error",
        "Every error of posthaste; str(e) is the command line's one-line message and "
        "e.exit_code its exit code (1: input, output or evaluation, 2: the graph or a call).",
        PyExc_Exception,
        nullptr);
    graph_error = PyErr_NewExceptionWithDoc("posthaste.GraphError",
                                            "The graph, a node type, an input or a call is "
                                            "invalid; nothing was computed (exit code 2).",
                                            base.ptr(),
                                            nullptr);
    param_error = PyErr_NewExceptionWithDoc(
        "posthaste.ParameterError",
        "A node's parameter is unknown, of the wrong type, out of range or not applicable.",
        graph_error.ptr(),
        nullptr);
    run_error = PyErr_NewExceptionWithDoc(
        "posthaste.RunError",
        "Reading, writing or evaluating failed: a missing or broken file, a missing pass or "
        "camera, bad pixels (exit code 1).",
        base.ptr(),
        nullptr);
    m.add_object("Error", base);
    m.add_object("GraphError", graph_error);
    m.add_object("ParameterError", param_error);
    m.add_object("RunError", run_error);
    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) {
                std::rethrow_exception(p);
            }
        } catch (const Error &e) {
            const std::string msg = printable_line(e.what());  // as the command line prints it
            py::handle type = run_error;
            if (e.code() == ExitCode::Usage) {
                type = msg.find("param \"") != std::string::npos ? param_error : graph_error;
            }
            py::object exc = py::reinterpret_borrow<py::object>(type)(msg);
            exc.attr("exit_code") = e.exit_code();
            PyErr_SetObject(type.ptr(), exc.ptr());
        }
    });
}

}  // namespace posthaste::python
