// nodes/crop.cpp: a new display window (the box, file coordinates, exclusive maximum, y down;
// all zero, the default, keeps the display window), and by default the data window cut to it;
// `reformat` moves the box to the origin. No pixel is resampled: passes are cut or padded (0,
// depth +inf where the box reaches past the data), so their values and file origins are kept.
// worldToNDC (and the previous frame's) and the sensor size follow the new display window, so
// the camera still projects onto the same pixels.

#include "filter/frame_ops.h"
#include "io/source_file.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kBox = ParamSpec::vec4("box", 0, 0, 0, 0)
                               .units("px")
                               .doc(
                                   "The new display window: x0, y0, x1, y1 (file coordinates, "
                                   "x1 and y1 excluded); all 0: the display window as it is.");
constexpr ParamSpec kCropData = ParamSpec::boolean("crop_data", true)
                                    .doc(
                                        "Cut the data window to the box too (false: keep the "
                                        "pixels outside it as overscan).");
constexpr ParamSpec kReformat =
    ParamSpec::boolean("reformat", false).doc("Move the box's corner to (0, 0).");
constexpr ParamSpec kParams[] = {kBox, kCropData, kReformat};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to crop."}};

/// The box as a rectangle (all zero: `display`), or a usage error naming the parameter.
Rect box_of(const NodeParams &p, const std::string &where, const Rect &display)
{
    const std::vector<double> &b = p.get_vec(kBox);
    if (b[0] == 0 && b[1] == 0 && b[2] == 0 && b[3] == 0) {
        return display;
    }
    for (double v : b) {
        if (v != std::floor(v) || std::abs(v) > 1e9) {
            throw_param_expected(where, kBox.name, "whole pixel coordinates", v);
        }
    }
    const Rect r{int(b[0]), int(b[1]), int(b[2]), int(b[3])};
    if (r.empty()) {
        throw_param_expected(where,
                             kBox.name,
                             "x1 above x0 and y1 above y0",
                             str_cat("[", r.x0, ", ", r.y0, ", ", r.x1, ", ", r.y1, "] (empty)"));
    }
    if (r.width() > kMaxImageSide || r.height() > kMaxImageSide) {
        throw_param_expected(where,
                             kBox.name,
                             str_cat("at most ", kMaxImageSide, " pixels a side"),
                             str_cat(r.width(), "x", r.height()));
    }
    return r;
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Rect box = box_of(ctx.params(), ctx.where(), in.display_window);
    Rect window = ctx.get_bool(kCropData) ? in.data_window.intersect(box) : in.data_window;
    if (window.empty()) {
        window = {box.x0, box.y0, box.x0 + 1, box.y0 + 1};  // nothing left: one empty pixel
    }
    const int dx = ctx.get_bool(kReformat) ? -box.x0 : 0;
    const int dy = ctx.get_bool(kReformat) ? -box.y0 : 0;
    filter::Affine shift(1.0);
    shift[2][0] = dx;
    shift[2][1] = dy;
    Frame &out = ctx.output();
    if (window == in.data_window && box == in.display_window && dx == 0 && dy == 0) {
        return;
    }
    out.camera = filter::moved_camera(in.camera, shift, in.display_window, box.offset(dx, dy));
    for (const auto &[view, camera] : in.view_cameras) {
        out.view_cameras[view] =
            filter::moved_camera(camera, shift, in.display_window, box.offset(dx, dy));
    }
    out.display_window = box.offset(dx, dy);
    if (in.source && (dx != 0 || dy != 0)) {
        out.source = moved_source(*in.source, dx, dy);  // its parts' windows move too
    }
    if (window == in.data_window) {
        out.data_window = window.offset(dx, dy);
        return;  // only the windows moved: the pixels are shared
    }
    filter::cut_data_window(in, window, out, dx, dy);
}

void check(CheckContext &ctx)
{
    box_of(ctx.params, ctx.node.json_path + "/params: " + ctx.node.describe(), Rect{0, 0, 1, 1});
}

}  // namespace

extern const NodeType kCrop{
    {"crop",
     "Crop to a box: a new display window, the data window cut to it, optionally at the origin.",
     kInputs,
     kParams,
     "",
     /*sink=*/false,
     /*keeps_specular=*/true},
    &execute,
    nullptr,
    &check};

}  // namespace posthaste::nodes
