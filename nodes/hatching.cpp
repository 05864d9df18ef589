// nodes/hatching.cpp: pen-and-ink hatching with tonal art maps (Praun, Hoppe, Webb, Finkelstein
// 2001, "Real-Time Hatching"). Reads color, depth, normal and position (and id with `ids`);
// writes color. Strokes are anchored to surfaces through world position and normal (face-plane
// projection by default, triplanar optionally), the TAM level comes from the pixel footprint, the
// tone from luminance (or n.l) blended over paper plus 6 tones; outlines from depth and normal
// discontinuities. mode=screen is the naive screen-space method, kept as a baseline.
// Departure from Praun et al.: no lapped-texture parametrisation (world-space planar projection
// instead) and procedural strokes instead of scanned ones. See docs/nodes/hatching.md.

#include <glm/geometric.hpp>

#include "core/text.h"
#include "graph/mask.h"
#include "nodes/node.h"
#include "shading/hatching/hatch.h"
#include "shading/hatching/tam.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kMode =
    ParamSpec::choice("mode", "surface|screen", "surface")
        .doc(
            "surface: strokes anchored to world position and normal; screen: TAM indexed by pixel "
            "(naive baseline, swims).");
constexpr ParamSpec kProjection = ParamSpec::choice("projection", "dominant|triplanar", "dominant")
                                      .doc(
                                          "dominant: the plane of N's largest axis (voxels); "
                                          "triplanar: three planes blended by |N|.")
                                      .only_when("mode", "surface");
constexpr ParamSpec kScale =
    ParamSpec::real("scale", 2.0)
        .range(1e-3, 1e4)
        .units("m")
        .doc("World size of one TAM tile.")
        .only_when("mode", "surface");
constexpr ParamSpec kTone =
    ParamSpec::choice("tone", "luminance|light", "luminance")
        .doc("Tone from the input color's luminance, or from n.l with light_dir.");
constexpr ParamSpec kLightDir = ParamSpec::vec3("light_dir", 0.4, 1.0, 0.3)
                                    .doc("World direction towards the light (tone=light).")
                                    .only_when("tone", "light");
constexpr ParamSpec kAmbient = ParamSpec::real("ambient", 0.15)
                                   .range(0.0, 1.0)
                                   .doc("Tone floor for tone=light.")
                                   .only_when("tone", "light");
constexpr ParamSpec kExposure = ParamSpec::real("exposure", 1.0)
                                    .range(0.0, 1e6)
                                    .doc("Multiplies luminance (or n.l) before the tone curve.");
constexpr ParamSpec kGamma =
    ParamSpec::real("gamma", 2.2)
        .range(0.1, 10.0)
        .doc("tone = clamp(exposure L, 0, 1)^(1/gamma); 1 is paper white.");
constexpr ParamSpec kStrokeWidth = ParamSpec::real("stroke_width", 1.5)
                                       .range(0.25, 16.0)
                                       .units("px")
                                       .doc("Stroke width in TAM texels, about pixels on screen.");
constexpr ParamSpec kStrokeLength = ParamSpec::real("stroke_length", 0.3)
                                        .range(0.02, 0.9)
                                        .doc("Stroke length as a fraction of the TAM tile.");
constexpr ParamSpec kJitter =
    ParamSpec::real("jitter", 0.3)
        .range(0.0, 1.0)
        .doc("Random spread of stroke angle (+-12 deg at 1), length and bend.");
constexpr ParamSpec kAngle = ParamSpec::real("angle_deg", 45.0)
                                 .range(-360.0, 360.0)
                                 .units("deg")
                                 .doc("Hatching direction in the TAM plane.");
constexpr ParamSpec kCrossAngle = ParamSpec::real("cross_angle_deg", -45.0)
                                      .range(-360.0, 360.0)
                                      .units("deg")
                                      .doc("Cross-hatching direction.");
constexpr ParamSpec kCrossTones =
    ParamSpec::integer("cross_tones", 2)
        .range(0, 6)
        .doc("The darkest this many of the 6 tones add cross strokes.");
constexpr ParamSpec kCandidates =
    ParamSpec::integer("candidates", 8)
        .range(1, 256)
        .doc("Random candidates per stroke (the most even one is kept).");
constexpr ParamSpec kDarkest =
    ParamSpec::real("darkest", 0.9).range(0.05, 0.98).doc("Mean ink coverage of the darkest tone.");
constexpr ParamSpec kTamSize = ParamSpec::choice("tam_size", "64|128|256|512", "256")
                                   .units("px")
                                   .doc("Finest TAM level side.");
constexpr ParamSpec kSeed =
    ParamSpec::integer("seed", 1).range(0, 2147483647).doc("Stroke placement seed.");
constexpr ParamSpec kOutlineWidth = ParamSpec::real("outline_width", 1.5)
                                        .range(0.0, 8.0)
                                        .units("px")
                                        .doc("Outline thickness; 0 turns outlines off.");
constexpr ParamSpec kDepthThreshold = ParamSpec::real("depth_threshold", 0.02)
                                          .range(0.0, 10.0)
                                          .doc(
                                              "Depth edge: a neighbour off this pixel's plane "
                                              "by more than this fraction of its depth.");
constexpr ParamSpec kNormalThreshold = ParamSpec::real("normal_threshold_deg", 50.0)
                                           .range(0.0, 180.0)
                                           .units("deg")
                                           .doc("Crease edge: normals differ by more than this.");
constexpr ParamSpec kPaper =
    ParamSpec::vec3("paper", 0.95, 0.93, 0.86).doc("Paper color (scene-linear).");
constexpr ParamSpec kInk = ParamSpec::vec3("ink", 0.04, 0.04, 0.06).doc("Hatching ink color.");
constexpr ParamSpec kOutlineColor =
    ParamSpec::vec3("outline_color", 0.02, 0.02, 0.03).doc("Outline color.");
constexpr ParamSpec kIds = ParamSpec::string("ids", "").doc(
    "Comma-separated material ids to hatch (id pass); empty: everywhere.");
constexpr ParamSpec kMix =
    ParamSpec::real("mix", 1.0).range(0.0, 1.0).doc("0: input color, 1: full drawing.");
constexpr ParamSpec kParams[] = {kMode,
                                 kProjection,
                                 kScale,
                                 kTone,
                                 kLightDir,
                                 kAmbient,
                                 kExposure,
                                 kGamma,
                                 kStrokeWidth,
                                 kStrokeLength,
                                 kJitter,
                                 kAngle,
                                 kCrossAngle,
                                 kCrossTones,
                                 kCandidates,
                                 kDarkest,
                                 kTamSize,
                                 kSeed,
                                 kOutlineWidth,
                                 kDepthThreshold,
                                 kNormalThreshold,
                                 kPaper,
                                 kInk,
                                 kOutlineColor,
                                 kIds,
                                 kMix, kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {
    {"image",
     "color,depth,normal,position",
     false,
     "Frame to draw; id is read too when `ids` is given."}, kMaskPort};

/// Parses `ids` ("1, 4,7"); returns false on a word that is not a non-negative integer.
bool parse_ids(const std::string &text, std::vector<int> &ids, std::string &bad)
{
    for (const std::string &word : split_list(text)) {
        const std::optional<int> v = parse_int(word);
        if (!v || *v < 0) {
            bad = word;
            return false;
        }
        ids.push_back(*v);
    }
    return true;
}

constexpr Binding<shading::TamParams> kTamFields[] = {
    bind<&shading::TamParams::size>(kTamSize),
    bind<&shading::TamParams::width>(kStrokeWidth),
    bind<&shading::TamParams::length>(kStrokeLength),
    bind<&shading::TamParams::jitter>(kJitter),
    bind<&shading::TamParams::angle_deg>(kAngle),
    bind<&shading::TamParams::cross_angle_deg>(kCrossAngle),
    bind<&shading::TamParams::cross_tones>(kCrossTones),
    bind<&shading::TamParams::candidates>(kCandidates),
    bind<&shading::TamParams::darkest>(kDarkest),
    bind<&shading::TamParams::seed>(kSeed),
};
constexpr Binding<shading::HatchSettings> kHatchFields[] = {
    bind<&shading::HatchSettings::screen_space>(kMode, "screen"),
    bind<&shading::HatchSettings::triplanar>(kProjection, "triplanar"),
    bind<&shading::HatchSettings::scale>(kScale),
    bind<&shading::HatchSettings::tone_from_light>(kTone, "light"),
    bind<&shading::HatchSettings::light_dir>(kLightDir),
    bind<&shading::HatchSettings::ambient>(kAmbient),
    bind<&shading::HatchSettings::exposure>(kExposure),
    bind<&shading::HatchSettings::gamma>(kGamma),
    bind<&shading::HatchSettings::outline_width>(kOutlineWidth),
    bind<&shading::HatchSettings::depth_threshold>(kDepthThreshold),
    bind<&shading::HatchSettings::normal_threshold_deg>(kNormalThreshold),
    bind<&shading::HatchSettings::paper>(kPaper),
    bind<&shading::HatchSettings::ink>(kInk),
    bind<&shading::HatchSettings::outline>(kOutlineColor),
    bind<&shading::HatchSettings::mix>(kMix),
};

shading::TamParams tam_params(const NodeParams &p)
{
    shading::TamParams t = fill(p, kTamFields);
    t.stroke_levels = t.size >= 256 ? 4 : (t.size == 128 ? 3 : 2);
    return t;
}

shading::HatchSettings settings(const NodeParams &p)
{
    shading::HatchSettings s = fill(p, kHatchFields);
    std::string bad;
    parse_ids(p.get_string(kIds), s.ids, bad);  // checked in check()
    return s;
}

void execute(NodeContext &ctx)
{
    const shading::Tam &tam = ctx.state().get_or_create<shading::Tam>(
        [&] { return shading::build_tam(tam_params(ctx.params())); });
    const shading::HatchSettings s = settings(ctx.params());
    shading::HatchInputs in;
    in.color = &ctx.input_pass("image", pass::kColor);
    in.depth = &ctx.input_pass("image", pass::kDepth);
    in.normal = &ctx.input_pass("image", pass::kNormal);
    in.position = &ctx.input_pass("image", pass::kPosition);
    if (!s.ids.empty()) {
        in.id = &ctx.input_pass("image", pass::kId);
    }
    const std::pair<const char *, const Image *> need[] = {{pass::kDepth, in.depth},
                                                           {pass::kNormal, in.normal},
                                                           {pass::kPosition, in.position},
                                                           {pass::kId, in.id}};
    const int want_channels[] = {1, 3, 3, 1};
    if (in.color->channels() < 3) {
        throw_runtime(ctx.where(),
                      ": pass \"color\" has ",
                      in.color->channels(),
                      " channels, expected 3 or 4");
    }
    for (int i = 0; i < 4; ++i) {
        const Image *img = need[i].second;
        if (img && (img->width() != in.color->width() || img->height() != in.color->height() ||
                    img->channels() < want_channels[i])) {
            throw_runtime(ctx.where(),
                          ": pass \"",
                          need[i].first,
                          "\" is ",
                          img->width(),
                          "x",
                          img->height(),
                          "x",
                          img->channels(),
                          ", expected ",
                          in.color->width(),
                          "x",
                          in.color->height(),
                          "x",
                          want_channels[i]);
        }
    }
    Image out = shading::hatch(in, s, tam);
    const Pass &cp = ctx.input("image").pass(pass::kColor, ctx.where());
    ctx.output().set(
        pass::kColor, std::make_shared<const Image>(std::move(out)), cp.channels, cp.storage);
}

void plan(PlanContext &ctx)
{
    if (!ctx.params.get_string(kIds).empty()) {
        ctx.inputs[0].add(pass::kId);
    }
}

void check(CheckContext &ctx)
{
    std::vector<int> ids;
    std::string bad;
    if (!parse_ids(ctx.params.get_string(kIds), ids, bad)) {
        throw_param_expected(ctx, kIds, "comma-separated integers >= 0", quoted(bad));
    }
    const glm::vec3 l = settings(ctx.params).light_dir;
    if (!(glm::dot(l, l) > 1e-12f)) {
        throw_param_expected(ctx, kLightDir, "a non-zero vector", "[0, 0, 0]");
    }
}

}  // namespace

extern const NodeType kHatching{{"hatching",
                                 "Pen-and-ink hatching with tonal art maps (Praun et "
                                 "al. 2001), anchored to surfaces, with outlines.",
                                 kInputs,
                                 kParams,
                                 "color", /*sink=*/false, /*keeps_specular=*/false, /*maskable=*/true},
                                &execute,
                                &plan,
                                &check,
                                nullptr,
                                [](std::vector<std::string> &problems) {
                                    audit(kHatching, kTamFields, problems);
                                    audit(kHatching, kHatchFields, problems);
                                }};

}  // namespace posthaste::nodes
