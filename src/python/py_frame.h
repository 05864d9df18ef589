#pragma once
// posthaste.Frame: an engine Frame held by Python, whose passes are numpy arrays over the pass
// images' own memory.
//
// Sharing rule: a pass image may be shared with other frames (a node's output keeps the passes it
// did not change, as the engine does). An array is writable only while its frame holds the image
// alone; otherwise it is read-only, and Frame.writable(name) first gives the frame its own copy
// (copy-on-write). Handing a frame to the engine (a node, write, diff) shares its images, so the
// writable arrays made before become read-only then.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <map>
#include <memory>
#include <string>

#include "core/frame.h"

namespace posthaste::python {

namespace py = pybind11;

class PyFrame {
   public:
    PyFrame() = default;
    explicit PyFrame(Frame f) : frame_(std::move(f)) {}

    Frame &frame() { return frame_; }
    const Frame &frame() const { return frame_; }

    /// An array over pass `name`'s memory: writable when this frame holds the image alone.
    py::array view(const std::string &name);
    /// A writable array over pass `name`, copying the image first when it is shared.
    py::array writable(const std::string &name);
    /// Replace or add pass `name` from an array (converted to float32 once).
    void set_pass(const std::string &name, py::handle array, py::handle channels);
    void remove_pass(const std::string &name);
    /// True when this frame holds pass `name`'s image alone.
    bool owns(const std::string &name) const;

    /// The frame for the engine: its writable arrays become read-only, since the images are
    /// shared from now on.
    std::shared_ptr<const Frame> share();

   private:
    struct Holder {
        const Image *image = nullptr;
        py::object capsule;  ///< Holds an ImagePtr; the base object of every array over it.
        py::list writable;   ///< Weak references to the writable arrays made over it.
    };
    Holder &holder(const std::string &name);
    py::array make_array(const std::string &name, bool writable);

    Frame frame_;
    std::map<std::string, Holder> holders_;
};

/// A pass array from Python (2-D or 3-D, float16/32/64) as an image; ValueError naming `name`.
Image image_from_array(const std::string &name, py::handle array);

void bind_frame(py::module_ &m);

}  // namespace posthaste::python
