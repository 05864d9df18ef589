// nodes/reformat.cpp: resize a frame to a new format (ImageBufAlgo::resize, a named filter whose
// support widens when minifying, so nothing aliases). Every pass is resized: `filtered` passes
// (color, albedo) with `filter`, the others (depth, ids, normals, motion) by nearest neighbour,
// values unchanged except motion vectors, which are pixels and scale with the image. The display
// window becomes the new format (its origin scaled), the data window the old one scaled (rounded
// outward), so overscan keeps its share of the frame. The camera needs no change: worldToNDC
// spans the display window, whatever its resolution.

#include <algorithm>
#include <cmath>

#include "filter/frame_ops.h"
#include "io/source_file.h"
#include "nodes/geometry_params.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kWidth = ParamSpec::integer("width", 0)
                                 .range(0, kMaxImageSide)
                                 .units("px")
                                 .doc(
                                     "New display width; 0: from height keeping the pixel "
                                     "aspect, or from scale.");
constexpr ParamSpec kHeight = ParamSpec::integer("height", 0)
                                  .range(0, kMaxImageSide)
                                  .units("px")
                                  .doc(
                                      "New display height; 0: from width keeping the pixel "
                                      "aspect, or from scale.");
constexpr ParamSpec kScale = ParamSpec::real("scale", 1.0)
                                 .range(1e-4, 64.0)
                                 .doc("Scale of both sides when width and height are 0.");
constexpr ParamSpec kFilter = geometry_filter("blackman-harris");
constexpr ParamSpec kParams[] = {kWidth, kHeight, kScale, kFilter, kGeometryFiltered};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to resize."}};

/// The new display window: the size asked for, the origin scaled with it.
Rect new_display(const NodeParams &p, const Rect &d)
{
    int w = p.get_int(kWidth), h = p.get_int(kHeight);
    if (w == 0 && h == 0) {
        w = int(std::lround(d.width() * p.get_real(kScale)));
        h = int(std::lround(d.height() * p.get_real(kScale)));
    } else if (w == 0) {  // (bounded before the cast: a 1xN frame's width could pass int's)
        w = int(std::lround(std::min(double(d.width()) * h / d.height(), 1e9)));
    } else if (h == 0) {
        h = int(std::lround(std::min(double(d.height()) * w / d.width(), 1e9)));
    }
    w = std::max(w, 1);
    h = std::max(h, 1);
    const int x0 = int(std::lround(double(d.x0) * w / d.width()));
    const int y0 = int(std::lround(double(d.y0) * h / d.height()));
    return {x0, y0, x0 + w, y0 + h};
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Rect display = new_display(ctx.params(), in.display_window);
    if (display == in.display_window) {
        return;  // the same format: every pass is shared
    }
    filter::FrameWarp w;
    w.to_output = filter::window_map(in.display_window, display);
    w.window = filter::transformed_bounds(w.to_output, in.data_window);
    // The parameter that made the size: a height alone sets the width too (it named "width").
    const NodeParams &p = ctx.params();
    const char *param = p.given(kScale)                                               ? "scale"
                        : p.get_int(kWidth) == 0                                      ? "height"
                        : p.get_int(kHeight) == 0 || w.window.width() > kMaxImageSide ? "width"
                                                                                      : "height";
    check_window_size(ctx.where(), w.window, param);
    w.display = display;
    w.resize = true;
    fill_into(w, ctx.params(), std::span<const Binding<filter::FrameWarp>>(kWarpFields<kFilter>));
    filter::warp_frame(in, w, ctx.output());
    if (in.source) {
        // The file's parts follow the new grid (a write once cut it to their old windows).
        ctx.output().source = regridded_source(*in.source, ctx.output().data_window);
    }
}

void check(CheckContext &ctx)
{
    check_filter_name(ctx);
    check_separable_filter(ctx);
    const NodeParams &p = ctx.params;
    if (p.given(kScale) && (p.get_int(kWidth) != 0 || p.get_int(kHeight) != 0)) {
        throw_param(ctx, kScale, "applies only when width and height are 0");
    }
}

}  // namespace

extern const NodeType kReformat{
    {"reformat",
     "Resize to a new format (OpenImageIO filters); every pass, motion vectors scaled.",
     kInputs,
     kParams,
     "",
     /*sink=*/false,
     /*keeps_specular=*/true},
    &execute,
    nullptr,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kReformat, kWarpFields<kFilter>, problems); }};

}  // namespace posthaste::nodes
