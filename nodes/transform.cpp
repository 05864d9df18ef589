// nodes/transform.cpp: translate, rotate and scale the frame's pixels within its format (bicubic
// or bilinear through the lens node's Highway kernel, or an OpenImageIO filter through
// ImageBufAlgo::warp). The map is Nuke's Transform order: scale, then rotate
// (degrees, counter-clockwise on screen), both about the pivot, then translate (pixels, y down).
// Every pass moves: `filtered` passes with `filter`, the others by nearest neighbour, values
// unchanged except motion vectors, which turn and scale with the image. The data window becomes
// the moved one (rounded outward), within the display window widened by half its size on every
// side; the display window stays. worldToNDC (and the previous frame's) take the same map, so a
// world point still projects onto the pixel that shows it.

#include <cmath>
#include <limits>

#include "filter/frame_ops.h"
#include "io/source_file.h"
#include "nodes/geometry_params.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kTranslateX =
    ParamSpec::real("translate_x", 0.0).range(-1e6, 1e6).units("px").doc("Move right.");
constexpr ParamSpec kTranslateY =
    ParamSpec::real("translate_y", 0.0).range(-1e6, 1e6).units("px").doc("Move down.");
constexpr ParamSpec kRotate = ParamSpec::real("rotate", 0.0)
                                  .range(-36000.0, 36000.0)
                                  .units("deg")
                                  .doc("Rotation, counter-clockwise on screen.");
constexpr ParamSpec kScale =
    ParamSpec::real("scale", 1.0).range(1e-3, 1e3).doc("Uniform scale about the pivot.");
constexpr ParamSpec kScaleX =
    ParamSpec::real("scale_x", 1.0).range(1e-3, 1e3).doc("Horizontal scale (times scale).");
constexpr ParamSpec kScaleY =
    ParamSpec::real("scale_y", 1.0).range(1e-3, 1e3).doc("Vertical scale (times scale).");
constexpr ParamSpec kPivotX = ParamSpec::real("pivot_x", 0.0)
                                  .range(-1e6, 1e6)
                                  .units("px")
                                  .doc("Pivot's offset from the display window's centre.");
constexpr ParamSpec kPivotY = ParamSpec::real("pivot_y", 0.0)
                                  .range(-1e6, 1e6)
                                  .units("px")
                                  .doc("Pivot's offset from the display window's centre (down).");
constexpr ParamSpec kFilter = geometry_filter("bicubic");
constexpr ParamSpec kParams[] = {kTranslateX,
                                 kTranslateY,
                                 kRotate,
                                 kScale,
                                 kScaleX,
                                 kScaleY,
                                 kPivotX,
                                 kPivotY,
                                 kFilter,
                                 kGeometryFiltered};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to move."}};

filter::Affine transform_map(const NodeContext &ctx, const Rect &display)
{
    const double cx = 0.5 * (display.x0 + display.x1) + ctx.get_real(kPivotX);
    const double cy = 0.5 * (display.y0 + display.y1) + ctx.get_real(kPivotY);
    const double s = ctx.get_real(kScale);
    const double sx = s * ctx.get_real(kScaleX), sy = s * ctx.get_real(kScaleY);
    // Counter-clockwise on screen with y down is a negative angle in the file's coordinates.
    const double a = -ctx.get_real(kRotate) * (std::acos(-1.0) / 180.0);
    const double c = std::cos(a), sn = std::sin(a);
    // p' = pivot + R S (p - pivot) + t, glm column-major.
    filter::Affine m(1.0);
    m[0][0] = c * sx;
    m[0][1] = sn * sx;
    m[1][0] = -sn * sy;
    m[1][1] = c * sy;
    m[2][0] = cx + ctx.get_real(kTranslateX) - (m[0][0] * cx + m[1][0] * cy);
    m[2][1] = cy + ctx.get_real(kTranslateY) - (m[0][1] * cx + m[1][1] * cy);
    // Exact quarter turns: cos and sin of pi/2 are not exactly 0 and 1 in floating point.
    for (int i = 0; i < 2; ++i) {
        for (int j = 0; j < 2; ++j) {
            if (std::abs(m[i][j]) < 1e-15) {
                m[i][j] = 0.0;
            }
        }
    }
    return m;
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const filter::Affine m = transform_map(ctx, in.display_window);
    if (m == filter::Affine(1.0)) {
        return;  // the identity: every pass is shared
    }
    filter::FrameWarp w;
    w.to_output = m;
    const Rect &d = in.display_window;
    const Rect limit = d.expand(std::max(d.width(), d.height()) / 2);
    w.window = filter::transformed_bounds(m, in.data_window).intersect(limit);
    if (w.window.empty()) {
        // Everything moved out of reach: one empty pixel at the display's origin.
        w.window = {d.x0, d.y0, d.x0 + 1, d.y0 + 1};
    }
    check_window_size(ctx.where(), w.window, "scale");
    w.display = d;
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
    // Each axis's own scale within the range one scale has: scale 0.001 times scale_x 0.001
    // asked OpenImageIO's warp for a footprint of millions of pixels a side (it ran for hours).
    const NodeParams &p = ctx.params;
    for (const ParamSpec *axis : {&kScaleX, &kScaleY}) {
        const double total = p.get_real(kScale) * p.get_real(*axis);
        if (!(total >= 1e-3 && total <= 1e3)) {
            throw_param(ctx,
                        *axis,
                        str_cat("scale x ", axis->name, " is ", total, ", outside 0.001..1000"));
        }
    }
}

}  // namespace

extern const NodeType kTransform{
    {"transform",
     "Translate, rotate and scale every pass (OpenImageIO warp); the camera follows.",
     kInputs,
     kParams,
     "",
     /*sink=*/false,
     /*keeps_specular=*/true},
    &execute,
    nullptr,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kTransform, kWarpFields<kFilter>, problems); }};

}  // namespace posthaste::nodes
