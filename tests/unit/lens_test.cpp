// Lens: the distortion's exact inverse (round trip within 1e-3 px), its Jacobian against finite
// differences, the node's round trip on an image, the ST-map against positions computed here,
// the data window growing for pincushion and shrinking for barrel, natural vignetting against
// cos^4 of the field angle, lateral chromatic aberration moving red and blue by their factors,
// and a distortion that folds over refused with the pixel where it does.

#include "filter/lens.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/error.h"
#include "test_util.h"

namespace posthaste {
namespace {

const filter::Distortion kCases[] = {
    {-0.2, 0.05, 0.0, 0.0, 0.0},          // barrel
    {0.15, 0.02, 0.0, 0.0, 0.0},          // pincushion
    {-0.05, 0.01, -0.002, 0.01, -0.005},  // mixed, tangential
};

TEST(Lens, UndistortInvertsDistortWithinAThousandthOfAPixel)
{
    const double unit = 960.0;  // half of 1920 px
    for (const filter::Distortion &d : kCases) {
        double worst = 0.0;
        for (double y = -0.6; y <= 0.6; y += 0.05) {
            for (double x = -1.0; x <= 1.0; x += 0.05) {
                const glm::dvec2 u(x, y);
                const auto back = d.undistort(d.distort(u));
                ASSERT_TRUE(back.has_value()) << x << " " << y;
                worst = std::max(worst, glm::length(*back - u) * unit);
            }
        }
        EXPECT_LT(worst, 1e-3);
    }
}

TEST(Lens, JacobianMatchesFiniteDifferences)
{
    const double h = 1e-6;
    for (const filter::Distortion &d : kCases) {
        for (const glm::dvec2 u :
             {glm::dvec2(0.3, -0.2), glm::dvec2(-0.7, 0.4), glm::dvec2(0.9, 0.5)}) {
            const glm::dmat2 j = d.jacobian(u);
            const glm::dvec2 dx =
                (d.distort(u + glm::dvec2(h, 0)) - d.distort(u - glm::dvec2(h, 0))) / (2 * h);
            const glm::dvec2 dy =
                (d.distort(u + glm::dvec2(0, h)) - d.distort(u - glm::dvec2(0, h))) / (2 * h);
            EXPECT_NEAR(j[0].x, dx.x, 1e-6);
            EXPECT_NEAR(j[0].y, dx.y, 1e-6);
            EXPECT_NEAR(j[1].x, dy.x, 1e-6);
            EXPECT_NEAR(j[1].y, dy.y, 1e-6);
        }
    }
}

/// A smooth colour pattern (periods of 40-60 px), alpha 1, a depth ramp.
Frame smooth_frame(int w, int h)
{
    Frame f;
    f.number = 1;
    f.set_size(w, h);
    Image c(w, h, 4), z(w, h, 1);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            c.at(x, y, 0) = 0.5f + 0.4f * std::sin(float(x) / 40.0f * 6.2831853f);
            c.at(x, y, 1) = 0.5f + 0.4f * std::cos(float(y) / 60.0f * 6.2831853f);
            c.at(x, y, 2) = 0.3f + 0.002f * float(x + y);
            c.at(x, y, 3) = 1.0f;
            z.at(x, y, 0) = 1.0f + 0.01f * float(x);
        }
    }
    f.set("color", std::make_shared<const Image>(std::move(c)), {"R", "G", "B", "A"});
    f.set("depth", std::make_shared<const Image>(std::move(z)));
    f.camera.focal_length_mm = 50.0f;
    f.camera.sensor_width_mm = 36.0f;
    return f;
}

TEST(Lens, IdentityPassesThrough)
{
    const Frame in = smooth_frame(32, 24);
    const Frame out = test::run_node("lens", in, "{}");
    EXPECT_EQ(&out.image("color"), &in.image("color"));
}

TEST(Lens, DistortThenUndistortGivesTheImageBack)
{
    const Frame in = smooth_frame(320, 200);
    const std::string coeffs = R"("k1": -0.08, "k2": 0.01, "p1": 0.002)";
    const Frame d = test::run_node("lens", in, "{" + coeffs + "}");
    const Frame back = test::run_node("lens", d, R"({"direction": "undistort", )" + coeffs + "}");
    // Back in the input's window; compare away from the edges the barrel pulled in.
    ASSERT_EQ(back.data_window.x0 <= 20 && back.data_window.x1 >= 300, true);
    double sum = 0.0;
    int n = 0;
    for (int y = 40; y < 160; ++y) {
        for (int x = 40; x < 280; ++x) {
            for (int c = 0; c < 3; ++c) {
                const double e =
                    back.image("color").at(x - back.data_window.x0, y - back.data_window.y0, c) -
                    in.image("color").at(x, y, c);
                sum += e * e;
                ++n;
            }
        }
    }
    EXPECT_LT(std::sqrt(sum / n), 2e-3);
}

TEST(Lens, StMapHoldsWhereEachPixelReads)
{
    const int w = 160, h = 100;
    const Frame in = smooth_frame(w, h);
    const Frame out = test::run_node("lens", in, R"({"k1": 0.1, "stmap": true})");
    const filter::Distortion dist{0.1, 0, 0, 0, 0};
    const Image &st = out.image("stmap");
    for (int y = 0; y < st.height(); y += 7) {
        for (int x = 0; x < st.width(); x += 11) {
            // Output pixel centre, normalised by half the width about the centre.
            const glm::dvec2 p(out.data_window.x0 + x + 0.5, out.data_window.y0 + y + 0.5);
            const glm::dvec2 c(w / 2.0, h / 2.0);
            const auto u = dist.undistort((p - c) / (w / 2.0));
            ASSERT_TRUE(u.has_value());
            const glm::dvec2 src = *u * (w / 2.0) + c;
            EXPECT_NEAR(st.at(x, y, 0), src.x / w, 1e-5);
            EXPECT_NEAR(st.at(x, y, 1), 1.0 - src.y / h, 1e-5);
        }
    }
    // Without distortion: Nuke's identity ST-map.
    const Frame ident = test::run_node("lens", in, R"({"stmap": true})");
    EXPECT_FLOAT_EQ(ident.image("stmap").at(0, 0, 0), 0.5f / w);
    EXPECT_FLOAT_EQ(ident.image("stmap").at(0, 0, 1), 1.0f - 0.5f / h);
    EXPECT_FLOAT_EQ(ident.image("stmap").at(w - 1, h - 1, 0), (w - 0.5f) / w);
}

TEST(Lens, DataWindowGrowsForPincushionAndShrinksForBarrel)
{
    const Frame in = smooth_frame(200, 120);
    const Frame pin = test::run_node("lens", in, R"({"k1": 0.2})");
    EXPECT_LT(pin.data_window.x0, 0);
    EXPECT_GT(pin.data_window.x1, 200);
    EXPECT_LT(pin.data_window.y0, 0);
    EXPECT_EQ(pin.display_window, in.display_window);
    const Frame barrel = test::run_node("lens", in, R"({"k1": -0.2})");
    EXPECT_GT(barrel.data_window.x0, 0);
    EXPECT_LT(barrel.data_window.x1, 200);
    EXPECT_EQ(barrel.image("depth").width(), barrel.data_window.width());
    // Undistorting a pincushion pulls the edges in (a barrel-like outline): the corners of its
    // bounding window read outside the input, where depth is the sky and colour is empty.
    const Frame undo = test::run_node("lens", in, R"({"k1": 0.2, "direction": "undistort"})");
    EXPECT_GT(undo.data_window.x0, 0);
    EXPECT_TRUE(std::isinf(undo.image("depth").at(0, 0, 0)));
    EXPECT_EQ(undo.image("color").at(0, 0, 3), 0.0f);
}

TEST(Lens, NaturalVignettingIsCosFourOfTheFieldAngle)
{
    Frame in = smooth_frame(192, 108);
    Image white(192, 108, 4);
    white.fill(1.0f);
    in.set("color", std::make_shared<const Image>(white), {"R", "G", "B", "A"});
    const Frame out = test::run_node("lens", in, R"({"natural_vignetting": 1})");
    for (const auto &[x, y] : {std::pair{0, 0}, std::pair{150, 20}, std::pair{96, 54}}) {
        const double r_px = std::hypot(x + 0.5 - 96.0, y + 0.5 - 54.0);
        const double t = r_px * (36.0 / 192.0) / 50.0;
        EXPECT_NEAR(out.image("color").at(x, y, 1), 1.0 / ((1 + t * t) * (1 + t * t)), 1e-5);
    }
    // No camera: a one-line error naming the parameter and the attribute.
    Frame bare = in;
    bare.camera = Camera{};
    try {
        test::run_node("lens", bare, R"({"natural_vignetting": 1})");
        FAIL();
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("natural_vignetting"), std::string::npos) << e.what();
    }
}

TEST(Lens, ChromaticAberrationScalesRedAndBlue)
{
    // A white vertical line 100 px right of the centre: red is read at 1.01x the distance, so
    // it appears at 100 / 1.01 px; blue at 100 / 0.99.
    const int w = 400, h = 60;
    Frame f;
    f.set_size(w, h);
    Image img(w, h, 4);
    for (int y = 0; y < h; ++y) {
        img.at(300, y, 0) = img.at(300, y, 1) = img.at(300, y, 2) = 1.0f;
    }
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    const Frame out =
        test::run_node("lens", f, R"({"chromatic_aberration": 0.01, "filter": "bilinear"})");
    auto centroid = [&](int c) {
        double s = 0.0, sx = 0.0;
        for (int x = 0; x < w; ++x) {
            const double v = out.image("color").at(x, 30, c);
            s += v;
            sx += v * (x + 0.5);
        }
        return sx / s;
    };
    EXPECT_NEAR(centroid(1), 300.5, 1e-3);
    EXPECT_NEAR(centroid(0), 200.0 + 100.5 / 1.01, 0.02);
    EXPECT_NEAR(centroid(2), 200.0 + 100.5 / 0.99, 0.02);
}

TEST(Lens, FoldingDistortionIsRefusedWithThePixel)
{
    // r (1 - r^2) turns back at r = 0.577 half-widths, inside the frame.
    try {
        test::run_node("lens", smooth_frame(200, 120), R"({"k1": -1})");
        FAIL() << "a folding distortion was accepted";
    } catch (const Error &e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("folds over at pixel"), std::string::npos) << m;
        EXPECT_EQ(m.find('\n'), std::string::npos);
    }
}

}  // namespace
}  // namespace posthaste
