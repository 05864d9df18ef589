#pragma once
// Parameters and checks shared by the nodes that move every pass (reformat, transform): the
// resampling filter, which passes it applies to, and the size guard.

#include <string>

#include "filter/frame_ops.h"
#include "filter/image_ops.h"
#include "nodes/node.h"

namespace posthaste::nodes {

/// The filter parameter, with its default per node: `def` is "blackman-harris" or "bicubic".
constexpr ParamSpec geometry_filter(std::string_view def)
{
    return ParamSpec::string("filter", def)
        .doc(
            "bicubic (Catmull-Rom) or bilinear: fast point sampling (Highway); an OpenImageIO "
            "filter (blackman-harris, lanczos3, catmull-rom, mitchell, gaussian, triangle, "
            "box, ...): its footprint; or nearest.");
}
inline constexpr ParamSpec kGeometryFiltered =
    ParamSpec::string("filtered", "color,albedo")
        .doc("Passes resampled with `filter`; the others (depth, ids, normals) take the nearest.");

/// The warp's resampling, from the node's `filter` and `filtered`. FrameWarp leaves both to its
/// caller: reformat and transform default `filter` differently.
template <const ParamSpec &Filter>
inline constexpr Binding<filter::FrameWarp> kWarpFields[] = {
    bind<&filter::FrameWarp::filter>(Filter).without_default(),
    bind<&filter::FrameWarp::filtered>(kGeometryFiltered).without_default(),
};

/// A usage error naming the node and parameter when `filter` is not a filter OpenImageIO knows.
inline void check_filter_name(const CheckContext &ctx)
{
    const std::string &f = ctx.params.values().at("filter").text;
    if (f != "nearest" && f != "bicubic" && f != "bilinear" && !filter::is_filter_name(f)) {
        throw_param(ctx.node.json_path + "/params/filter: " + ctx.node.describe(),
                    "filter",
                    "unknown filter " + quoted(f) +
                        " (bicubic, bilinear, nearest, or OpenImageIO's: blackman-harris, "
                        "lanczos3, catmull-rom, mitchell, gaussian, triangle, box, ...)");
    }
}

/// A usage error naming the node and parameter when `filter` is one of OpenImageIO's
/// non-separable (radial) filters: ImageBufAlgo::resize fails an assertion on them at some sizes
/// (disk and radial-lanczos3 to 1x1 or 100x100 from 320x180 aborted the process), so reformat,
/// which resizes through it, takes only separable ones.
inline void check_separable_filter(const CheckContext &ctx)
{
    const std::string &f = ctx.params.values().at("filter").text;
    if (filter::is_filter_name(f) && !filter::is_separable_filter(f)) {
        throw_param(ctx.node.json_path + "/params/filter: " + ctx.node.describe(),
                    "filter",
                    "filter " + quoted(f) +
                        " is radial (not separable), which resizing does not take: use a "
                        "separable one (blackman-harris, lanczos3, catmull-rom, mitchell, "
                        "gaussian, triangle, box, ...), or transform, which warps with any");
    }
}

/// A runtime error naming the node when an output window would be absurdly large.
inline void check_window_size(const std::string &where, const Rect &window, const char *param)
{
    constexpr double kMaxPixels = double(1 << 28);
    if (window.width() > kMaxImageSide || window.height() > kMaxImageSide ||
        double(window.width()) * double(window.height()) > kMaxPixels) {
        throw_param(where,
                    param,
                    str_cat("the output would be ",
                            window.width(),
                            "x",
                            window.height(),
                            " pixels (at most ",
                            kMaxImageSide,
                            " a side and 2^28 in all)"));
    }
}

}  // namespace posthaste::nodes
