// nodes/tonemap.cpp: scene-linear to display-linear tone curves for graphs whose OCIO config has
// no view transform of its own (the bundled config's views, or an ACES config's, go through the
// `ocio` node instead). Curves: extended Reinhard (white point `white`), Hable's filmic curve
// (Uncharted 2, 2010; the shoulder, linear, toe and white constants), Narkowicz's 2015 fit of the
// ACES RRT+ODT, and an AgX-style curve (Rec.709 inset, log2 encoding of -12.47..+4.03 stops
// around middle grey, a sigmoid, the outset, a 2.2 linearisation). `mode: per_channel` maps R, G,
// B each; `luminance` maps the Rec.709 luminance and scales RGB by the ratio (hue and saturation
// kept, highlights can leave [0, 1]). Output display-linear; encode it with `ocio` or a preview.
// Alpha passes through (color unpremultiplied around the curve); a point operation: non-finite
// values stay in their pixel.

#include "filter/rgba_rows.h"
#include "filter/tonemap_kernels.h"
#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kCurve =
    ParamSpec::choice("curve", "reinhard|hable|aces|agx", "agx").doc("The tone curve.");
constexpr ParamSpec kMode = ParamSpec::choice("mode", "per_channel|luminance", "per_channel")
                                .doc("Map each channel, or the luminance with RGB scaled by it.");
constexpr ParamSpec kWhite =
    ParamSpec::real("white", 4.0)
        .range(1e-3, 1e6)
        .doc(
            "reinhard: the input that maps to 1; hable: Hable's white W (11.2 in his; with his "
            "exposure "
            "bias of 2 the input W / 2 maps to 1). Beyond, both clip to 1.")
        .only_when("curve", "reinhard|hable");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to tone map.").reads_passes();
constexpr ParamSpec kParams[] = {kCurve, kMode, kWhite, kPass, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to tone map."}, kMaskPort};

void execute(NodeContext &ctx)
{
    const std::string &name = ctx.get_string(kPass);
    const Pass &in = rgb_pass(ctx, name, "tonemap");
    const int nc = in.image->channels();
    const auto curve = filter::ToneCurve(ctx.params().get_choice(kCurve));
    const bool luminance = ctx.get_string(kMode) == "luminance";
    const float white = float(ctx.get_real(kWhite));
    const Image &src = *in.image;
    Image out = Image::uninitialized(src.width(), src.height(), nc);
    filter::for_rgba_rows(src, out, [&](int, const float *s, float *d, int n) {
        filter::tonemap_rgba_row(s, d, n, curve, luminance, white);
    });
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

}  // namespace

extern const NodeType kTonemap{
    {"tonemap",
     "Tone curves to display-linear: AgX-style, ACES fit, Hable filmic, extended Reinhard.",
     kInputs,
     kParams,
     "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
    &execute,
    nullptr,
    nullptr};

}  // namespace posthaste::nodes
