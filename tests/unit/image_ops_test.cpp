// The everyday image operations: blur against a direct 2-D sum and its moments, sharpen against
// its formula, reformat's windows, filters, nearest passes and motion scaling, transform's exact
// shifts and quarter turns (values and motion vectors), crop's windows and values, and for the
// three geometric nodes that the camera still projects a world point onto the pixel showing it.

#include "filter/image_ops.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "graph/graph.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame single_pass_frame(const Image &img, const std::string &name = "color")
{
    Frame f;
    f.set_size(img.width(), img.height());
    f.set(name, img);
    return f;
}

/// The image's value at absolute coordinates of `frame`'s data window.
float at_abs(const Frame &f, const std::string &pass, int x, int y, int c)
{
    return f.image(pass).at(x - f.data_window.x0, y - f.data_window.y0, c);
}

TEST(ImageOps, GaussianBlurEqualsTheDirectSumWithEdgesExtended)
{
    Image img(23, 17, 2);
    for (int y = 0; y < 17; ++y) {
        for (int x = 0; x < 23; ++x) {
            img.at(x, y, 0) = float(std::sin(0.7 * x) + std::cos(1.3 * y) + 0.05 * x * y);
            img.at(x, y, 1) = (x * 7 + y * 3) % 5 == 0 ? 4.0f : 0.0f;
        }
    }
    const double sx = 1.7, sy = 0.9;
    const Image out = filter::gaussian_blur(img, sx, sy);
    const std::vector<float> kx = filter::gaussian_kernel(sx), ky = filter::gaussian_kernel(sy);
    const int rx = int(kx.size() / 2), ry = int(ky.size() / 2);
    double worst = 0.0;
    for (int y = 0; y < 17; ++y) {
        for (int x = 0; x < 23; ++x) {
            for (int c = 0; c < 2; ++c) {
                double sum = 0.0;
                for (int j = -ry; j <= ry; ++j) {
                    for (int i = -rx; i <= rx; ++i) {
                        sum += double(kx[std::size_t(i + rx)]) * ky[std::size_t(j + ry)] *
                               img.load_clamped(x + i, y + j, c);
                    }
                }
                worst = std::max(worst, std::abs(sum - out.at(x, y, c)));
            }
        }
    }
    EXPECT_LT(worst, 1e-5);
}

TEST(ImageOps, GaussianKernelHasUnitSumAndTheAskedVariance)
{
    for (double sigma : {1.0, 2.5, 8.0}) {
        const std::vector<float> k = filter::gaussian_kernel(sigma);
        const int r = int(k.size() / 2);
        double sum = 0.0, var = 0.0;
        for (int i = -r; i <= r; ++i) {
            sum += k[std::size_t(i + r)];
            var += double(i) * i * k[std::size_t(i + r)];
        }
        EXPECT_NEAR(sum, 1.0, 1e-6);
        EXPECT_NEAR(std::sqrt(var), sigma, 0.01 * sigma);
    }
    EXPECT_EQ(filter::gaussian_kernel(0.0), std::vector<float>{1.0f});
}

TEST(ImageOps, BlurNodeKeepsAConstantAndEnergyAndSkipsOtherPasses)
{
    Frame f = test::make_sample_frame(40, 30, 1);
    Image flat(40, 30, 4);
    flat.fill(0.25f);
    f.set("color", flat);
    const Frame out = test::run_node("blur", f, R"({"sigma": 5})");
    for (int y = 0; y < 30; ++y) {
        for (int x = 0; x < 40; ++x) {
            ASSERT_NEAR(out.image("color").at(x, y, 0), 0.25f, 1e-6f);
        }
    }
    EXPECT_EQ(out.pass("depth").image, f.pass("depth").image);  // shared, not blurred
    // An impulse far from the edges keeps its energy.
    Image dot(64, 64, 4);
    dot.at(32, 32, 0) = 1.0f;
    dot.at(32, 32, 3) = 1.0f;
    const Frame blurred = test::run_node("blur", single_pass_frame(dot), R"({"sigma": 3})");
    double sum = 0.0;
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
            sum += blurred.image("color").at(x, y, 0);
        }
    }
    EXPECT_NEAR(sum, 1.0, 1e-5);
    EXPECT_THROW(test::run_node("blur", f, R"({"passes": "nope"})"), Error);
}

TEST(ImageOps, SharpenIsTheUnsharpMaskFormula)
{
    Image img(32, 8, 4);
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 32; ++x) {
            const float v = x < 16 ? 0.2f : 0.8f;
            img.at(x, y, 0) = img.at(x, y, 1) = img.at(x, y, 2) = v;
            img.at(x, y, 3) = 0.5f;
        }
    }
    const Frame out = test::run_node("sharpen",
                                     single_pass_frame(img),
                                     R"({"amount": 2, "sigma": 1.5, "clamp_negative": false})");
    const Image blur = filter::gaussian_blur(img, 1.5, 1.5);
    for (int x = 0; x < 32; ++x) {
        const float expect = img.at(x, 4, 0) + 2.0f * (img.at(x, 4, 0) - blur.at(x, 4, 0));
        EXPECT_NEAR(out.image("color").at(x, 4, 0), expect, 1e-6f) << x;
        EXPECT_EQ(out.image("color").at(x, 4, 3), 0.5f);  // alpha untouched
    }
    EXPECT_LT(out.image("color").at(15, 4, 0), 0.2f);          // undershoot before the edge
    EXPECT_GT(out.image("color").at(16, 4, 0), 0.8f);          // overshoot after it
    EXPECT_NEAR(out.image("color").at(2, 4, 0), 0.2f, 1e-6f);  // flat: unchanged
    // A threshold above the step's detail leaves the image alone.
    const Frame none =
        test::run_node("sharpen", single_pass_frame(img), R"({"amount": 2, "threshold": 1})");
    EXPECT_TRUE(none.image("color").bit_equal(img));
}

/// Projects a few world points through the frame's camera: pixel positions (absolute).
std::vector<glm::dvec2> project(const Frame &f)
{
    std::vector<glm::dvec2> out;
    for (const glm::vec3 p :
         {glm::vec3(0.0f, 1.5f, 0.0f), glm::vec3(0.8f, 1.0f, 1.0f), glm::vec3(-1.2f, 2.1f, 3.0f)}) {
        glm::vec2 px;
        EXPECT_TRUE(world_to_pixel(
            *f.camera.world_to_ndc, p, f.display_window.width(), f.display_window.height(), px));
        out.emplace_back(px.x + f.display_window.x0, px.y + f.display_window.y0);
    }
    return out;
}

void expect_camera_follows(const Frame &in, const Frame &out, const filter::Affine &m)
{
    const std::vector<glm::dvec2> a = project(in), b = project(out);
    for (std::size_t i = 0; i < a.size(); ++i) {
        const glm::dvec3 moved = m * glm::dvec3(a[i], 1.0);
        EXPECT_NEAR(b[i].x, moved.x, 2e-3) << i;
        EXPECT_NEAR(b[i].y, moved.y, 2e-3) << i;
    }
}

TEST(ImageOps, ReformatResizesEveryPassAndScalesMotion)
{
    const Frame f = test::make_sample_frame(64, 32, 1);
    // Overscan: a data window 8 px beyond the display window on every side.
    Frame big;
    big.display_window = f.display_window;
    big.data_window = {-8, -8, 72, 40};
    big.camera = f.camera;
    for (const auto &[name, p] : f.passes()) {
        big.set(name,
                place_in_window(*p.image,
                                {0, 0, 64, 32},
                                big.data_window,
                                std::vector<float>(std::size_t(p.image->channels()), 0.5f)));
    }
    const Frame out = test::run_node("reformat", big, R"({"width": 32})");
    EXPECT_EQ(out.display_window, (Rect{0, 0, 32, 16}));
    EXPECT_EQ(out.data_window, (Rect{-4, -4, 36, 20}));
    // Motion vectors halve with the image; depth is sampled, not filtered.
    EXPECT_FLOAT_EQ(at_abs(out, "motion", 10, 10, 0), 1.0f);
    EXPECT_FLOAT_EQ(at_abs(out, "motion", 10, 10, 1), -0.5f);
    const float d = at_abs(out, "depth", 10, 10, 0);
    EXPECT_TRUE(d == at_abs(big, "depth", 20, 20, 0) || d == at_abs(big, "depth", 21, 21, 0));
    // The color ramp u*2 across 64 px: at output pixel x the input position is 2x+1.
    for (int x = 4; x < 28; ++x) {
        EXPECT_NEAR(at_abs(out, "color", x, 8, 0), (2.0 * x + 1.0) / 32.0, 2e-3) << x;
    }
    expect_camera_follows(big, out, filter::window_map(big.display_window, out.display_window));
    // Upsizing with a named filter (an unknown one is refused: tests/invalid).
    const Frame up = test::run_node(
        "reformat", test::make_sample_frame(64, 32, 1), R"({"scale": 2, "filter": "catmull-rom"})");
    EXPECT_EQ(up.display_window, (Rect{0, 0, 128, 64}));
    EXPECT_NEAR(at_abs(up, "color", 64, 10, 0), (64.5 / 2.0 / 64.0) * 2.0, 2e-3);
}

// An output too large names the parameter that made it: a height alone sets the width too, and
// the error named "width" for it.
TEST(ImageOps, ReformatNamesTheParameterOfAnOutputTooLarge)
{
    const Frame f = test::make_sample_frame(48, 27, 1);
    const auto message = [&](const char *params) {
        try {
            test::run_node("reformat", f, params);
        } catch (const Error &e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(message(R"({"height": 65536})").find("param \"height\""), std::string::npos)
        << message(R"({"height": 65536})");
    EXPECT_NE(message(R"({"width": 65536})").find("param \"width\""), std::string::npos);
    // A 1-pixel-high frame: the width follows the height past int's range; refused, not wrapped.
    const Frame thin = test::make_sample_frame(60000, 1, 1);
    try {
        test::run_node("reformat", thin, R"({"height": 65536})");
        ADD_FAILURE() << "a 3.9e9-pixel-wide output was not refused";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("param \"height\""), std::string::npos) << e.what();
    }
}

TEST(ImageOps, TransformShiftsAndTurnsExactlyAndTheCameraFollows)
{
    const Frame f = test::make_sample_frame(48, 48, 1);
    const Frame moved = test::run_node(
        "transform", f, R"({"translate_x": 5, "translate_y": -3, "filter": "lanczos3"})");
    EXPECT_EQ(moved.data_window, (Rect{5, -3, 53, 45}));
    EXPECT_EQ(moved.display_window, f.display_window);
    for (int y = 4; y < 40; ++y) {
        for (int x = 4; x < 40; ++x) {
            ASSERT_NEAR(
                at_abs(moved, "color", x + 5, y - 3, 0), f.image("color").at(x, y, 0), 1e-5f);
            ASSERT_EQ(at_abs(moved, "depth", x + 5, y - 3, 0), f.image("depth").at(x, y, 0));
        }
    }
    filter::Affine shift(1.0);
    shift[2][0] = 5.0;
    shift[2][1] = -3.0;
    expect_camera_follows(f, moved, shift);

    // A quarter turn counter-clockwise about the centre: (x, y) -> (y, 47 - x) in pixel indices.
    const Frame turned = test::run_node("transform", f, R"({"rotate": 90})");
    EXPECT_EQ(turned.data_window, f.data_window);
    for (int y = 0; y < 48; ++y) {
        for (int x = 0; x < 48; ++x) {
            ASSERT_EQ(at_abs(turned, "depth", y, 47 - x, 0), f.image("depth").at(x, y, 0));
        }
    }
    // Motion (2, -1): right and up becomes up and left.
    EXPECT_NEAR(at_abs(turned, "motion", 20, 20, 0), -1.0f, 1e-6f);
    EXPECT_NEAR(at_abs(turned, "motion", 20, 20, 1), -2.0f, 1e-6f);
    filter::Affine turn(1.0);
    turn[0][0] = 0.0;
    turn[0][1] = -1.0;
    turn[1][0] = 1.0;
    turn[1][1] = 0.0;
    turn[2][0] = 0.0;
    turn[2][1] = 48.0;
    expect_camera_follows(f, turned, turn);

    // Scaling about the centre, then back: the smooth color ramp returns within 1e-3.
    Frame f2 = test::make_sample_frame(64, 64, 1);
    const Frame there = test::run_node("transform", f2, R"({"scale": 1.5, "rotate": 17})");
    const Frame back =
        test::run_node("transform", there, R"({"scale": 0.6666666666666666, "rotate": -17})");
    for (int y = 20; y < 44; ++y) {
        for (int x = 20; x < 44; ++x) {
            ASSERT_NEAR(at_abs(back, "color", x, y, 0), f2.image("color").at(x, y, 0), 1e-3f);
        }
    }
}

TEST(ImageOps, CropCutsTheWindowsAndKeepsValues)
{
    const Frame f = test::make_sample_frame(40, 30, 1);
    const Frame c = test::run_node("crop", f, R"({"box": [10, 5, 30, 25]})");
    EXPECT_EQ(c.display_window, (Rect{10, 5, 30, 25}));
    EXPECT_EQ(c.data_window, (Rect{10, 5, 30, 25}));
    EXPECT_EQ(at_abs(c, "color", 12, 7, 0), f.image("color").at(12, 7, 0));
    expect_camera_follows(f, c, filter::Affine(1.0));

    const Frame r = test::run_node("crop", f, R"({"box": [10, 5, 30, 25], "reformat": true})");
    EXPECT_EQ(r.display_window, (Rect{0, 0, 20, 20}));
    EXPECT_EQ(at_abs(r, "color", 2, 2, 0), f.image("color").at(12, 7, 0));
    filter::Affine shift(1.0);
    shift[2][0] = -10.0;
    shift[2][1] = -5.0;
    expect_camera_follows(f, r, shift);

    // A box past the data: the data window is cut, not padded; crop_data false keeps it all.
    const Frame wide = test::run_node("crop", f, R"({"box": [-10, 0, 20, 30]})");
    EXPECT_EQ(wide.data_window, (Rect{0, 0, 20, 30}));
    const Frame keep = test::run_node("crop", f, R"({"box": [0, 0, 20, 30], "crop_data": false})");
    EXPECT_EQ(keep.data_window, f.data_window);
    EXPECT_EQ(keep.pass("color").image, f.pass("color").image);
    EXPECT_THROW(test::run_node("crop", f, R"({"box": [5, 5, 5, 9]})"), Error);
    EXPECT_THROW(test::run_node("crop", f, R"({"box": [0.5, 0, 10, 10]})"), Error);
}

}  // namespace
}  // namespace posthaste
