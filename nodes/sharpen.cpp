// nodes/sharpen.cpp: unsharp mask, out = in + amount (in - blur(in, sigma)), where the detail
// |in - blur| exceeds `threshold` (per channel), on chosen passes; the blur is the blur node's
// (filter/image_ops.h). Color's alpha is left alone (R, G, B only). Linear light overshoots at
// strong edges: `clamp_negative` keeps color non-negative. Non-finite values read as 0.

#include <algorithm>
#include <cmath>

#include "core/sanitize.h"
#include "filter/image_ops.h"
#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kAmount =
    ParamSpec::real("amount", 0.5).range(0.0, 16.0).doc("Gain of the detail added back.");
constexpr ParamSpec kSigma = ParamSpec::real("sigma", 1.0)
                                 .range(0.1, 64.0)
                                 .units("px")
                                 .doc("Standard deviation of the blur the detail is taken from.");
constexpr ParamSpec kThreshold =
    ParamSpec::real("threshold", 0.0).range(0.0, 1e6).doc("Detail below this is left alone.");
constexpr ParamSpec kClampNegative =
    ParamSpec::boolean("clamp_negative", true).doc("Clamp sharpened color at 0.");
constexpr ParamSpec kPasses =
    ParamSpec::string("passes", "color").doc("Comma-separated passes to sharpen.").reads_passes();
constexpr ParamSpec kParams[] = {kAmount, kSigma, kThreshold, kClampNegative, kPasses, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to sharpen."}, kMaskPort};

void execute(NodeContext &ctx)
{
    const float amount = ctx.get_float(kAmount), threshold = ctx.get_float(kThreshold);
    if (amount == 0.0f) {
        return;
    }
    const Frame &in = ctx.input("image");
    for (const std::string &name : split_list(ctx.get_string(kPasses))) {
        const Pass &p = in.pass(name, ctx.where());
        Image storage;
        const Image &src = finite_view(*p.image, 0.0f, storage);
        const bool color = name.substr(0, name.find('@')) == "color";
        const int nc = src.channels(), c1 = color ? std::min(nc, 3) : nc;
        const bool clamp = color && ctx.get_bool(kClampNegative);
        const double sigma = ctx.get_real(kSigma);
        Image out = filter::gaussian_blur(src, sigma, sigma, 0, c1);
        parallel_for(0, src.height(), [&](int y) {
            const float *s = src.pixel(0, y);
            float *d = out.pixel(0, y);
            for (int i = 0; i < src.width() * nc; ++i) {
                if (i % nc >= c1) {
                    continue;  // blur copied these channels unchanged
                }
                const float detail = s[i] - d[i];
                float v = std::abs(detail) > threshold ? s[i] + amount * detail : s[i];
                d[i] = clamp ? std::max(v, 0.0f) : v;
            }
        });
        ctx.output().set(
            name, std::make_shared<const Image>(std::move(out)), p.channels, p.storage);
    }
}

}  // namespace

extern const NodeType kSharpen{
    {"sharpen",
     "Unsharp mask: detail above a threshold amplified (the blur node's Gaussian).",
     kInputs,
     kParams,
     "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
    &execute,
    nullptr,
    nullptr};

}  // namespace posthaste::nodes
