// nodes/ocio.cpp: an OpenColorIO transform of one pass (color by default): from one color space
// to another, or to a display and view. Premultiplied color is unpremultiplied around the
// transform. Config: $OCIO, else samples/ocio/config.ocio (built in). Linear 0.18 -> sRGB 0.461356.

#include "graph/mask.h"
#include "nodes/color_pass.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kMode =
    ParamSpec::choice("mode", "colorspace|display", "colorspace")
        .doc("Convert between color spaces, or apply a display + view transform.");
constexpr ParamSpec kFrom = ParamSpec::string("from", "lin_rec709").doc("Input color space.");
constexpr ParamSpec kTo = ParamSpec::string("to", "srgb")
                              .doc("Output color space (colorspace mode).")
                              .only_when("mode", "colorspace");
constexpr ParamSpec kDisplay = ParamSpec::string("display", "sRGB")
                                   .doc("Display (display mode).")
                                   .only_when("mode", "display");
constexpr ParamSpec kView =
    ParamSpec::string("view", "Standard").doc("View (display mode).").only_when("mode", "display");
constexpr ParamSpec kUnpremultiply =
    ParamSpec::boolean("unpremultiply", true)
        .doc("Divide color by alpha before the transform and multiply after.");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to transform.").reads_passes();
constexpr ParamSpec kParams[] = {kMode,
                                 kFrom,
                                 kTo,
                                 kDisplay,
                                 kView,
                                 kUnpremultiply,
                                 kPass,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to transform."}, kMaskPort};

ColorProcessor make_processor(const NodeParams &params, const NodeIdentity &node)
{
    const std::string where = node.json_path + "/params: " + node.describe();
    if (params.get_choice(kMode) == 0) {
        return ColorProcessor::between(params.get_string(kFrom),
                                       params.get_string(kTo),
                                       where,
                                       std::string(kFrom.name),
                                       std::string(kTo.name));
    }
    return ColorProcessor::display_view(params.get_string(kFrom),
                                        params.get_string(kDisplay),
                                        params.get_string(kView),
                                        where,
                                        false,
                                        std::string(kFrom.name));
}

void execute(NodeContext &ctx)
{
    const ColorProcessor &proc = ctx.state().get_or_create<ColorProcessor>(
        [&] { return make_processor(ctx.params(), ctx.node()); });
    apply_to_pass(
        ctx, proc, ctx.get_string(kPass), ctx.get_bool(kUnpremultiply), "a color transform");
}

void check(CheckContext &ctx)
{
    make_processor(ctx.params, ctx.node);
}

}  // namespace

extern const NodeType kOcio{{"ocio",
                             "OpenColorIO color space or display transform.",
                             kInputs,
                             kParams,
                             "",
                             /*sink=*/false,
                             /*keeps_specular=*/false,
                             /*maskable=*/true},
                            &execute,
                            nullptr,
                            &check};

}  // namespace posthaste::nodes
