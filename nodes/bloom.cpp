// nodes/bloom.cpp: bloom and glare as an energy-conserving convolution of a pass with a lens's
// point-spread function (src/filter/bloom.h): the light is moved, not added, so a frame's total
// energy is kept (away from its edges, beyond which the frame is taken to continue as its edge
// pixels). `method: fft` is the exact convolution; `method: pyramid` (default) approximates the
// PSF's scattering tail with a downsample/upsample chain fitted to it, and leaves out the
// aperture's diffraction spikes. The PSF is built in (diffraction of a `blades`-bladed aperture at
// the header's f-number and the pixel pitch from its sensor width, plus a scattering tail) or read
// from an image (`psf`, fft only). Alpha and the other channels pass through. Non-finite values
// read as 0.

#include "filter/bloom.h"

#include <cmath>
#include <filesystem>
#include <mutex>

#include "core/sanitize.h"
#include "io/image_file.h"
#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kMethod =
    ParamSpec::choice("method", "pyramid|fft", "pyramid")
        .doc("pyramid: fast, the tail fitted by a mip chain; fft: the exact convolution.");
constexpr ParamSpec kIntensity =
    ParamSpec::real("intensity", 0.05)
        .range(0.0, 1.0)
        .doc("Share of the light scattered into the tail (the rest stays in the aperture's core).");
constexpr ParamSpec kSize =
    ParamSpec::real("size", 0.003)
        .range(1e-5, 1.0)
        .units("display widths")
        .doc("Tail scale r0 of (1 + (r/r0)^2)^-falloff, as a fraction of the display width.");
constexpr ParamSpec kFalloff =
    ParamSpec::real("falloff", 1.5).range(1.05, 8.0).doc("Tail exponent (larger: shorter tail).");
constexpr ParamSpec kRadius =
    ParamSpec::real("radius", 0.15)
        .range(1e-3, 1.0)
        .units("display widths")
        .doc("Where the PSF is cut off, a fraction of the display width.");
constexpr ParamSpec kBlades =
    ParamSpec::integer("blades", 6)
        .range(0, 32)
        .doc("Aperture blades of the diffraction pattern (0-2: a circular aperture).")
        .only_when("method", "fft");
constexpr ParamSpec kBladeRotation = ParamSpec::real("blade_rotation", 0.0)
                                         .range(-360.0, 360.0)
                                         .units("degrees")
                                         .doc("Rotation of the aperture polygon.")
                                         .only_when("method", "fft");
constexpr ParamSpec kFstop = ParamSpec::real("fstop", 8.0)
                                 .range(0.5, 128.0)
                                 .doc("f-number for the diffraction pattern.")
                                 .from_header(attr::kAperture)
                                 .only_when("method", "fft");
constexpr ParamSpec kDiffractionScale =
    ParamSpec::real("diffraction_scale", 0.0)
        .range(0.0, 1000.0)
        .doc(
            "fft: the aperture's diffraction pattern at 1 its physical size, larger exaggerated; "
            "0: none (the core is a point).")
        .only_when("method", "fft");
constexpr ParamSpec kLevels = ParamSpec::integer("levels", 0)
                                  .range(0, 14)
                                  .doc(
                                      "pyramid: coarse levels mixed (0: enough for the radius; "
                                      "fewer is faster, the tail shorter).")
                                  .only_when("method", "pyramid");
constexpr ParamSpec kPsf = ParamSpec::string("psf", "")
                               .file_path()
                               .doc(
                                   "An image file whose color pass is the PSF (centred; each "
                                   "channel normalised). fft only.")
                               .only_when("method", "fft");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to bloom.").reads_passes();
constexpr ParamSpec kParams[] = {kMethod,
                                 kIntensity,
                                 kSize,
                                 kFalloff,
                                 kRadius,
                                 kBlades,
                                 kBladeRotation,
                                 kFstop,
                                 kDiffractionScale,
                                 kLevels,
                                 kPsf,
                                 kPass, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to bloom."}, kMaskPort};

/// The largest PSF a `psf` image may give (a 4097 x 4097 kernel).
constexpr int kMaxPsfRadius = 2048;

struct Built {
    std::array<double, 5> key;  // display width, f-number, pixel pitch, data window size
    std::shared_ptr<const filter::FftKernel> fft;
    std::shared_ptr<const filter::PyramidFit> fit;
};

struct BloomCache {
    std::unique_ptr<std::mutex> mutex = std::make_unique<std::mutex>();
    mutable std::vector<Built> built;
};

constexpr Binding<filter::BloomPsfParams> kPsfFields[] = {
    bind<&filter::BloomPsfParams::intensity>(kIntensity),
    bind<&filter::BloomPsfParams::size>(kSize),
    bind<&filter::BloomPsfParams::falloff>(kFalloff),
    bind<&filter::BloomPsfParams::radius>(kRadius),
    bind<&filter::BloomPsfParams::blades>(kBlades),
    bind<&filter::BloomPsfParams::blade_rotation>(kBladeRotation),
    bind<&filter::BloomPsfParams::fstop>(kFstop),
    bind<&filter::BloomPsfParams::diffraction_scale>(kDiffractionScale),
};

filter::BloomPsfParams psf_params(NodeContext &ctx, const Frame &frame)
{
    filter::BloomPsfParams p = fill(ctx, kPsfFields, HeaderSource::of(frame));
    const double sensor_mm = frame.camera.sensor_width_mm && *frame.camera.sensor_width_mm > 0.0f &&
                                     std::isfinite(*frame.camera.sensor_width_mm)
                                 ? *frame.camera.sensor_width_mm
                                 : 36.0;
    p.pixel_pitch_um = sensor_mm * 1000.0 / std::max(frame.display_window.width(), 1);
    return p;
}

Built build(NodeContext &ctx, const Frame &frame)
{
    const BloomCache &cache = ctx.state().get_or_create<BloomCache>([] { return BloomCache{}; });
    const filter::BloomPsfParams p = psf_params(ctx, frame);
    const int width = std::max(frame.display_window.width(), 1);
    const std::array<double, 5> key = {
        double(width), p.fstop, p.pixel_pitch_um, double(frame.width()), double(frame.height())};
    std::lock_guard lock(*cache.mutex);
    for (const Built &b : cache.built) {
        if (b.key == key) {
            return b;
        }
    }
    Built b;
    b.key = key;
    const bool fft = ctx.get_string(kMethod) == "fft";
    const std::string &path = ctx.get_string(kPsf);
    if (!path.empty()) {
        const std::set<std::string> wanted = {"color"};
        const Frame psf_frame = read_frame(path, &wanted, ctx.frame_number());
        b.fft = std::make_shared<const filter::FftKernel>(
            filter::psf_from_image(
                psf_frame.image("color", path), kMaxPsfRadius, ctx.where() + ": param \"psf\""),
            frame.width(),
            frame.height());
    } else if (fft) {
        b.fft = std::make_shared<const filter::FftKernel>(
            filter::builtin_psf(p, width), frame.width(), frame.height());
    } else {
        b.fit = std::make_shared<const filter::PyramidFit>(
            filter::fit_pyramid(filter::tail_psf(p, width), ctx.get_int(kLevels)));
    }
    if (cache.built.size() >= 4) {
        cache.built.erase(cache.built.begin());
    }
    cache.built.push_back(b);
    return b;
}

void execute(NodeContext &ctx)
{
    const std::string &name = ctx.get_string(kPass);
    const Frame &frame = ctx.input("image");
    const Pass &in = rgb_pass(ctx, name, "bloom");
    const bool fft = ctx.get_string(kMethod) == "fft";
    if (!fft && ctx.get_real(kIntensity) == 0.0) {
        return;  // nothing scattered: the output shares the input pass
    }
    const Built b = build(ctx, frame);
    // Non-finite values read as 0 in every channel (alpha is copied, and must not carry them).
    Image storage;
    const Image &src = finite_view(*in.image, 0.0f, storage);
    Image out =
        fft ? b.fft->apply(src) : filter::bloom_pyramid(src, *b.fit, ctx.get_real(kIntensity));
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

void check(CheckContext &ctx)
{
    const std::string &path = ctx.params.get_string(kPsf);
    if (!path.empty() && !std::filesystem::exists(path)) {
        throw_param(ctx, kPsf, path + ": no such file");
    }
}

void plan(PlanContext &ctx)
{
    // The PSF's pixel pitch comes from the sensor width, which a solved camera gives.
    ctx.inputs[0].camera = true;
}

}  // namespace

extern const NodeType kBloom{
    {"bloom",
     "Bloom and glare: energy-conserving convolution with a lens PSF (pyramid or exact FFT).",
     kInputs,
     kParams,
     "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
    &execute,
    &plan,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kBloom, kPsfFields, problems);
    }};

}  // namespace posthaste::nodes
