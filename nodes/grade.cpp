// nodes/grade.cpp: a color grade of one scene-linear Rec.709 pass, as one OpenColorIO group
// (io/color.h, ColorProcessor::grade): white balance (Bradford adaptation from the light at
// `temperature`/`tint` to the light at `target_temperature`/`target_tint`) and exposure in
// stops, the ASC CDL (slope, offset, power, saturation; OCIO's CDLTransform without clamping),
// lift/gamma/gain (Nuke's Grade with black point 0 and white point 1: x * (gain - lift) + lift,
// then x^(1/gamma) with negatives passed through), then a LUT file (.cube, .spi3d, .csp, any
// format OCIO reads). A point operation: a NaN or infinite value stays in its pixel. At the
// defaults the node passes its input through untouched.

#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/text.h"
#include "graph/mask.h"
#include "nodes/color_pass.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kExposure = ParamSpec::real("exposure", 0.0)
                                    .range(-32.0, 32.0)
                                    .units("stops")
                                    .doc("Multiply by 2^exposure.");
constexpr ParamSpec kTemperature =
    ParamSpec::real("temperature", 6504.0)
        .range(1667.0, 25000.0)
        .units("K")
        .doc("White balance: the color temperature of the light the image was lit or shot under.");
constexpr ParamSpec kTint =
    ParamSpec::real("tint", 0.0)
        .range(-100.0, 100.0)
        .doc("White balance: that light's offset from the Planckian locus (Duv x 1000, + green).");
constexpr ParamSpec kTargetTemperature =
    ParamSpec::real("target_temperature", 6504.0)
        .range(1667.0, 25000.0)
        .units("K")
        .doc("White balance: the light the image is adapted to.");
constexpr ParamSpec kTargetTint =
    ParamSpec::real("target_tint", 0.0).range(-100.0, 100.0).doc("White balance: its tint.");
constexpr ParamSpec kSlope = ParamSpec::vec3("slope", 1, 1, 1).doc("ASC CDL slope per channel.");
constexpr ParamSpec kOffset = ParamSpec::vec3("offset", 0, 0, 0).doc("ASC CDL offset.");
constexpr ParamSpec kPower =
    ParamSpec::vec3("power", 1, 1, 1)
        .range(0.01, 10.0)  // 1e6 took 1.07 to NaN (float overflow, then the saturation)
        .doc("ASC CDL power (negatives pass through).");
constexpr ParamSpec kSaturation =
    ParamSpec::real("saturation", 1.0).range(0.0, 10.0).doc("ASC CDL saturation (Rec.709 luma).");
constexpr ParamSpec kLift = ParamSpec::vec3("lift", 0, 0, 0).doc("Lift: the new black.");
constexpr ParamSpec kGamma =
    ParamSpec::vec3("gamma", 1, 1, 1)
        .range(0.1, 10.0)  // 1e6 failed inside OpenColorIO, naming its reciprocal
        .doc("Gamma: x^(1/gamma) after lift and gain.");
constexpr ParamSpec kGain = ParamSpec::vec3("gain", 1, 1, 1).doc("Gain: the new white.");
constexpr ParamSpec kLut = ParamSpec::string("lut", "").file_path().doc(
    "A LUT or look file OpenColorIO reads (.cube, .spi1d, .spi3d, .csp, .cc, ...), last.");
constexpr ParamSpec kInterpolation =
    ParamSpec::choice("lut_interpolation", "best|nearest|linear|tetrahedral", "best")
        .doc("How the LUT is interpolated.");
constexpr ParamSpec kUnpremultiply =
    ParamSpec::boolean("unpremultiply", true)
        .doc("Divide color by alpha before the grade and multiply after.");
constexpr ParamSpec kPass =
    ParamSpec::string("pass", "color").doc("The pass to grade.").reads_passes();
constexpr ParamSpec kParams[] = {kExposure,
                                 kTemperature,
                                 kTint,
                                 kTargetTemperature,
                                 kTargetTint,
                                 kSlope,
                                 kOffset,
                                 kPower,
                                 kSaturation,
                                 kLift,
                                 kGamma,
                                 kGain,
                                 kLut,
                                 kInterpolation,
                                 kUnpremultiply,
                                 kPass,
                                 kMaskPass,
                                 kMaskChannel,
                                 kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to grade."}, kMaskPort};

constexpr Binding<ColorProcessor::Grade> kGradeFields[] = {
    bind<&ColorProcessor::Grade::slope>(kSlope),
    bind<&ColorProcessor::Grade::offset>(kOffset),
    bind<&ColorProcessor::Grade::power>(kPower),
    bind<&ColorProcessor::Grade::saturation>(kSaturation),
    bind<&ColorProcessor::Grade::lift>(kLift),
    bind<&ColorProcessor::Grade::gamma>(kGamma),
    bind<&ColorProcessor::Grade::gain>(kGain),
    bind<&ColorProcessor::Grade::lut>(kLut),
    bind<&ColorProcessor::Grade::interpolation>(kInterpolation),
};

/// The first number in a LUT file that float cannot hold (nan, inf, 1e39) as "line N holds
/// TOKEN, ..."; empty when there is none. OpenColorIO takes them, and they reached finite frames
/// as infinities. The LUT formats OpenColorIO reads are text: whitespace-, comma- or
/// tag-separated numbers.
std::string non_finite_entry(const std::string &path)
{
    std::ifstream in(path, std::ios::binary);
    std::string line;
    for (long n = 1; std::getline(in, line); ++n) {
        std::size_t i = line.find_first_not_of(" \t");
        if (i == std::string::npos || line[i] == '#' || line.compare(i, 5, "TITLE") == 0) {
            continue;  // a comment or a title may say "inf" in words
        }
        while (i < line.size()) {
            const auto separator = [](char c) {
                return std::isspace(static_cast<unsigned char>(c)) || c == ',' || c == '<' ||
                       c == '>' || c == '"' || c == '(' || c == ')' || c == '{' || c == '}';
            };
            while (i < line.size() && separator(line[i])) {
                ++i;
            }
            std::size_t j = i;
            while (j < line.size() && !separator(line[j])) {
                ++j;
            }
            if (j > i) {
                const std::string token = line.substr(i, j - i);
                char *end = nullptr;
                const double v = std::strtod(token.c_str(), &end);
                if (end == token.c_str() + token.size() &&
                    !(std::isfinite(v) && std::fabs(v) <= double(FLT_MAX))) {
                    return "line " + std::to_string(n) + " holds " + printable_line(token) +
                           ", a value float cannot hold (a LUT's entries must be finite)";
                }
            }
            i = j;
        }
    }
    return "";
}

ColorProcessor make_processor(const NodeParams &params, const NodeIdentity &node)
{
    const std::string where = node.json_path + "/params: " + node.describe();
    ColorProcessor::Grade g;
    const std::array<double, 9> wb = white_balance_matrix(params.get_real(kTemperature),
                                                          params.get_real(kTint),
                                                          params.get_real(kTargetTemperature),
                                                          params.get_real(kTargetTint));
    const double scale = std::exp2(params.get_real(kExposure));
    for (int i = 0; i < 9; ++i) {
        g.matrix[i] = wb[std::size_t(i)] * scale;
    }
    fill_into(g, params, std::span<const Binding<ColorProcessor::Grade>>(kGradeFields));
    for (int c = 0; c < 3; ++c) {
        if (!(g.gamma[c] > 0.0) || !(g.power[c] > 0.0)) {
            const ParamSpec &bad = !(g.gamma[c] > 0.0) ? kGamma : kPower;
            throw_param_expected(
                node.json_path + "/params/" + std::string(bad.name) + ": " + node.describe(),
                bad.name,
                "> 0 in every channel",
                str_cat("[",
                        params.get_vec(bad)[0],
                        ", ",
                        params.get_vec(bad)[1],
                        ", ",
                        params.get_vec(bad)[2],
                        "]"));
        }
    }
    if (!g.lut.empty()) {
        std::error_code ec;  // a name too long for the system is an error, not a throw
        if (!std::filesystem::is_regular_file(g.lut, ec)) {
            throw_param(
                where,
                kLut.name,
                g.lut + (ec && ec != std::errc::no_such_file_or_directory ? ": " + ec.message()
                         : std::filesystem::exists(g.lut, ec)             ? ": not a regular file"
                                                                          : ": no such file"));
        }
        if (const std::string bad = non_finite_entry(g.lut); !bad.empty()) {
            throw_param(where, kLut.name, g.lut + ": " + bad);
        }
    }
    return ColorProcessor::grade(g, where);
}

void execute(NodeContext &ctx)
{
    const ColorProcessor &proc = ctx.state().get_or_create<ColorProcessor>(
        [&] { return make_processor(ctx.params(), ctx.node()); });
    apply_to_pass(ctx, proc, ctx.get_string(kPass), ctx.get_bool(kUnpremultiply), "a grade");
}

void check(CheckContext &ctx)
{
    make_processor(ctx.params, ctx.node);
}

}  // namespace

extern const NodeType kGrade{
    {"grade",
     "Color grade: white balance, exposure, ASC CDL, lift/gamma/gain, LUT (OpenColorIO).",
     kInputs,
     kParams,
     "",
     /*sink=*/false,
     /*keeps_specular=*/false,
     /*maskable=*/true},
    &execute,
    nullptr,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) { audit(kGrade, kGradeFields, problems); }};

}  // namespace posthaste::nodes
