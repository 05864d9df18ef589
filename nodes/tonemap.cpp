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

#include <algorithm>
#include <cmath>

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
            "bias of 2 the input W / 2 maps to 1). Beyond, both clip to 1.");
constexpr ParamSpec kPass = ParamSpec::string("pass", "color").doc("The pass to tone map.");
constexpr ParamSpec kParams[] = {kCurve, kMode, kWhite, kPass};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to tone map."}};

enum class Curve { Reinhard, Hable, Aces, Agx };

double hable_partial(double x)
{
    constexpr double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return (x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F) - E / F;
}

/// One value through a per-value curve (reinhard, hable, aces).
double curve_value(Curve curve, double x, double white)
{
    x = std::max(x, 0.0);
    switch (curve) {
        case Curve::Reinhard:  // inputs beyond the white point clip to 1
            return std::min(1.0, x * (1.0 + x / (white * white)) / (1.0 + x));
        case Curve::Hable:  // exposure bias 2, as Hable's; beyond white clips to 1
            return std::min(1.0, hable_partial(2.0 * x) / hable_partial(white));
        case Curve::Aces:
            return std::clamp(x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
        case Curve::Agx:
            break;
    }
    return x;
}

/// AgX-style: RGB in, display-linear RGB out.
void agx(double rgb[3])
{
    // The inset (a slight desaturation toward the primaries' mix) and the outset, Rec.709.
    constexpr double kInset[3][3] = {{0.842479062253094, 0.0784335999999992, 0.0792237451477643},
                                     {0.0423282422610123, 0.878468636469772, 0.0791661274605434},
                                     {0.0423756549057051, 0.0784336, 0.879142973793104}};
    constexpr double kOutset[3][3] = {{1.19687900512017, -0.0980208811401368, -0.0990297440797205},
                                      {-0.0528968517574562, 1.15190312990417, -0.0989611768448433},
                                      {-0.0529716355144438, -0.0980434501171241, 1.15107367264116}};
    constexpr double kMinEv = -12.47393, kMaxEv = 4.026069;
    double in[3], enc[3];
    for (int r = 0; r < 3; ++r) {
        in[r] = kInset[r][0] * rgb[0] + kInset[r][1] * rgb[1] + kInset[r][2] * rgb[2];
    }
    for (int c = 0; c < 3; ++c) {
        const double ev = std::log2(std::max(in[c], 1e-10) / 0.18);
        const double x = std::clamp((ev - kMinEv) / (kMaxEv - kMinEv), 0.0, 1.0);
        // A sixth-order polynomial fit of AgX's sigmoid, in display-encoded units.
        const double x2 = x * x, x4 = x2 * x2;
        enc[c] = 15.5 * x4 * x2 - 40.14 * x4 * x + 31.96 * x4 - 6.868 * x2 * x + 0.4298 * x2 +
                 0.1191 * x - 0.00232;
    }
    for (int r = 0; r < 3; ++r) {
        const double v = kOutset[r][0] * enc[0] + kOutset[r][1] * enc[1] + kOutset[r][2] * enc[2];
        rgb[r] = std::pow(std::clamp(v, 0.0, 1.0), 2.2);
    }
}

void execute(NodeContext &ctx)
{
    const std::string &name = ctx.get_string(kPass);
    const Pass &in = ctx.input("image").pass(name, ctx.where());
    const int nc = in.image->channels();
    if (nc < 3) {
        throw_runtime(
            ctx.where(), ": pass \"", name, "\" has ", nc, " channels; tonemap needs 3 or 4");
    }
    const Curve curve = Curve(ctx.params().get_choice(kCurve));
    const bool luminance = ctx.get_string(kMode) == "luminance";
    const double white = ctx.get_real(kWhite);
    Image out = *in.image;
    const int w = out.width();
    parallel_for(0, out.height(), [&](int y) {
        for (int x = 0; x < w; ++x) {
            float *px = out.pixel(x, y);
            if (!std::isfinite(px[0]) || !std::isfinite(px[1]) || !std::isfinite(px[2])) {
                continue;  // a point operation: the non-finite pixel stays as it is
            }
            const double alpha = nc >= 4 ? double(px[3]) : 1.0;
            const double un = alpha > 1e-6 ? 1.0 / alpha : 1.0;
            double rgb[3] = {px[0] * un, px[1] * un, px[2] * un};
            if (luminance) {
                const double lum = 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
                double mapped;
                if (curve == Curve::Agx) {
                    double grey[3] = {lum, lum, lum};
                    agx(grey);
                    mapped = grey[1];
                } else {
                    mapped = curve_value(curve, lum, white);
                }
                const double k = lum > 0.0 ? mapped / lum : 0.0;
                for (double &v : rgb) {
                    v = std::max(v, 0.0) * k;
                }
            } else if (curve == Curve::Agx) {
                agx(rgb);
            } else {
                for (double &v : rgb) {
                    v = curve_value(curve, v, white);
                }
            }
            const double pre = alpha > 1e-6 ? alpha : 1.0;
            for (int c = 0; c < 3; ++c) {
                px[c] = float(rgb[c] * pre);
            }
        }
    });
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

void plan(PlanContext &ctx)
{
    ctx.inputs[0].add(ctx.params.get_string(kPass));
}

}  // namespace

extern const NodeType kTonemap{
    {"tonemap",
     "Tone curves to display-linear: AgX-style, ACES fit, Hable filmic, extended Reinhard.",
     kInputs,
     kParams,
     ""},
    &execute,
    &plan,
    nullptr};

}  // namespace posthaste::nodes
