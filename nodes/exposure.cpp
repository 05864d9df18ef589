// nodes/exposure.cpp: scale a scene-linear pass by an exposure (src/filter/exposure.h).
// Modes: `ev` (2^exposure), `photographic` (a camera's f-number, shutter time and ISO: the scale
// 1 / (1.2 2^EV100), the header's aperture and shutter unless given), and `auto`: each frame is
// metered (a log-luminance histogram, the mean over a percentile window), the target brings the
// metered luminance to `key`, and the exposure adapts toward it over the sequence at
// rates `speed_up` / `speed_down` (per second, exponentially). The adapted value at frame n is
// defined by the frames of the sequence in [n - adaptation_frames, n] alone (started adapted at
// the first of them), so a farm chunk gives the same bits as a whole run: the node asks the
// engine for its input at those earlier frames (FrameHistory) and keeps their meterings. In
// every mode `exposure` is added (stops); alpha and the other channels pass through; a point
// operation, so non-finite values stay in their pixel (metering skips them).

#include "filter/exposure.h"

#include <cmath>
#include <future>
#include <map>
#include <mutex>

#include "graph/mask.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kMode = ParamSpec::choice("mode", "ev|photographic|auto", "ev")
                                .doc(
                                    "ev: 2^exposure; photographic: from the camera; auto: "
                                    "metered and adapted over the sequence.");
constexpr ParamSpec kExposure =
    ParamSpec::real("exposure", 0.0)
        .range(-32.0, 32.0)
        .units("stops")
        .doc("ev: the exposure; photographic and auto: a compensation added to theirs.");
constexpr ParamSpec kFstop = ParamSpec::real("fstop", 8.0)
                                 .range(0.5, 128.0)
                                 .doc("photographic: f-number.")
                                 .from_header(attr::kAperture)
                                 .only_when("mode", "photographic");
constexpr ParamSpec kShutterTime =
    ParamSpec::real("shutter_time", 1.0 / 48.0)
        .range(1e-6, 60.0)
        .units("s")
        .doc("photographic: exposure time (from the header: its shutter / fps).")
        .from_header(attr::kShutter)
        .only_when("mode", "photographic");
constexpr ParamSpec kIso = ParamSpec::real("iso", 100.0)
                               .range(1.0, 409600.0)
                               .doc("photographic: sensitivity.")
                               .only_when("mode", "photographic");
constexpr ParamSpec kFps =
    ParamSpec::real("fps", 24.0)
        .range(0.1, 1000.0)
        .units("frames/s")
        .doc("Frame rate: the shutter time from the header's shutter, and auto's adaptation time.")
        .only_when("mode", "photographic|auto");
constexpr ParamSpec kKey =
    ParamSpec::real("key", 0.18)
        .range(1e-4, 100.0)
        .doc("auto: the luminance the metered average is brought to (middle grey).")
        .only_when("mode", "auto");
constexpr ParamSpec kLowPercentile = ParamSpec::real("low_percentile", 50.0)
                                         .range(0.0, 100.0)
                                         .doc("auto: darkest share of the samples left out.")
                                         .only_when("mode", "auto");
constexpr ParamSpec kHighPercentile = ParamSpec::real("high_percentile", 95.0)
                                          .range(0.0, 100.0)
                                          .doc("auto: samples above this rank left out.")
                                          .only_when("mode", "auto");
constexpr ParamSpec kMinEv =
    ParamSpec::real("min_ev", -10.0)
        .range(-40.0, 40.0)
        .doc("auto: the histogram's darkest log2 luminance (and the target's lower clamp).")
        .only_when("mode", "auto");
constexpr ParamSpec kMaxEv = ParamSpec::real("max_ev", 20.0)
                                 .range(-40.0, 40.0)
                                 .doc("auto: the histogram's brightest log2 luminance.")
                                 .only_when("mode", "auto");
constexpr ParamSpec kSpeedUp =
    ParamSpec::real("speed_up", 3.0)
        .at_least(0.0)
        .units("1/s")
        .doc("auto: adaptation rate toward a brighter scene (0: at once).")
        .only_when("mode", "auto");
constexpr ParamSpec kSpeedDown =
    ParamSpec::real("speed_down", 1.0)
        .at_least(0.0)
        .units("1/s")
        .doc("auto: adaptation rate toward a darker scene (0: at once).")
        .only_when("mode", "auto");
constexpr ParamSpec kAdaptationFrames =
    ParamSpec::integer("adaptation_frames", 48)
        .range(0, 100000)
        .doc("auto: earlier frames the adaptation starts from (0: each frame metered alone).")
        .only_when("mode", "auto");
constexpr ParamSpec kMeteringStep = ParamSpec::integer("metering_step", 4)
                                        .range(1, 64)
                                        .doc("auto: every n-th pixel of every n-th row is metered.")
                                        .only_when("mode", "auto");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to expose.").reads_passes();
constexpr ParamSpec kParams[] = {kMode,
                                 kExposure,
                                 kFstop,
                                 kShutterTime,
                                 kIso,
                                 kFps,
                                 kKey,
                                 kLowPercentile,
                                 kHighPercentile,
                                 kMinEv,
                                 kMaxEv,
                                 kSpeedUp,
                                 kSpeedDown,
                                 kAdaptationFrames,
                                 kMeteringStep,
                                 kPass, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to expose."}, kMaskPort};

/// Earlier frames' meterings, shared by the frames in flight: a frame computes its own, and the
/// first frame to need an earlier one that is missing computes it from the engine's history
/// while the others wait for it.
struct MeterCache {
    std::unique_ptr<std::mutex> mutex = std::make_unique<std::mutex>();
    mutable std::map<int, std::shared_future<double>> meters;
};

constexpr Binding<filter::MeterParams> kMeterFields[] = {
    bind<&filter::MeterParams::min_ev>(kMinEv),
    bind<&filter::MeterParams::max_ev>(kMaxEv),
    bind<&filter::MeterParams::low_percentile>(kLowPercentile),
    bind<&filter::MeterParams::high_percentile>(kHighPercentile),
    bind<&filter::MeterParams::step>(kMeteringStep),
};
constexpr Binding<filter::PhotographicParams> kPhotographicFields[] = {
    bind<&filter::PhotographicParams::fstop>(kFstop),
    bind<&filter::PhotographicParams::iso>(kIso),
};

filter::MeterParams meter_params(const NodeParams &p)
{
    return fill(p, kMeterFields);
}

/// The EV a frame's metering asks for: the metered log2 luminance less log2(key).
double target_ev(const Image &image, const NodeParams &p)
{
    return filter::meter_log2_luminance(image, meter_params(p)) - std::log2(p.get_real(kKey));
}

double metered(NodeContext &ctx, const MeterCache &cache, int frame)
{
    std::promise<double> promise;
    std::shared_future<double> future;
    bool mine = false;
    {
        std::lock_guard lock(*cache.mutex);
        auto it = cache.meters.find(frame);
        if (it != cache.meters.end()) {
            future = it->second;
        } else {
            future = promise.get_future().share();
            cache.meters.emplace(frame, future);
            mine = true;
        }
    }
    if (mine) {
        try {
            const std::shared_ptr<const Frame> in = ctx.input_at("image", frame);
            promise.set_value(
                target_ev(in->image(ctx.get_string(kPass), ctx.where()), ctx.params()));
        } catch (...) {
            promise.set_exception(std::current_exception());
        }
    }
    return future.get();
}

double auto_ev(NodeContext &ctx, const Image &image)
{
    const MeterCache &cache = ctx.state().get_or_create<MeterCache>([] { return MeterCache{}; });
    const int n = ctx.frame_number();
    const double own = target_ev(image, ctx.params());
    {
        std::lock_guard lock(*cache.mutex);
        if (!cache.meters.count(n)) {
            std::promise<double> done;
            done.set_value(own);
            cache.meters.emplace(n, done.get_future().share());
        }
    }
    std::vector<filter::MeterSample> samples;
    for (int k : ctx.earlier_frames(ctx.get_int(kAdaptationFrames))) {
        samples.emplace_back(k, metered(ctx, cache, k));
    }
    samples.emplace_back(n, own);
    return filter::adapt_ev(
        samples, ctx.get_real(kFps), ctx.get_real(kSpeedUp), ctx.get_real(kSpeedDown));
}

/// log2 of the scale a frame gets.
double scale_stops(NodeContext &ctx, const Frame &frame, const Image &image)
{
    const double compensation = ctx.get_real(kExposure);
    const std::string &mode = ctx.get_string(kMode);
    if (mode == "ev") {
        return compensation;
    }
    if (mode == "photographic") {
        const filter::PhotographicParams lens =
            fill(ctx, kPhotographicFields, HeaderSource::of(frame));
        // The header's shutter is a fraction of the frame interval: seconds at the frame rate.
        double shutter = ctx.get_real(kShutterTime);
        if (!ctx.params().given(kShutterTime) && frame.camera.shutter &&
            *frame.camera.shutter > 0.0f && std::isfinite(*frame.camera.shutter)) {
            shutter = *frame.camera.shutter / ctx.get_real(kFps);
        }
        const double ev = filter::ev100(lens.fstop, shutter, lens.iso);
        return std::log2(filter::photographic_scale(ev)) + compensation;
    }
    return compensation - auto_ev(ctx, image);
}

void execute(NodeContext &ctx)
{
    const std::string &name = ctx.get_string(kPass);
    const Frame &frame = ctx.input("image");
    const Pass &in = rgb_pass(ctx, name, "exposure");
    const double stops = scale_stops(ctx, frame, *in.image);
    if (stops == 0.0) {
        return;  // the output shares the input pass
    }
    Image out = filter::scale_rgb(*in.image, float(std::exp2(stops)));
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

void check(CheckContext &ctx)
{
    const filter::MeterParams m = meter_params(ctx.params);
    if (m.low_percentile >= m.high_percentile) {
        throw_param_expected(
            ctx, kLowPercentile, str_cat("below high_percentile (", m.high_percentile, ")"), m.low_percentile);
    }
    if (m.min_ev >= m.max_ev) {
        throw_param_expected(ctx, kMinEv, str_cat("below max_ev (", m.max_ev, ")"), m.min_ev);
    }
}

}  // namespace

extern const NodeType kExposure{{"exposure",
                                 "Exposure: stops, a camera's f-number/shutter/ISO, or auto "
                                 "exposure adapted over the sequence.",
                                 kInputs,
                                 kParams,
                                 "", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
                                &execute,
                                nullptr,
                                &check,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(nodes::kExposure, kMeterFields, problems);
        audit(nodes::kExposure, kPhotographicFields, problems);
    },
    [](const NodeParams &params) { return params.get_string(kMode) == "auto"; }};

}  // namespace posthaste::nodes
