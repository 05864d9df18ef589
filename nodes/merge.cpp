// nodes/merge.cpp: combine the color of two frames (premultiplied RGBA): over, under, add,
// subtract, multiply, max, min, or mix; optionally limited by a mask channel from a third input
// and faded by `mix`. Every other pass comes from input "b" (the background).
//   over: A + B (1 - A.a)      under: B + A (1 - B.a)      add: A + B      subtract: A - B
//   multiply: A B              max/min: per channel        mix: A
//   result = B + (op(A, B) - B) * mix * mask

#include <algorithm>

#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kOperation =
    ParamSpec::choice("operation", "over|under|add|subtract|multiply|max|min|mix", "over")
        .doc("How A combines with B.");
constexpr ParamSpec kMix =
    ParamSpec::real("mix", 1.0).range(0.0, 1.0).doc("Fade between B (0) and the full result (1).");
constexpr ParamSpec kMaskPass =
    ParamSpec::string("mask_pass", "color").doc("Pass of the mask input that holds the mask.");
constexpr ParamSpec kMaskChannel =
    ParamSpec::choice("mask_channel", "r|g|b|a|luminance", "a")
        .doc(
            "Channel of mask_pass used as the mask (luminance: Rec.709 weights); a one-channel "
            "pass is the mask whichever is named.");
constexpr ParamSpec kParams[] = {kOperation, kMix, kMaskPass, kMaskChannel};
constexpr PortSpec kInputs[] = {
    {"b", "color", false, "Background; its other passes pass through."},
    {"a", "color", false, "Foreground."},
    {"mask", "", true, "Optional mask frame."},
};

enum Op { Over, Under, Add, Subtract, Multiply, Max, Min, Mix };

inline float combine(Op op, float a, float b, float a_alpha, float b_alpha)
{
    switch (op) {
        case Over:
            return a + b * (1.0f - a_alpha);
        case Under:
            return b + a * (1.0f - b_alpha);
        case Add:
            return a + b;
        case Subtract:
            return a - b;
        case Multiply:
            return a * b;
        case Max:
            return std::max(a, b);
        case Min:
            return std::min(a, b);
        case Mix:
            return a;
    }
    return b;
}

void execute(NodeContext &ctx)
{
    // The result covers B's data window (Nuke's "bbox: B"): A and the mask are placed into it,
    // transparent (zero) where their own data windows do not reach.
    const Frame &fb = ctx.input("b");
    const Image &b = ctx.input_pass("b", pass::kColor);
    Image a_placed, mask_placed;
    const Image *a_ptr = &ctx.input_pass("a", pass::kColor);
    if (const Frame &fa = ctx.input("a"); fa.data_window != fb.data_window) {
        a_placed = place_in_window(*a_ptr, fa.data_window, fb.data_window);
        a_ptr = &a_placed;
    }
    const Image &a = *a_ptr;
    const Image *mask = nullptr;
    if (ctx.has_input("mask")) {
        mask = &ctx.input_pass("mask", ctx.get_string(kMaskPass));
        if (const Frame &fm = ctx.input("mask"); fm.data_window != fb.data_window) {
            mask_placed = place_in_window(*mask, fm.data_window, fb.data_window);
            mask = &mask_placed;
        }
    }
    const Op op = Op(ctx.get_choice(kOperation));
    const float mix = ctx.get_float(kMix);
    // A one-channel pass (a cryptomatte matte) is the mask whichever channel is named, as on
    // every masked node (mask_channel's default, a, refused it here).
    int mask_channel = mask && mask->channels() == 1 ? 0 : ctx.get_choice(kMaskChannel);
    // The reader's alpha of a file without one (a matte written as Y alone) is no mask: as on
    // every masked node, the luminance instead (graph/mask.h).
    if (mask && mask_channel == 3 &&
        alpha_made_by_reader(ctx.input("mask").pass(ctx.get_string(kMaskPass)))) {
        mask_channel = kMaskGrey;
    }
    if (mask && mask_channel < 4 && mask_channel >= mask->channels()) {
        throw_runtime(ctx.where(),
                      ": mask pass \"",
                      ctx.get_string(kMaskPass),
                      "\" has ",
                      mask->channels(),
                      " channels, no channel ",
                      "rgba"[mask_channel]);
    }
    if (mask && mask_channel >= 4 && mask->channels() < 3) {
        throw_runtime(ctx.where(),
                      ": mask luminance needs 3 channels in pass \"",
                      ctx.get_string(kMaskPass),
                      "\"");
    }
    const int nb = b.channels(), na = a.channels();
    Image out = Image::uninitialized(b.width(), b.height(), nb);
    parallel_for_tiles(out.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float *pb = b.pixel(x, y);
                const float *pa = a.pixel(x, y);
                float *po = out.pixel(x, y);
                float m = mix;
                if (mask) {
                    const float *pm = mask->pixel(x, y);
                    const float mv = mask_sample(pm, mask_channel);
                    // As every masked node: NaN is 0, the rest within [0, 1] (a NaN mask made
                    // its pixel's colour NaN).
                    m *= std::isnan(mv) ? 0.0f : std::clamp(mv, 0.0f, 1.0f);
                }
                const float a_alpha = na >= 4 ? pa[3] : 1.0f;
                const float b_alpha = nb >= 4 ? pb[3] : 1.0f;
                for (int c = 0; c < nb; ++c) {
                    const float av = c < na ? pa[c] : (c == 3 ? 1.0f : 0.0f);
                    const float r = combine(op, av, pb[c], a_alpha, b_alpha);
                    po[c] = mask_mix(pb[c], r, m);
                }
            }
        }
    });
    const Pass &bp = ctx.input("b").pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), bp.channels, bp.storage);
}

void plan(PlanContext &ctx)
{
    if (ctx.connected[2]) {
        ctx.inputs[2].add(ctx.params.get_string(kMaskPass));
    }
}

}  // namespace

extern const NodeType kMerge{
    {"merge", "Combine two frames' color: over, add, multiply, mix...", kInputs, kParams, "color"},
    &execute,
    &plan};

}  // namespace posthaste::nodes
