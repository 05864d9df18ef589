// nodes/render.cpp: the bundled rasterizer as a source: renders a Minecrappy scene's frames
// with exactly the passes nodes downstream read (src/raster/render.h), or, with `truth`, the
// ground-truth color by accumulation over the shutter and/or the lens aperture.

#include "raster/render.h"

#include "core/memory.h"
#include "io/cryptomatte.h"
#include "nodes/node.h"
#include "raster/ray_cast.h"
#include "raster/scene.h"
#include "shading/atmosphere/sky.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kScene = ParamSpec::string("scene", "samples/scenes/minecrappy.json")
                                 .file_path()
                                 .doc("Scene file (JSON, samples/scenes/README.md).");
constexpr ParamSpec kWidth =
    ParamSpec::integer("width", 1920).range(1, 16384).units("px").doc("Image width.");
constexpr ParamSpec kHeight =
    ParamSpec::integer("height", 1080).range(1, 16384).units("px").doc("Image height.");
constexpr ParamSpec kSupersample =
    ParamSpec::integer("supersample", 1)
        .range(1, 4)
        .doc("Beauty supersampling per axis: 1, 2 or 4 (data passes stay one sample per pixel).");
constexpr ParamSpec kShadows = ParamSpec::boolean("shadows", true).doc("Sun shadow map.");
constexpr ParamSpec kTruth =
    ParamSpec::choice("truth", "none|motion|dof|motion_dof|ao|reflections|gi", "none")
        .doc(
            "Replace color by ground truth accumulated over the shutter, the aperture, or both; "
            "ao: add pass \"ao\", ambient occlusion by exact ray casting; reflections: color "
            "with exactly traced glossy reflections (samples: GGX rays a pixel; supersample 1); "
            "gi: "
            "color plus one bounce of diffuse light, exactly traced (samples: cosine-weighted "
            "rays a pixel; each hit lit by the sun with an exact shadow ray and the sky).");
constexpr ParamSpec kSamples = ParamSpec::integer("samples", 64)
                                   .range(1, 65536)
                                   .doc(
                                       "Renders accumulated for the ground truth (rays a texel "
                                       "for the latlong probe).");
constexpr ParamSpec kSeed = ParamSpec::integer("seed", 0)
                                .range(0, 2147483647)
                                .doc("Jitter seed for the ground truth and the latlong probe.");
constexpr ParamSpec kAoRadius =
    ParamSpec::real("ao_radius", 1.0)
        .range(1e-3, 100.0)
        .units("m")
        .doc("truth ao: occluders farther than this from the surface point do not count.")
        .only_when("truth", "ao");
constexpr ParamSpec kCryptomatteRanks =
    ParamSpec::integer("cryptomatte_ranks", 6)
        .range(1, 16)
        .doc(
            "Ranks of CryptoObject and CryptoMaterial, made when a node asks for them (a "
            "cryptomatte node, or a write of their rank layers): two a layer, coverage from the "
            "beauty's samples (supersample).");
constexpr ParamSpec kProjection =
    ParamSpec::choice("projection", "perspective|latlong", "perspective")
        .doc(
            "latlong: a reflection probe, the radiance seen from the camera's position in every "
            "direction, exactly traced (samples: rays a texel), as a latitude-longitude map "
            "(width x height, +y up, the top row straight up, the middle column looking down "
            "-z) with color and depth (distance, +inf for the sky); header "
            "posthaste:probePosition. For ssr's environment input.");
constexpr ParamSpec kOverscan =
    ParamSpec::real("overscan", 0.0)
        .range(0.0, 4096.0)
        .doc(
            "Render beyond the frame: below 1, a fraction each dimension grows by (0.1: a "
            "1920x1080 frame gets 96 px left and right, 54 px top and bottom, as Unreal's "
            "overscan percentage); from 1, whole pixels on every side. The data window grows, "
            "the display window and the camera stay width x height's; every pass and truth "
            "covers the data window.");
constexpr ParamSpec kParams[] = {kScene,
                                 kWidth,
                                 kHeight,
                                 kOverscan,
                                 kSupersample,
                                 kShadows,
                                 kTruth,
                                 kSamples,
                                 kSeed,
                                 kAoRadius,
                                 kProjection,
                                 kCryptomatteRanks};
constexpr int kTruthAo = 4;
constexpr int kTruthReflections = 5;
constexpr int kTruthGi = 6;
constexpr int kProjectionLatLong = 1;

constexpr Binding<raster::RenderOptions> kRenderFields[] = {
    bind<&raster::RenderOptions::cryptomatte_ranks>(kCryptomatteRanks),
    bind<&raster::RenderOptions::width>(kWidth),
    bind<&raster::RenderOptions::height>(kHeight),
    bind<&raster::RenderOptions::supersample>(kSupersample),
    bind<&raster::RenderOptions::shadows>(kShadows),
};
constexpr Binding<raster::TruthOptions> kTruthFields[] = {
    bind<&raster::TruthOptions::samples>(kSamples),
    bind<&raster::TruthOptions::seed>(kSeed),
};

/// Overscan pixels a side (x, y) for `overscan` around a width x height frame; an error for a
/// pixel count that is not whole.
std::pair<int, int> overscan_pixels(const NodeParams &params, const std::string &where)
{
    const double v = params.get_real(kOverscan);
    if (v < 1.0) {
        return {int(std::lround(v * 0.5 * params.get_int(kWidth))),
                int(std::lround(v * 0.5 * params.get_int(kHeight)))};
    }
    if (v != std::floor(v)) {
        throw_param_expected(where, kOverscan.name, "a fraction below 1 or whole pixels a side", v);
    }
    return {int(v), int(v)};
}

raster::RenderOptions render_options(const NodeParams &params,
                                     const PassSet &requested,
                                     const std::string &where)
{
    raster::RenderOptions o = fill(params, kRenderFields);
    std::tie(o.overscan_x, o.overscan_y) = overscan_pixels(params, where);
    o.passes.clear();
    for (const std::string &p : raster::render_pass_names()) {
        if (requested.wants(p)) {
            o.passes.insert(p);
        }
    }
    // A cryptomatte asked for by a rank layer's name or by a "cryptomatte:<type>" request (every
    // one for an empty type): all its rank layers.
    for (const char *type : {raster::kCryptoObject, raster::kCryptoMaterial}) {
        bool wanted = false;
        for (const std::string &r : requested.optional) {
            std::string t;
            wanted = wanted || (cryptomatte::parse_request(r, t) && (t.empty() || t == type));
        }
        for (int k = 0; k < 8; ++k) {
            wanted = wanted || requested.wants(raster::crypto_layer(type, k));
        }
        for (int k = 0; wanted && k < (o.cryptomatte_ranks + 1) / 2; ++k) {
            o.passes.insert(raster::crypto_layer(type, k));
        }
    }
    return o;
}

const raster::Scene &scene_of(NodeContext &ctx)
{
    return ctx.state().get_or_create<raster::Scene>(
        [&] { return raster::load_scene(ctx.get_string(kScene)); });
}

/// The scene's sun in the header, for nodes downstream (fog, relight) to default to.
void add_sun_attributes(const raster::Scene &scene, Frame &frame)
{
    const glm::vec3 d = scene.sun.direction;
    // The sky is computed for this illuminance (shading/atmosphere/sky.h): the fog node's
    // atmosphere, which defaults to it, then draws the same sky.
    const glm::vec3 e(shading::kSkyIlluminance);
    frame.attributes.push_back(OIIO::ParamValue("posthaste:sunDirection", OIIO::TypeVector, 1, &d));
    frame.attributes.push_back(
        OIIO::ParamValue("posthaste:sunIlluminance", OIIO::TypeVector, 1, &e));
    // The scale of the sky light in the beauty (the ssr node's sky fallback defaults to it).
    frame.attributes.push_back(OIIO::ParamValue("posthaste:skyAmbient", scene.sky_ambient));
    // The scene's sun as it lights the beauty (colour times illuminance): the ssr node shades
    // its hits' sun response for the reflected rays with it.
    const glm::vec3 sun = scene.sun.color * scene.sun.illuminance;
    frame.attributes.push_back(
        OIIO::ParamValue("posthaste:sunIrradiance", OIIO::TypeVector, 1, &sun));
}

void execute(NodeContext &ctx)
{
    const raster::Scene &scene = scene_of(ctx);
    struct SunOnExit {
        const raster::Scene &scene;
        NodeContext &ctx;
        ~SunOnExit() { add_sun_attributes(scene, ctx.output()); }
    } sun_on_exit{scene, ctx};
    raster::RenderOptions options = render_options(ctx.params(), ctx.requested(), ctx.where());
    const int truth = ctx.get_choice(kTruth);
    try {
        if (ctx.get_choice(kProjection) == kProjectionLatLong) {
            raster::EnvironmentProbe probe =
                raster::render_environment_probe(scene,
                                                 ctx.frame_number(),
                                                 options.width,
                                                 options.height,
                                                 ctx.get_int(kSamples),
                                                 std::uint32_t(ctx.get_int(kSeed)));
            Frame &f = ctx.output();
            f.set_size(options.width, options.height);
            if (ctx.requested().wants(pass::kColor)) {
                f.set(pass::kColor, std::move(probe.color));
            }
            if (ctx.requested().wants(pass::kDepth)) {
                f.set(pass::kDepth, std::move(probe.distance));
            }
            f.attributes.push_back(
                OIIO::ParamValue("posthaste:probePosition", OIIO::TypeVector, 1, &probe.position));
            return;
        }
        if (truth == kTruthAo) {
            // The requested passes as usual, plus the exact ambient occlusion (rays per pixel:
            // `samples`).
            Frame f = raster::render_frame(scene, ctx.frame_number(), options);
            if (ctx.requested().contains(pass::kAo)) {
                f.set(pass::kAo,
                      std::make_shared<const Image>(
                          raster::render_ao_truth(scene,
                                                  ctx.frame_number(),
                                                  options,
                                                  float(ctx.get_real(kAoRadius)),
                                                  ctx.get_int(kSamples),
                                                  std::uint32_t(ctx.get_int(kSeed)))),
                      {"Y"});
            }
            ctx.output() = std::move(f);
            return;
        }
        if (truth == kTruthReflections) {
            // The requested passes (one sample a pixel, as the truth), color replaced.
            options.supersample = 1;
            Frame f = raster::render_frame(scene, ctx.frame_number(), options);
            if (ctx.requested().contains(pass::kColor)) {
                f.set(pass::kColor,
                      std::make_shared<const Image>(
                          raster::render_reflection_truth(scene,
                                                          ctx.frame_number(),
                                                          options,
                                                          ctx.get_int(kSamples),
                                                          std::uint32_t(ctx.get_int(kSeed)))));
            }
            ctx.output() = std::move(f);
            return;
        }
        if (truth == kTruthGi) {
            // The requested passes as usual, color replaced by beauty plus one bounce.
            Frame f = raster::render_frame(scene, ctx.frame_number(), options);
            if (ctx.requested().contains(pass::kColor)) {
                f.set(pass::kColor,
                      std::make_shared<const Image>(
                          raster::render_gi_truth(scene,
                                                  ctx.frame_number(),
                                                  options,
                                                  ctx.get_int(kSamples),
                                                  std::uint32_t(ctx.get_int(kSeed)))
                              .color));
            }
            ctx.output() = std::move(f);
            return;
        }
        if (truth == 0) {
            ctx.output() = raster::render_frame(scene, ctx.frame_number(), options);
            return;
        }
        raster::TruthOptions t = fill(ctx.params(), kTruthFields);
        t.motion = truth == 1 || truth == 3;
        t.dof = truth == 2 || truth == 3;
        Frame truth_frame = raster::render_truth(scene, ctx.frame_number(), options, t);
        options.passes.erase(pass::kColor);
        if (!options.passes.empty()) {
            Frame f = raster::render_frame(scene, ctx.frame_number(), options);
            f.set(pass::kColor, truth_frame.pass(pass::kColor).image);
            truth_frame = std::move(f);
        }
        ctx.output() = std::move(truth_frame);
    } catch (const Error &e) {
        rethrow_with_prefix(e, ctx.where() + ": ");
    }
}

void check(CheckContext &ctx)
{
    const std::string where = ctx.node.json_path + "/params: " + ctx.node.describe();
    if (ctx.params.get_choice(kProjection) == kProjectionLatLong) {
        if (ctx.params.get_choice(kTruth) != 0) {
            throw_param(ctx, kProjection, "latlong makes no ground truth (truth none)");
        }
        if (ctx.params.get_real(kOverscan) != 0.0) {
            throw_param(ctx, kOverscan, "a latlong probe has no frame to overscan (give 0)");
        }
        if (!ctx.downstream.all) {
            for (const std::string &p : ctx.downstream.names) {
                if (p != pass::kColor && p != pass::kDepth) {
                    throw_usage(where,
                                ": a latlong probe makes color and depth only, not pass \"",
                                p,
                                "\"; a node downstream reads it");
                }
            }
        }
    } else if (!ctx.downstream.all) {
        for (const std::string &p : ctx.downstream.names) {
            if (p == pass::kAo && ctx.params.get_choice(kTruth) == kTruthAo) {
                continue;
            }
            if (!raster::render_pass_names().count(p)) {
                std::string have;
                for (const std::string &n : raster::render_pass_names()) {
                    have += (have.empty() ? "" : ", ") + n;
                }
                throw_usage(where,
                            ": the renderer makes no pass \"",
                            p,
                            "\" (it makes: ",
                            have,
                            "); a node downstream reads it");
            }
        }
    }
    const int ss = ctx.params.get_int(kSupersample);
    if (ss == 3) {
        throw_param_expected(ctx, kSupersample, "1, 2 or 4", ss);
    }
    const auto [ox, oy] = overscan_pixels(ctx.params, where);
    const int wide_w = ctx.params.get_int(kWidth) + 2 * ox,
              wide_h = ctx.params.get_int(kHeight) + 2 * oy;
    if (wide_w > kMaxImageSide / 4 || wide_h > kMaxImageSide / 4) {
        throw_param(ctx,
                    kOverscan,
                    str_cat("makes a ",
                            wide_w,
                            "x",
                            wide_h,
                            " frame, over ",
                            kMaxImageSide / 4,
                            " pixels a side"));
    }
    // What a frame will allocate, before any is: the requested passes plus the rasterizer's
    // own buffers (G-buffer, depth, ids, about 16 floats a pixel), at the supersampled size.
    if (const std::size_t budget = image_memory_budget(); budget != 0) {
        std::size_t channels = 16;
        std::set<std::string> wanted = raster::render_pass_names();
        if (!ctx.downstream.all) {
            wanted = ctx.downstream.names;
            for (const std::string &p : ctx.downstream.optional) {
                if (raster::render_pass_names().count(p)) {
                    wanted.insert(p);
                }
            }
        }
        for (const std::string &p : wanted) {
            const pass::CanonicalPass *cp = pass::find_canonical(p);
            channels += cp ? cp->channels.size() : 4;
        }
        const std::size_t pixels = std::size_t(wide_w) * std::size_t(wide_h) * std::size_t(ss * ss);
        const std::size_t estimate = pixels * channels * sizeof(float);
        if (estimate > budget) {
            throw_runtime(where,
                          ": a ",
                          wide_w,
                          "x",
                          wide_h,
                          " frame (supersample ",
                          ss,
                          ") needs about ",
                          format_bytes(estimate),
                          ", over --max-memory ",
                          format_bytes(budget));
        }
    }
    try {
        raster::load_scene(ctx.params.get_string(kScene));
    } catch (const Error &e) {
        throw Error(ExitCode::Usage, where + ": " + e.what());
    }
}

std::vector<int> discover(const NodeParams &params)
{
    const raster::Scene scene = raster::load_scene(params.get_string(kScene));
    std::vector<int> frames;
    for (int f = scene.frame_start; f <= scene.frame_end; ++f) {
        frames.push_back(f);
    }
    return frames;
}

}  // namespace

extern const NodeType kRender{{"render",
                               "Render a Minecrappy scene (bundled rasterizer), or its "
                               "ground truth.",
                               {},
                               kParams,
                               "*"},
                              &execute,
                              nullptr,
                              &check,
                              &discover,
                              [](std::vector<std::string> &problems) {
                                  audit(kRender, kRenderFields, problems);
                                  audit(kRender, kTruthFields, problems);
                              }};

}  // namespace posthaste::nodes
