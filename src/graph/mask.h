#pragma once
// A mask on every colour node, declared once: a node that changes colour lists kMaskPort among
// its inputs and kMaskParams' three parameters among its own and sets NodeSpec::maskable; the
// engine then blends whatever pass the node replaced with the same pass of its input,
// out = in + (node - in) * m, m the mask (a channel, or the luminance, of a pass of the frame on
// the "mask" port: a cryptomatte matte, an alpha, a luminance), clamped to [0, 1], 1 - m with
// mask_invert. Nothing is blended when the port is not connected. The same convention as
// merge's mask (mask_pass, mask_channel).

#include <cmath>
#include <string>

#include "core/frame.h"
#include "graph/node.h"
#include "graph/param_bind.h"

namespace posthaste {

inline constexpr PortSpec kMaskPort{
    "mask",
    "",
    true,
    "Optional: where the node applies (mask_pass's mask_channel; 0 keeps the input, 1 the "
    "node's result)."};
inline constexpr ParamSpec kMaskPass =
    ParamSpec::string("mask_pass", "color")
        .doc("Pass of the mask input that holds the mask (a cryptomatte node's \"matte\").");
inline constexpr ParamSpec kMaskChannel =
    ParamSpec::choice("mask_channel", "r|g|b|a|luminance", "a")
        .doc(
            "Channel of mask_pass used as the mask (luminance: Rec.709 weights of R, G, B); a "
            "one-channel pass is the mask whichever is named; a, where the file has no alpha, is "
            "the luminance (a grey pixel's value).");
inline constexpr ParamSpec kMaskInvert =
    ParamSpec::boolean("mask_invert", false).doc("Use 1 - mask: the node applies outside it.");

/// The mask's parameters, bound to their fields (graph/param_bind.h).
struct MaskSettings {
    enum class Channel { R, G, B, A, Luminance };  ///< mask_channel's choices, in order
    std::string pass = "color";
    Channel channel = Channel::A;
    bool invert = false;
};
inline constexpr Binding<MaskSettings> kMaskFields[] = {
    bind<&MaskSettings::pass>(kMaskPass),
    bind<&MaskSettings::channel>(kMaskChannel),
    bind<&MaskSettings::invert>(kMaskInvert),
};

/// A mask channel past mask_channel's five: the alpha a mask's file lacks, read as a grey
/// pixel's own value, else the luminance.
inline constexpr int kMaskGrey = 5;

/// Whether the alpha of `p` (a four-channel pass read from a file) is no channel of the file
/// but the constant the reader added, and still that constant everywhere (a node that wrote an
/// alpha into the pass kept its origin): as a mask it would apply everywhere.
bool alpha_made_by_reader(const Pass &p);

/// The mask's value at pixel `p` for `channel` (0..3, 4 the luminance, kMaskGrey), before the
/// clamp.
inline float mask_sample(const float *p, int channel)
{
    if (channel < 4) {
        return p[channel];
    }
    if (channel == kMaskGrey && p[0] == p[1] && p[1] == p[2]) {
        return p[0];
    }
    return 0.2126f * p[0] + 0.7152f * p[1] + 0.0722f * p[2];
}

/// a + (b - a) * t, exactly a at t = 0 and b at t = 1. Where a or b is infinite the weighted
/// sum instead, so +inf (the sky's depth) stays +inf under a fractional mask (inf - inf made
/// NaN); finite values keep the lerp's bits, except where b - a overflows (a = 3e38,
/// b = -3e38): there the weighted sum, which stays finite for t in [0, 1]. Scalar: the mask's
/// blend and merge's call it per value.
inline float mask_mix(float a, float b, float t)
{
    if (t == 0.0f) {
        return a;
    }
    if (t == 1.0f) {
        return b;
    }
    if (std::isfinite(a) && std::isfinite(b)) {
        const float d = b - a;
        return std::isfinite(d) ? a + d * t : a * (1.0f - t) + b * t;
    }
    return a == b ? a : (1.0f - t) * a + t * b;
}

/// Blend every pass `out` replaced with `in`'s by the mask of frame `mask` (the node's
/// parameters name its pass and channel). Passes the node added, or whose size changed, are
/// left as the node made them. Errors name `who`, the pass and the channel.
void apply_mask(const std::string &who,
                const NodeParams &params,
                const Frame &in,
                const Frame &mask,
                Frame &out);

}  // namespace posthaste
