// nodes/blur.cpp: Gaussian blur of chosen passes by a standard deviation in pixels, separable,
// through the Highway FIR kernels (filter/image_ops.h); the image continues beyond its data window
// as its edge pixels, so edges neither darken nor grow (the windows stay, as for every blur here).
// Color is blurred premultiplied, alpha with it. Non-finite values read as 0 so one bad pixel
// cannot spread over the kernel.

#include "core/sanitize.h"
#include "filter/image_ops.h"
#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kSigma = ParamSpec::real("sigma", 2.0)
                                 .range(0.0, 256.0)
                                 .units("px")
                                 .doc("Standard deviation of the Gaussian.");
constexpr ParamSpec kSigmaY = ParamSpec::real("sigma_y", 0.0)
                                  .range(0.0, 256.0)
                                  .units("px")
                                  .doc("Vertical standard deviation, when given (else sigma).");
constexpr ParamSpec kPasses =
    ParamSpec::string("passes", "color").doc("Comma-separated passes to blur.").reads_passes();
constexpr ParamSpec kParams[] = {kSigma, kSigmaY, kPasses, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to blur."}, kMaskPort};

void execute(NodeContext &ctx)
{
    const double sx = ctx.get_real(kSigma);
    const double sy = ctx.params().given(kSigmaY) ? ctx.get_real(kSigmaY) : sx;
    if (sx == 0.0 && sy == 0.0) {
        return;
    }
    const Frame &in = ctx.input("image");
    for (const std::string &name : split_list(ctx.get_string(kPasses))) {
        const Pass &p = in.pass(name, ctx.where());
        Image storage;
        const Image &src = finite_view(*p.image, 0.0f, storage);
        ctx.output().set(name,
                         std::make_shared<const Image>(filter::gaussian_blur(src, sx, sy)),
                         p.channels,
                         p.storage);
    }
}

}  // namespace

extern const NodeType kBlur{{"blur",
                             "Gaussian blur by sigma in pixels (separable, Highway FIR kernels).",
                             kInputs,
                             kParams,
                             "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
                            &execute,
                            nullptr,
                            nullptr};

}  // namespace posthaste::nodes
