// posthaste.Frame (py_frame.h): passes as numpy arrays over the images' own memory.

#include "python/py_frame.h"

#include <pybind11/stl.h>

#include <algorithm>
#include <cstring>

#include "python/py_convert.h"

namespace posthaste::python {
namespace {

std::string size_text(int w, int h)
{
    return std::to_string(w) + "x" + std::to_string(h);
}

std::string missing_pass(const Frame &f, const std::string &name)
{
    std::string known;
    for (const std::string &n : f.pass_names()) {
        known += (known.empty() ? "" : ", ") + n;
    }
    return "no pass \"" + name + "\" in the frame (it has: " + (known.empty() ? "none" : known) +
           ")";
}

/// The Python face of Frame.passes: a mutable mapping over the frame's passes.
struct PassMap {
    std::shared_ptr<PyFrame> owner;
};

}  // namespace

Image image_from_array(const std::string &name, py::handle object)
{
    const std::string who = "pass \"" + name + "\"";
    if (!py::isinstance<py::array>(object)) {
        throw py::value_error(who + ": expected a numpy array, got " +
                              std::string(py::str(object.get_type().attr("__name__"))));
    }
    const py::array a = py::reinterpret_borrow<py::array>(object);
    const py::dtype dt = a.dtype();
    if (dt.kind() != 'f' || (dt.itemsize() != 2 && dt.itemsize() != 4 && dt.itemsize() != 8)) {
        throw py::value_error(who + ": dtype " + std::string(py::str(py::handle(dt))) +
                              " is not float16, float32 or float64");
    }
    if (a.ndim() != 2 && a.ndim() != 3) {
        throw py::value_error(who +
                              ": expected shape (height, width) or (height, width, channels), "
                              "got " +
                              std::to_string(a.ndim()) + " dimensions");
    }
    const py::ssize_t h = a.shape(0), w = a.shape(1), c = a.ndim() == 3 ? a.shape(2) : 1;
    if (c < 1 || c > 64) {
        throw py::value_error(who + ": " + std::to_string(c) + " channels (1 to 64 allowed)");
    }
    if (w < 1 || h < 1 || w > 65536 || h > 65536 || w * h > (py::ssize_t(1) << 28)) {
        throw py::value_error(who + ": size " + std::to_string(w) + "x" + std::to_string(h) +
                              " (each side 1 to 65536, at most 2^28 pixels)");
    }
    // The image first, against the memory budget (a posthaste.Error naming the size); numpy
    // then converts straight into it, whatever the dtype, byte order and strides. A float32
    // temporary made first (array_t::ensure) could fail for lack of memory, and pybind11 then
    // said only "error_already_set called while Python error indicator not set".
    Image image = Image::uninitialized(int(w), int(h), int(c));
    const py::capsule no_owner(image.data(), [](void *) {});
    py::array dst = a.ndim() == 3
                        ? py::array(py::dtype::of<float>(), {h, w, c}, image.data(), no_owner)
                        : py::array(py::dtype::of<float>(), {h, w}, image.data(), no_owner);
    py::module_::import("numpy").attr("copyto")(dst, a, py::arg("casting") = "unsafe");
    return image;
}

PyFrame::Holder &PyFrame::holder(const std::string &name)
{
    const ImagePtr &image = frame_.pass(name, "posthaste.Frame").image;
    Holder &h = holders_[name];
    if (h.image != image.get()) {
        h.image = image.get();
        h.capsule =
            py::capsule(new ImagePtr(image), [](void *p) { delete static_cast<ImagePtr *>(p); });
        h.writable = py::list();
    }
    return h;
}

bool PyFrame::owns(const std::string &name) const
{
    const ImagePtr &image = frame_.pass(name, "posthaste.Frame").image;
    const auto it = holders_.find(name);
    const long ours = it != holders_.end() && it->second.image == image.get() ? 2 : 1;
    return image.use_count() == ours;
}

py::array PyFrame::make_array(const std::string &name, bool writable)
{
    Holder &h = holder(name);
    const Image &img = *h.image;
    const auto c = py::ssize_t(img.channels());
    const auto w = py::ssize_t(img.width());
    py::array_t<float> a({py::ssize_t(img.height()), w, c},
                         {w * c * py::ssize_t(sizeof(float)),
                          c * py::ssize_t(sizeof(float)),
                          py::ssize_t(sizeof(float))},
                         img.data(),
                         h.capsule);
    if (writable) {
        // Dead references go when the list reaches a power of two (16, 32, ...): a loop that
        // reads passes[name][y, x] made a reference per call and kept it (84 MB a million).
        const std::size_t n = py::len(h.writable);
        if (n >= 16 && (n & (n - 1)) == 0) {
            py::list alive;
            for (py::handle ref : h.writable) {
                if (!ref().is_none()) {
                    alive.append(ref);
                }
            }
            h.writable = alive;
        }
        h.writable.append(py::module_::import("weakref").attr("ref")(a));
        // A writable array may change the pixels: the writer must not treat the pass as read.
        Pass p = frame_.pass(name);
        if (p.untouched()) {
            p.as_read.reset();
            frame_.set_pass(name, std::move(p));
        }
    } else {
        a.attr("flags").attr("writeable") = false;
    }
    return a;
}

py::array PyFrame::view(const std::string &name)
{
    if (!frame_.has(name)) {
        throw py::key_error(missing_pass(frame_, name));
    }
    return make_array(name, owns(name));
}

py::array PyFrame::writable(const std::string &name)
{
    if (!frame_.has(name)) {
        throw py::key_error(missing_pass(frame_, name));
    }
    if (!owns(name)) {
        Pass p = frame_.pass(name);
        p.image = std::make_shared<const Image>(*p.image);
        p.as_read.reset();
        frame_.set_pass(name, std::move(p));
    }
    return make_array(name, true);
}

void PyFrame::set_pass(const std::string &name, py::handle array, py::handle channels)
{
    if (name.empty()) {
        throw py::value_error("a pass needs a name");
    }
    Image image = image_from_array(name, array);
    if (!frame_.data_window.empty() &&
        (image.width() != frame_.width() || image.height() != frame_.height())) {
        throw py::value_error("pass \"" + name + "\": " + size_text(image.width(), image.height()) +
                              ", but the frame's data window is " +
                              size_text(frame_.width(), frame_.height()));
    }
    std::vector<std::string> names;
    if (!channels.is_none()) {
        // (a null cut "x\0y" to "x" in the file)
        names = channel_names_arg(channels, "pass \"" + name + "\"");
        for (std::size_t k = 0; k < names.size(); ++k) {
            // A dot separates a layer from its channel in the file: "a.b" would come back as a
            // pass of its own; an empty name or a repeated one cannot be told apart.
            if (names[k].empty() || names[k].find('.') != std::string::npos ||
                std::find(names.begin(), names.begin() + std::ptrdiff_t(k), names[k]) !=
                    names.begin() + std::ptrdiff_t(k)) {
                throw py::value_error("pass \"" + name + "\": channel name \"" + names[k] +
                                      "\" (names are unique, not empty, without a dot)");
            }
        }
        if (int(names.size()) != image.channels()) {
            throw py::value_error("pass \"" + name + "\": " + std::to_string(names.size()) +
                                  " channel names for " + std::to_string(image.channels()) +
                                  " channels");
        }
    } else if (frame_.has(name) && frame_.pass(name).image->channels() == image.channels()) {
        names = frame_.pass(name).channels;
    }
    frame_.set(name, std::make_shared<const Image>(std::move(image)), std::move(names));
}

void PyFrame::remove_pass(const std::string &name)
{
    if (!frame_.has(name)) {
        throw py::key_error(missing_pass(frame_, name));
    }
    frame_.erase(name);
    holders_.erase(name);
}

std::shared_ptr<const Frame> PyFrame::share()
{
    // A writable array still alive may change its pass later, and so may any view of it
    // (a[..., 0], a.reshape(-1): numpy keeps their own writeable flags, so clearing the array's
    // did not stop them). Such a pass is handed on as a copy of its pixels now; the rest are
    // shared.
    auto shared = std::make_shared<Frame>(frame_);
    for (auto &[name, h] : holders_) {
        py::list alive;
        for (py::handle ref : h.writable) {
            if (!ref().is_none()) {
                alive.append(ref);
            }
        }
        h.writable = alive;
        if (alive.empty() || !frame_.has(name) || frame_.pass(name).image.get() != h.image) {
            continue;
        }
        Pass p = frame_.pass(name);
        p.image = std::make_shared<const Image>(*p.image);
        shared->set_pass(name, std::move(p));
    }
    return shared;
}

void bind_frame(py::module_ &m)
{
    py::class_<PassMap>(m,
                        "Passes",
                        "The passes of a Frame by name: numpy arrays of shape "
                        "(height, width, channels) over the frame's memory.")
        .def("__getitem__",
             [](PassMap &p, py::handle n) {
                 return p.owner->view(pass_name_arg(n, "posthaste.Passes"));
             })
        .def("__setitem__",
             [](PassMap &p, py::handle n, py::handle a) {
                 p.owner->set_pass(pass_name_arg(n, "posthaste.Passes"), a, py::none());
             })
        .def("__delitem__",
             [](PassMap &p, py::handle n) {
                 p.owner->remove_pass(pass_name_arg(n, "posthaste.Passes"));
             })
        .def("__contains__",
             [](PassMap &p, py::handle n) {
                 // A mapping: anything that is not a name is not in it (0 in f.passes).
                 return py::isinstance<py::str>(n) && p.owner->frame().has(n.cast<std::string>());
             })
        .def("__len__", [](PassMap &p) { return p.owner->frame().passes().size(); })
        .def("__iter__",
             [](PassMap &p) { return py::iter(py::cast(p.owner->frame().pass_names())); })
        .def("keys", [](PassMap &p) { return p.owner->frame().pass_names(); })
        .def("items",
             [](PassMap &p) {
                 py::list out;
                 for (const std::string &n : p.owner->frame().pass_names()) {
                     out.append(py::make_tuple(n, p.owner->view(n)));
                 }
                 return out;
             })
        .def("values",
             [](PassMap &p) {
                 py::list out;
                 for (const std::string &n : p.owner->frame().pass_names()) {
                     out.append(p.owner->view(n));
                 }
                 return out;
             })
        .def(
            "get",
            [](PassMap &p, py::handle name, py::object fallback) -> py::object {
                const std::string n = pass_name_arg(name, "posthaste.Passes.get");
                return p.owner->frame().has(n) ? py::object(p.owner->view(n)) : fallback;
            },
            py::arg("name"),
            py::arg("default") = py::none())
        .def("__repr__", [](PassMap &p) {
            std::string s;
            for (const auto &[n, pass] : p.owner->frame().passes()) {
                s += (s.empty() ? "" : ", ") + n + "(" + std::to_string(pass.image->channels()) +
                     ")";
            }
            return "<posthaste.Passes " + s + ">";
        });

    py::class_<PyFrame, std::shared_ptr<PyFrame>>(
        m, "Frame", "One frame: named passes (numpy views), camera, header attributes, windows.")
        .def(py::init([](py::object passes,
                         py::object camera,
                         py::object attributes,
                         py::object display_window,
                         py::object data_window,
                         py::handle number,
                         py::object channels) {
                 auto f = std::make_shared<PyFrame>();
                 Frame &fr = f->frame();
                 fr.number = cast_arg<int>(number, "number", "an int (32 bits)");
                 if (!data_window.is_none()) {
                     fr.data_window = tuple_to_rect(data_window, "data_window");
                 }
                 if (!display_window.is_none()) {
                     fr.display_window = tuple_to_rect(display_window, "display_window");
                     if (data_window.is_none()) {
                         fr.data_window = fr.display_window;
                     }
                 } else if (!data_window.is_none()) {
                     fr.display_window = fr.data_window;
                 }
                 if (!channels.is_none() && !py::isinstance<py::dict>(channels)) {
                     throw py::type_error("channels: expected a dict {pass: [names]}");
                 }
                 if (passes.is_none() && !channels.is_none() && py::len(channels) > 0) {
                     // (they were ignored without a word)
                     const py::object first = py::list(channels)[0];
                     throw py::value_error("channels: no pass \"" +
                                           key_text(first, "channels: pass") + "\" in passes");
                 }
                 if (!passes.is_none()) {
                     const py::dict chans =
                         channels.is_none() ? py::dict() : channels.cast<py::dict>();
                     if (!py::isinstance<py::dict>(passes)) {
                         throw py::type_error("passes: expected a dict {name: array}, got " +
                                              type_name(passes));
                     }
                     const py::dict given = passes.cast<py::dict>();
                     for (auto [key, value] : chans) {
                         if (!given.contains(key)) {
                             throw py::value_error("channels: no pass \"" +
                                                   key_text(key, "channels: pass") +
                                                   "\" in passes");
                         }
                     }
                     for (auto [key, value] : given) {
                         const std::string n = pass_name_arg(key, "passes");
                         f->set_pass(
                             n, value, chans.contains(key) ? py::object(chans[key]) : py::none());
                     }
                 }
                 fr.camera = dict_to_camera(camera);
                 dict_to_attributes(attributes, fr.attributes);
                 return f;
             }),
             py::arg("passes") = py::none(),
             py::arg("camera") = py::none(),
             py::arg("attributes") = py::none(),
             py::arg("display_window") = py::none(),
             py::arg("data_window") = py::none(),
             py::arg("number") = 1,
             py::arg("channels") = py::none(),
             "Passes from numpy arrays (float16, float32 or float64; converted to float32 once).")
        .def_property_readonly(
            "passes",
            [](std::shared_ptr<PyFrame> f) { return PassMap{std::move(f)}; },
            "The passes by name (a mutable mapping of numpy arrays).")
        .def(
            "writable",
            [](PyFrame &f, py::handle n) {
                return f.writable(pass_name_arg(n, "posthaste.Frame.writable"));
            },
            py::arg("name"),
            "A writable array over the pass, copied first if another frame shares it.")
        .def(
            "owns",
            [](PyFrame &f, py::handle n) {
                const std::string name = pass_name_arg(n, "posthaste.Frame.owns");
                if (!f.frame().has(name)) {
                    throw py::key_error(missing_pass(f.frame(), name));  // as writable's
                }
                return f.owns(name);
            },
            py::arg("name"),
            "True when no other frame shares the pass (its array is writable).")
        .def(
            "set_pass",
            [](PyFrame &f, py::handle n, py::handle array, py::handle channels) {
                f.set_pass(pass_name_arg(n, "posthaste.Frame.set_pass"), array, channels);
            },
            py::arg("name"),
            py::arg("array"),
            py::arg("channels") = py::none())
        .def(
            "channels",
            [](PyFrame &f, py::handle name) {
                const std::string n = pass_name_arg(name, "posthaste.Frame.channels");
                if (!f.frame().has(n)) {
                    throw py::key_error(missing_pass(f.frame(), n));
                }
                return f.frame().pass(n).channels;
            },
            py::arg("name"),
            "The channel names of a pass (\"R\", \"G\", ...).")
        .def(
            "copy",
            [](PyFrame &f) { return std::make_shared<PyFrame>(*f.share()); },
            "A new frame sharing this one's pass images (copy-on-write).")
        .def(
            "_data_address",
            [](PyFrame &f, const std::string &n) {
                return reinterpret_cast<std::uintptr_t>(
                    f.frame().pass(n, "posthaste.Frame").image->data());
            },
            "The address of a pass's pixels in memory (for tests of sharing).")
        .def_property(
            "number",
            [](PyFrame &f) { return f.frame().number; },
            [](PyFrame &f, py::handle n) {
                f.frame().number = cast_arg<int>(n, "posthaste.Frame.number", "an int (32 bits)");
            })
        .def_property_readonly("width", [](PyFrame &f) { return f.frame().width(); })
        .def_property_readonly("height", [](PyFrame &f) { return f.frame().height(); })
        .def_property(
            "display_window",
            [](PyFrame &f) { return rect_to_tuple(f.frame().display_window); },
            [](PyFrame &f, py::handle r) {
                f.frame().display_window = tuple_to_rect(r, "display_window");
            },
            "(x0, y0, x1, y1), exclusive maximum: the delivered format.")
        .def_property(
            "data_window",
            [](PyFrame &f) { return rect_to_tuple(f.frame().data_window); },
            [](PyFrame &f, py::handle r) {
                const Rect d = tuple_to_rect(r, "data_window");
                if (!f.frame().passes().empty() &&
                    (d.width() != f.frame().width() || d.height() != f.frame().height())) {
                    throw py::value_error("data_window: " + size_text(d.width(), d.height()) +
                                          ", but the passes are " +
                                          size_text(f.frame().width(), f.frame().height()));
                }
                f.frame().data_window = d;
            },
            "(x0, y0, x1, y1), exclusive maximum: where the passes' pixels are.")
        .def_property(
            "camera",
            [](PyFrame &f) { return camera_to_dict(f.frame().camera); },
            [](PyFrame &f, py::handle d) { f.frame().camera = dict_to_camera(d); },
            "The camera as header attributes (4x4 float32 matrices, p @ M), plus origin.")
        .def_property(
            "attributes",
            [](PyFrame &f) { return attributes_to_dict(f.frame().attributes); },
            [](PyFrame &f, py::handle d) {
                OIIO::ParamValueList list;
                dict_to_attributes(d, list, &f.frame().attributes);
                f.frame().attributes = std::move(list);
            },
            "Header attributes other than the camera's.")
        .def("__repr__", [](PyFrame &f) {
            std::string s;
            for (const auto &[n, pass] : f.frame().passes()) {
                s += (s.empty() ? "" : ", ") + n + "(" + std::to_string(pass.image->channels()) +
                     ")";
            }
            return "<posthaste.Frame " + std::to_string(f.frame().number) + ", " +
                   size_text(f.frame().width(), f.frame().height()) + ": " + s + ">";
        });
}

}  // namespace posthaste::python
