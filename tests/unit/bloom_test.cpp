// Bloom: the FFT convolution against a direct sum computed here, energy conservation for both
// methods, a uniform frame staying uniform, the Airy pattern's first dark ring where optics puts
// it (1.22 lambda N), the pyramid against the exact method, a PSF read from a file, determinism
// across thread counts, and the one-line errors.

#include "filter/bloom.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "core/error.h"
#include "core/parallel.h"
#include "io/image_file.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame frame_of(const Image &img)
{
    Frame f;
    f.number = 1;
    f.set_size(img.width(), img.height());
    f.set("color", std::make_shared<const Image>(img), {"R", "G", "B", "A"});
    return f;
}

/// A dark frame with a few bright points and a soft gradient, alpha 1.
Image points_image(int w, int h)
{
    Image img(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            img.at(x, y, 0) = 0.02f + 0.1f * float(x) / float(w);
            img.at(x, y, 1) = 0.03f;
            img.at(x, y, 2) = 0.05f * float(y) / float(h);
            img.at(x, y, 3) = 1.0f;
        }
    }
    const int pts[][2] = {
        {w / 2, h / 2}, {w / 4, h / 3}, {3 * w / 4, 2 * h / 3}, {w / 3, 3 * h / 4}};
    float e = 50.0f;
    for (const auto &p : pts) {
        img.at(p[0], p[1], 0) = e;
        img.at(p[0], p[1], 1) = 0.7f * e;
        img.at(p[0], p[1], 2) = 0.4f * e;
        e *= 0.5f;
    }
    return img;
}

double channel_sum(const Image &img, int c)
{
    double s = 0.0;
    for (int y = 0; y < img.height(); ++y) {
        for (int x = 0; x < img.width(); ++x) {
            s += img.at(x, y, c);
        }
    }
    return s;
}

double rms_difference(const Image &a, const Image &b, int channels = 3)
{
    double s = 0.0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int c = 0; c < channels; ++c) {
                const double d = double(a.at(x, y, c)) - b.at(x, y, c);
                s += d * d;
            }
        }
    }
    return std::sqrt(s / double(a.pixel_count() * std::size_t(channels)));
}

TEST(Bloom, FftEqualsTheDirectSumWithEdgePixelsExtended)
{
    const Image in = points_image(37, 23);
    filter::BloomPsfParams p;
    p.intensity = 0.3;
    p.size = 0.05;
    p.radius = 0.25;  // 9 px: the kernel reaches past every edge
    p.diffraction_scale = 30.0;
    const filter::Psf psf = filter::builtin_psf(p, 37);
    ASSERT_EQ(psf.radius, 9);
    const Image out = filter::bloom_fft(in, psf);
    double worst = 0.0;
    for (int y = 0; y < in.height(); ++y) {
        for (int x = 0; x < in.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                double s = 0.0;
                for (int dy = -psf.radius; dy <= psf.radius; ++dy) {
                    for (int dx = -psf.radius; dx <= psf.radius; ++dx) {
                        s += double(psf.at(c, dx, dy)) * in.load_clamped(x - dx, y - dy, c);
                    }
                }
                worst = std::max(worst, std::abs(s - out.at(x, y, c)) / std::max(1e-3, s));
            }
            EXPECT_EQ(out.at(x, y, 3), 1.0f);  // alpha passes through
        }
    }
    EXPECT_LT(worst, 1e-4);
}

TEST(Bloom, BothMethodsConserveEnergy)
{
    // Points well inside a black frame: no light reaches the edges, so none is lost there.
    const int w = 256, h = 192;
    Image in(w, h, 4);
    in.at(128, 96, 0) = 100.0f;
    in.at(120, 90, 1) = 40.0f;
    in.at(140, 100, 2) = 7.0f;
    for (const char *method : {"pyramid", "fft"}) {
        SCOPED_TRACE(method);
        const Frame out = test::run_node(
            "bloom",
            frame_of(in),
            std::string(R"({"intensity": 0.5, "radius": 0.2, "method": ")") + method + "\"}");
        for (int c = 0; c < 3; ++c) {
            const double before = channel_sum(in, c), after = channel_sum(out.image("color"), c);
            EXPECT_NEAR(after / before, 1.0, 1e-4) << "channel " << c;
        }
    }
}

TEST(Bloom, UniformFrameStaysUniform)
{
    Image in(64, 48, 4);
    for (int y = 0; y < 48; ++y) {
        for (int x = 0; x < 64; ++x) {
            const float v[4] = {0.5f, 2.0f, 0.25f, 1.0f};
            std::copy(v, v + 4, in.pixel(x, y));
        }
    }
    for (const char *method : {"pyramid", "fft"}) {
        SCOPED_TRACE(method);
        const Frame out =
            test::run_node("bloom",
                           frame_of(in),
                           std::string(R"({"intensity": 0.8, "method": ")") + method + "\"}");
        EXPECT_LT(rms_difference(out.image("color"), in), 2e-6);
    }
}

TEST(Bloom, AiryFirstDarkRingAtOnePointTwoTwoLambdaN)
{
    // A circular aperture: the pattern's first zero lies at 1.22 lambda N on the sensor.
    filter::BloomPsfParams p;
    p.intensity = 0.0;
    p.blades = 0;
    p.fstop = 8.0;
    p.pixel_pitch_um = 5.0;
    p.diffraction_scale = 8.0;  // the ring lands a few pixels out
    p.radius = 0.2;
    const filter::Psf psf = filter::builtin_psf(p, 200);
    const double lambda_um[3] = {0.610, 0.550, 0.465};
    for (int c = 0; c < 3; ++c) {
        const double expected =
            1.22 * lambda_um[c] * p.fstop * p.diffraction_scale / p.pixel_pitch_um;
        // The radial profile along the x axis: its first local minimum.
        int first_min = -1;
        for (int x = 1; x < psf.radius; ++x) {
            if (psf.at(c, x, 0) < psf.at(c, x - 1, 0) && psf.at(c, x, 0) <= psf.at(c, x + 1, 0)) {
                first_min = x;
                break;
            }
        }
        EXPECT_NEAR(first_min, expected, 1.0) << "channel " << c;
        double sum = 0.0;
        for (float v : psf.planes[std::size_t(c)]) {
            sum += v;
        }
        EXPECT_NEAR(sum, 1.0, 1e-5);
    }
}

TEST(Bloom, BladesGiveThePatternTheirSymmetry)
{
    // Six blades: the pattern repeats every 60 degrees; it is not symmetric under 45.
    filter::BloomPsfParams p;
    p.intensity = 0.0;
    p.blades = 6;
    p.diffraction_scale = 10.0;  // first dark ring at 10.7 px
    p.pixel_pitch_um = 5.0;
    p.radius = 0.5;
    const filter::Psf psf = filter::builtin_psf(p, 400);
    auto sample = [&](double r, double deg) {  // bilinear
        const double a = deg * M_PI / 180.0, x = r * std::cos(a), y = r * std::sin(a);
        const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        return (1 - fx) * (1 - fy) * psf.at(1, x0, y0) + fx * (1 - fy) * psf.at(1, x0 + 1, y0) +
               (1 - fx) * fy * psf.at(1, x0, y0 + 1) + fx * fy * psf.at(1, x0 + 1, y0 + 1);
    };
    double same = 0.0, other = 0.0, ref = 0.0;
    for (double r = 20.0; r < 150.0; r += 1.0) {
        for (double deg = 0.0; deg < 360.0; deg += 7.5) {
            same += std::abs(sample(r, deg) - sample(r, deg + 60.0));
            other += std::abs(sample(r, deg) - sample(r, deg + 45.0));
            ref += sample(r, deg);
        }
    }
    EXPECT_LT(same, 0.25 * other);
    EXPECT_GT(other, 0.1 * ref);
}

TEST(Bloom, PyramidIsWithinFivePercentOfTheExactTail)
{
    // Same PSF both ways (no diffraction): the pyramid's error against the exact convolution,
    // relative to the bloom itself (exact minus input).
    const Image in = points_image(320, 180);
    const Frame f = frame_of(in);
    const Frame exact = test::run_node("bloom", f, R"({"method": "fft", "intensity": 0.2})");
    const Frame pyr = test::run_node("bloom", f, R"({"intensity": 0.2})");
    const double signal = rms_difference(exact.image("color"), in);
    const double error = rms_difference(exact.image("color"), pyr.image("color"));
    EXPECT_GT(signal, 1e-3);
    EXPECT_LT(error / signal, 0.05) << "error " << error << " signal " << signal;

    filter::BloomPsfParams p;
    const filter::PyramidFit fit = filter::fit_pyramid(filter::tail_psf(p, 1920));
    EXPECT_LT(fit.residual, 0.1);
    EXPECT_NEAR(std::accumulate(fit.weights.begin(), fit.weights.end(), 0.0), 1.0, 1e-6);
}

TEST(Bloom, ZeroIntensityPassesThrough)
{
    const Frame f = frame_of(points_image(40, 30));
    const Frame pyr = test::run_node("bloom", f, R"({"intensity": 0})");
    EXPECT_EQ(&pyr.image("color"), &f.image("color"));
    const Frame exact = test::run_node("bloom", f, R"({"intensity": 0, "method": "fft"})");
    EXPECT_LT(rms_difference(exact.image("color"), f.image("color")), 1e-5);
}

TEST(Bloom, PsfFromAFile)
{
    // A 3x3 box PSF: the result is the 3x3 box blur, edges clamped.
    const std::string dir = test::scratch_dir("bloom_psf");
    Image k(3, 3, 4);
    for (int y = 0; y < 3; ++y) {
        for (int x = 0; x < 3; ++x) {
            const float v[4] = {2.0f, 2.0f, 2.0f, 1.0f};  // normalised by the node
            std::copy(v, v + 4, k.pixel(x, y));
        }
    }
    write_exr(frame_of(k), dir + "/box.exr", {});
    const Image in = points_image(30, 20);
    const Frame out = test::run_node(
        "bloom", frame_of(in), R"({"method": "fft", "psf": ")" + dir + R"(/box.exr"})");
    for (int y = 0; y < 20; ++y) {
        for (int x = 0; x < 30; ++x) {
            for (int c = 0; c < 3; ++c) {
                double s = 0.0;
                for (int dy = -1; dy <= 1; ++dy) {
                    for (int dx = -1; dx <= 1; ++dx) {
                        s += in.load_clamped(x + dx, y + dy, c) / 9.0;
                    }
                }
                EXPECT_NEAR(out.image("color").at(x, y, c), s, 1e-4 * std::max(1.0, s));
            }
        }
    }
}

TEST(Bloom, SameBitsWhateverTheThreadCount)
{
    const Frame f = frame_of(points_image(300, 170));
    for (const char *params : {"{}", R"({"method": "fft", "diffraction_scale": 20})"}) {
        set_thread_count(1);
        const Frame a = test::run_node("bloom", f, params);
        set_thread_count(2);
        const Frame b = test::run_node("bloom", f, params);
        set_thread_count(0);
        EXPECT_TRUE(a.image("color").bit_equal(b.image("color"))) << params;
    }
}

TEST(Bloom, NonFiniteInputReadsAsZero)
{
    Image in = points_image(64, 40);
    in.at(10, 10, 0) = std::numeric_limits<float>::quiet_NaN();
    in.at(30, 20, 1) = std::numeric_limits<float>::infinity();
    for (const char *method : {"pyramid", "fft"}) {
        const Frame out =
            test::run_node("bloom", frame_of(in), std::string(R"({"method": ")") + method + "\"}");
        const Image &o = out.image("color");
        for (std::size_t i = 0; i < o.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(o.data()[i])) << method << " value " << i;
        }
    }
}

TEST(Bloom, BadPsfImagesAreOneLineErrors)
{
    const std::string dir = test::scratch_dir("bloom_bad_psf");
    write_exr(frame_of(Image(5, 5, 4)), dir + "/black.exr", {});
    try {
        test::run_node("bloom",
                       frame_of(points_image(20, 20)),
                       R"({"method": "fft", "psf": ")" + dir + R"(/black.exr"})");
        FAIL() << "an all-black PSF was accepted";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("param \"psf\""), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("sums to 0"), std::string::npos) << e.what();
        EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
    }
    EXPECT_THROW(filter::psf_from_image(Image(41, 9, 1), 10, "who"), Error);
}

}  // namespace
}  // namespace posthaste
