// nodes/grain.cpp: film grain (src/filter/grain.h): a deterministic, unit-variance noise field
// with a Gaussian correlation of `size` pixels, hashed from each pixel's file coordinates, the
// frame number and `seed` (so it does not crawl with the data window, changes every frame, and
// is the same on every run and thread count), applied as exposure noise in log2(value + offset)
// with `intensity` stops of standard deviation, weighted toward the midtones by `response`.
// Alpha and other channels pass through; non-finite values stay in their pixel.

#include "filter/grain.h"

#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kIntensity = ParamSpec::real("intensity", 0.15)
                                     .range(0.0, 4.0)
                                     .units("stops")
                                     .doc("Standard deviation of the grain's exposure noise.");
constexpr ParamSpec kSize = ParamSpec::real("size", 0.8)
                                .range(0.0, 16.0)
                                .units("px")
                                .doc(
                                    "Grain size: the noise's Gaussian correlation radius (sigma); "
                                    "under 0.3 the grain is per pixel.");
constexpr ParamSpec kMode = ParamSpec::choice("mode", "mono|color", "mono")
                                .doc("mono: one grain for R, G and B; color: one per channel.");
constexpr ParamSpec kResponse =
    ParamSpec::real("response", 0.6)
        .range(0.0, 1.0)
        .doc("0: the same grain at every level; 1: midtones only (shadows and highlights clean).");
constexpr ParamSpec kOffset =
    ParamSpec::real("offset", 1.0 / 256.0)
        .range(1e-6, 1.0)
        .doc("The log space's offset: black gets grain of about this size times intensity.");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 0).range(0, 2147483647).doc("Another seed, another grain.");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to grain.").reads_passes();
constexpr ParamSpec kParams[] = {kIntensity, kSize, kMode, kResponse, kOffset, kSeed, kPass, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to grain."}, kMaskPort};

constexpr Binding<filter::GrainParams> kFields[] = {
    bind<&filter::GrainParams::intensity>(kIntensity),
    bind<&filter::GrainParams::size>(kSize),
    bind<&filter::GrainParams::color>(kMode, "color"),
    bind<&filter::GrainParams::response>(kResponse),
    bind<&filter::GrainParams::offset>(kOffset),
    bind<&filter::GrainParams::seed>(kSeed),
};

void execute(NodeContext &ctx)
{
    const std::string &name = ctx.get_string(kPass);
    const Frame &frame = ctx.input("image");
    const Pass &in = rgb_pass(ctx, name, "grain");
    if (ctx.get_real(kIntensity) == 0.0) {
        return;  // the output shares the input pass
    }
    const filter::GrainParams p = fill(ctx.params(), kFields);
    Image out = filter::apply_grain(
        *in.image, frame.data_window.x0, frame.data_window.y0, ctx.frame_number(), p);
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

}  // namespace

extern const NodeType kGrain{
    {"grain",
     "Film grain: deterministic per frame and seed, sized in pixels, in a log-like space.",
     kInputs,
     kParams,
     "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
    &execute,
    nullptr,
    nullptr,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kGrain, kFields, problems);
    }};

}  // namespace posthaste::nodes
