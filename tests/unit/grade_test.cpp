// The grade node against hand-computed values and against OpenColorIO's own transforms built
// directly here: the CDL and a LUT file to 1e-5, exposure, lift/gamma/gain, white balance
// against the Planckian locus and Bradford adaptation; the defaults pass the input through;
// non-finite values stay in their pixel; bad parameters are one-line errors.

#include <OpenColorIO/OpenColorIO.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>

#include "core/error.h"
#include "io/color.h"
#include "test_util.h"

namespace posthaste {
namespace {

namespace OCIO = OCIO_NAMESPACE;

/// A 1-row frame whose color pass holds `values` (RGB triples), alpha 1.
Frame rgb_frame(const std::vector<float> &values)
{
    const int n = int(values.size() / 3);
    Frame f;
    f.number = 1;
    f.set_size(n, 1);
    Image img(n, 1, 4);
    for (int i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c) {
            img.at(i, 0, c) = values[std::size_t(i) * 3 + std::size_t(c)];
        }
        img.at(i, 0, 3) = 1.0f;
    }
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    return f;
}

const std::vector<float> kValues = {0.0f,
                                    0.0f,
                                    0.0f,
                                    0.18f,
                                    0.18f,
                                    0.18f,
                                    1.0f,
                                    0.5f,
                                    0.25f,
                                    4.0f,
                                    12.0f,
                                    0.01f,
                                    -0.2f,
                                    0.3f,
                                    0.7f,
                                    2.5f,
                                    -1.0f,
                                    100.0f};

TEST(Grade, DefaultsPassTheInputThrough)
{
    const Frame in = rgb_frame(kValues);
    const Frame out = test::run_node("grade", in, "{}");
    EXPECT_EQ(&out.image("color"), &in.image("color"));  // the same pass, not a copy
}

TEST(Grade, CdlEqualsOpenColorIOsOwn)
{
    const Frame in = rgb_frame(kValues);
    const Frame out = test::run_node(
        "grade",
        in,
        R"({"slope": [1.2, 0.9, 1.05], "offset": [0.01, -0.02, 0.0], "power": [0.9, 1.1, 1.3],
            "saturation": 0.8})");
    auto cdl = OCIO::CDLTransform::Create();
    const double slope[3] = {1.2, 0.9, 1.05}, offset[3] = {0.01, -0.02, 0.0},
                 power[3] = {0.9, 1.1, 1.3};
    cdl->setSlope(slope);
    cdl->setOffset(offset);
    cdl->setPower(power);
    cdl->setSat(0.8);
    cdl->setStyle(OCIO::CDL_NO_CLAMP);
    auto cpu = OCIO::Config::CreateRaw()->getProcessor(cdl)->getDefaultCPUProcessor();
    for (std::size_t i = 0; i < kValues.size() / 3; ++i) {
        float rgb[3] = {kValues[i * 3], kValues[i * 3 + 1], kValues[i * 3 + 2]};
        cpu->applyRGB(rgb);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(out.image("color").at(int(i), 0, c),
                        rgb[c],
                        1e-5f * std::max(1.0f, std::fabs(rgb[c])))
                << "pixel " << i << " channel " << c;
        }
    }
}

TEST(Grade, ExposureLiftGammaGainByHand)
{
    const Frame in = rgb_frame(kValues);
    const Frame up = test::run_node("grade", in, R"({"exposure": 1})");
    const Frame down = test::run_node("grade", in, R"({"exposure": -2})");
    for (std::size_t i = 0; i < kValues.size(); ++i) {
        const int x = int(i / 3), c = int(i % 3);
        EXPECT_FLOAT_EQ(up.image("color").at(x, 0, c), kValues[i] * 2.0f);
        EXPECT_FLOAT_EQ(down.image("color").at(x, 0, c), kValues[i] * 0.25f);
    }
    // Nuke's Grade with black point 0, white point 1: ((gain - lift) x + lift)^(1 / gamma),
    // negatives passed through.
    const Frame g = test::run_node(
        "grade", in, R"({"lift": [0.05, 0, -0.02], "gamma": [2.2, 1, 0.5], "gain": [1.5, 1, 2]})");
    const double lift[3] = {0.05, 0, -0.02}, gamma[3] = {2.2, 1, 0.5}, gain[3] = {1.5, 1, 2};
    for (std::size_t i = 0; i < kValues.size(); ++i) {
        const int x = int(i / 3), c = int(i % 3);
        const double v = (gain[c] - lift[c]) * kValues[i] + lift[c];
        const double expected = v > 0.0 ? std::pow(v, 1.0 / gamma[c]) : v;
        EXPECT_NEAR(
            g.image("color").at(x, 0, c), expected, 2e-5 * std::max(1.0, std::fabs(expected)))
            << "value " << kValues[i] << " channel " << c;
    }
}

/// Linear Rec.709 of the light at `kelvin` (Y = 1), from its xy through the standard matrix.
std::array<double, 3> rec709_of_light(double kelvin)
{
    double x, y;
    planckian_xy(kelvin, 0.0, x, y);
    const double X = x / y, Y = 1.0, Z = (1.0 - x - y) / y;
    return {3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z,
            -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z,
            0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z};
}

TEST(Grade, WhiteBalanceFollowsThePlanckianLocus)
{
    // The locus fit against tabulated chromaticities: illuminant A's 2856 K (0.4476, 0.4074)
    // and 6504 K on the Planckian locus (0.3135, 0.3236).
    double x, y;
    planckian_xy(2856.0, 0.0, x, y);
    EXPECT_NEAR(x, 0.4476, 1e-3);
    EXPECT_NEAR(y, 0.4074, 1e-3);
    planckian_xy(6504.0, 0.0, x, y);
    EXPECT_NEAR(x, 0.3135, 1e-3);
    EXPECT_NEAR(y, 0.3236, 1e-3);
    // Tint moves toward green (larger y) for positive values.
    double xt, yt;
    planckian_xy(6504.0, 10.0, xt, yt);
    EXPECT_GT(yt, y);

    // A white surface under a 3200 K light, balanced for 3200 K, looks as it would under the
    // 6504 K target light (Bradford is exact for the white itself).
    const std::array<double, 3> warm = rec709_of_light(3200.0);
    const std::array<double, 3> target = rec709_of_light(6504.0);
    const Frame in =
        rgb_frame({float(warm[0]), float(warm[1]), float(warm[2]), 0.18f, 0.18f, 0.18f});
    const Frame out = test::run_node("grade", in, R"({"temperature": 3200})");
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(out.image("color").at(0, 0, c), target[std::size_t(c)], 1e-4) << c;
    }
    // The grey becomes cooler: blue up, red down.
    EXPECT_GT(out.image("color").at(1, 0, 2), 0.18f);
    EXPECT_LT(out.image("color").at(1, 0, 0), 0.18f);
    // Adapting there and back is the identity.
    const Frame back =
        test::run_node("grade", out, R"({"temperature": 6504, "target_temperature": 3200})");
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(back.image("color").at(0, 0, c), warm[std::size_t(c)], 1e-5) << c;
        EXPECT_NEAR(back.image("color").at(1, 0, c), 0.18f, 1e-5) << c;
    }
}

TEST(Grade, LutFileEqualsOpenColorIOsFileTransform)
{
    const std::string dir = test::scratch_dir("grade_lut");
    const std::string lut = dir + "/half.cube";
    {
        std::ofstream f(lut);
        f << "TITLE \"halves, then a bend\"\nLUT_1D_SIZE 3\n0 0 0\n0.2 0.25 0.3\n0.5 0.5 0.5\n";
    }
    const std::vector<float> unit = {0.0f, 0.25f, 0.5f, 0.75f, 1.0f, 0.1f, 0.9f, 0.33f, 0.66f};
    const Frame in = rgb_frame(unit);
    const Frame out = test::run_node("grade", in, R"({"lut": ")" + lut + R"("})");
    auto file = OCIO::FileTransform::Create();
    file->setSrc(lut.c_str());
    file->setInterpolation(OCIO::INTERP_BEST);
    auto cpu = OCIO::Config::CreateRaw()->getProcessor(file)->getDefaultCPUProcessor();
    for (std::size_t i = 0; i < unit.size() / 3; ++i) {
        float rgb[3] = {unit[i * 3], unit[i * 3 + 1], unit[i * 3 + 2]};
        cpu->applyRGB(rgb);
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(out.image("color").at(int(i), 0, c), rgb[c], 1e-5f) << i << " " << c;
        }
    }
    // By hand, green: 0.25 lies halfway between the knots 0 -> 0 and 0.5 -> 0.25.
    EXPECT_NEAR(out.image("color").at(0, 0, 1), 0.125f, 1e-5f);  // green 0.25 -> half of 0.25
    EXPECT_NEAR(out.image("color").at(1, 0, 1), 0.5f, 1e-5f);    // green 1.0 -> 0.5
}

TEST(Grade, NonFiniteValuesStayInTheirPixel)
{
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const Frame in =
        rgb_frame({0.2f, 0.3f, 0.4f, nan, 0.5f, 0.5f, inf, 0.1f, 0.1f, 0.6f, 0.7f, 0.8f});
    const Frame clean = rgb_frame({0.2f, 0.3f, 0.4f, 0.6f, 0.7f, 0.8f});
    const char *params = R"({"exposure": 0.5, "slope": [1.1, 1, 0.9], "saturation": 1.2})";
    const Frame out = test::run_node("grade", in, params);
    const Frame ref = test::run_node("grade", clean, params);
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(out.image("color").at(0, 0, c), ref.image("color").at(0, 0, c));
        EXPECT_EQ(out.image("color").at(3, 0, c), ref.image("color").at(1, 0, c));
    }
    EXPECT_FALSE(std::isfinite(out.image("color").at(1, 0, 0)));
}

// A LUT whose entries float cannot hold put infinities into finite frames; a folder, and a
// name too long for the system (a raw std::filesystem throw, exit 1), are the parameter's
// errors too.
TEST(Grade, LutFilesWithNonFiniteEntriesOrBadNamesAreRefused)
{
    const std::string dir = test::scratch_dir("grade_bad_lut");
    const Frame in = rgb_frame(kValues);
    const std::pair<std::string, std::string> luts[] = {
        {"inf.spi1d", "Version 1\nFrom 0 1\nLength 4\nComponents 1\n{\n0\ninf\n0.5\n1\n}\n"},
        {"nan.cube", "# a comment may say inf\nLUT_1D_SIZE 2\n0 0 0\n1 nan 1\n"},
        {"big.cube", "LUT_1D_SIZE 2\n0 0 0\n1 1 1e39\n"}};
    // The grade's error for `path`, which must name the parameter, the file and `want`.
    const auto refused = [&](const std::string &path, const std::string &want) {
        try {
            test::run_node("grade", in, R"({"lut": ")" + path + R"("})");
            ADD_FAILURE() << path << ": no error";
        } catch (const Error &e) {
            const std::string what = e.what();
            EXPECT_EQ(e.code(), ExitCode::Usage) << what;
            EXPECT_NE(what.find("param \"lut\": " + path + ": "), std::string::npos) << what;
            EXPECT_NE(what.find(want), std::string::npos) << what;
        }
    };
    const std::string wants[] = {"line 7 holds inf", "line 4 holds nan", "line 3 holds 1e39"};
    for (std::size_t i = 0; i < std::size(luts); ++i) {
        const std::string path = dir + "/" + luts[i].first;
        std::ofstream(path) << luts[i].second;
        refused(path, wants[i]);
    }
    refused(dir, "not a regular file");
    refused(dir + "/" + std::string(300, 'a') + ".cube", "too long");
}

TEST(Grade, BadParametersAreOneLineErrors)
{
    const Frame in = rgb_frame(kValues);
    for (const char *params : {R"({"lut": "/nonexistent/look.cube"})",
                               R"({"gamma": [1, 0, 1]})",
                               // 1e6 failed inside OpenColorIO naming 1e-06; a power of 1e6
                               // took 1.07 to NaN (float overflow, then the saturation).
                               R"({"gamma": [1e6, 1, 1]})",
                               R"({"power": [1, 1e6, 1]})",
                               R"({"temperature": 100})",
                               R"({"lut_interpolation": "cubic"})"}) {
        SCOPED_TRACE(params);
        try {
            test::run_node("grade", in, params);
            ADD_FAILURE() << "no error";
        } catch (const Error &e) {
            const std::string what = e.what();
            EXPECT_EQ(e.code(), ExitCode::Usage) << what;
            EXPECT_EQ(what.find('\n'), std::string::npos) << what;
            EXPECT_NE(what.find("grade"), std::string::npos) << what;
        }
    }
}

}  // namespace
}  // namespace posthaste
