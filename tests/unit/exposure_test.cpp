// Exposure: stops and the photographic scale against hand-computed values, the metering of
// images whose answer is known exactly, the adaptation formula, and auto exposure over a
// sequence read from files: every frame's scale equals the adaptation computed here from the
// known luminances, a chunk started in the middle gives the same bits as the whole run, and
// frames evaluated in parallel give the same bits as one after another.

#include "filter/exposure.h"

#include <gtest/gtest.h>

#include <cmath>
#include <thread>

#include "core/error.h"
#include "core/parallel.h"
#include "io/image_file.h"
#include "nodes/registry.h"
#include "test_util.h"

namespace posthaste {
namespace {

Frame grey_frame(int w, int h, float value)
{
    Image img(w, h, 4);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float v[4] = {value, value, value, 1.0f};
            std::copy(v, v + 4, img.pixel(x, y));
        }
    }
    Frame f;
    f.number = 1;
    f.set_size(w, h);
    f.set("color", std::make_shared<const Image>(std::move(img)), {"R", "G", "B", "A"});
    return f;
}

TEST(Exposure, StopsScaleColorAndKeepAlpha)
{
    Frame in = grey_frame(8, 4, 0.25f);
    const Frame out = test::run_node("exposure", in, R"({"exposure": 1.5})");
    const Image &o = out.image("color");
    EXPECT_FLOAT_EQ(o.at(3, 2, 0), 0.25f * float(std::exp2(1.5)));
    EXPECT_FLOAT_EQ(o.at(3, 2, 2), 0.25f * float(std::exp2(1.5)));
    EXPECT_EQ(o.at(3, 2, 3), 1.0f);
    const Frame same = test::run_node("exposure", in, "{}");
    EXPECT_EQ(&same.image("color"), &in.image("color"));
}

TEST(Exposure, PhotographicScaleFromTheCamera)
{
    // f/8, 1/125 s, ISO 100: EV100 = log2(64 * 125) = log2(8000); scale 1 / (1.2 * 8000).
    EXPECT_NEAR(filter::ev100(8.0, 1.0 / 125.0, 100.0), std::log2(8000.0), 1e-12);
    EXPECT_NEAR(filter::photographic_scale(std::log2(8000.0)), 1.0 / 9600.0, 1e-15);
    Frame in = grey_frame(4, 4, 1000.0f);
    const Frame given = test::run_node(
        "exposure", in, R"({"mode": "photographic", "fstop": 8, "shutter_time": 0.008})");
    EXPECT_NEAR(given.image("color").at(1, 1, 1), 1000.0 / 9600.0, 1e-6);
    // From the header: f/4 and a 180-degree shutter at 24 fps (1/48 s), ISO 400:
    // EV100 = log2(16 * 48 * 100 / 400) = log2(192).
    in.camera.fstop = 4.0f;
    in.camera.shutter = 0.5f;
    const Frame header = test::run_node("exposure", in, R"({"mode": "photographic", "iso": 400})");
    EXPECT_NEAR(header.image("color").at(1, 1, 1), 1000.0 / (1.2 * 192.0), 1e-5);
}

TEST(Exposure, MeteringOfKnownImages)
{
    // Half the pixels at 2^-3, half at 2^1 (grey): every percentile window's mean is known.
    Image img(64, 64, 4);
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 64; ++x) {
            const float v = x < 32 ? 0.125f : 2.0f;
            const float px[4] = {v, v, v, 1.0f};
            std::copy(px, px + 4, img.pixel(x, y));
        }
    }
    filter::MeterParams p;
    p.low_percentile = 0.0;
    p.high_percentile = 100.0;
    EXPECT_NEAR(filter::meter_log2_luminance(img, p), -1.0, 1e-6);  // (-3 + 1) / 2
    p.low_percentile = 50.0;
    EXPECT_NEAR(filter::meter_log2_luminance(img, p), 1.0, 1e-6);
    p.low_percentile = 25.0;
    p.high_percentile = 75.0;
    EXPECT_NEAR(filter::meter_log2_luminance(img, p), -1.0, 1e-6);
    // Non-finite samples are skipped; black counts at min_ev.
    img.at(2, 2, 0) = std::numeric_limits<float>::quiet_NaN();
    Image black(16, 16, 4);
    EXPECT_NEAR(filter::meter_log2_luminance(black, p), p.min_ev, 1e-12);
    EXPECT_TRUE(std::isfinite(filter::meter_log2_luminance(img, p)));
}

TEST(Exposure, AdaptationFormula)
{
    // From EV 0 toward 3 (brighter) at speed_up 3/s for one frame at 24 fps, then toward -1
    // (darker) at speed_down 1/s for a gap of two frames.
    const double a1 = 3.0 * (1.0 - std::exp(-3.0 / 24.0));
    const double a2 = a1 + (-1.0 - a1) * (1.0 - std::exp(-1.0 * 2.0 / 24.0));
    EXPECT_NEAR(filter::adapt_ev({{1, 0.0}, {2, 3.0}}, 24.0, 3.0, 1.0), a1, 1e-12);
    EXPECT_NEAR(filter::adapt_ev({{1, 0.0}, {2, 3.0}, {4, -1.0}}, 24.0, 3.0, 1.0), a2, 1e-12);
    EXPECT_NEAR(filter::adapt_ev({{1, 0.0}, {2, 3.0}}, 24.0, 0.0, 1.0), 3.0, 1e-12);
}

class ExposureSequence : public ::testing::Test {
   protected:
    // Log2 luminance of frames 1..12: a cut to 3 stops brighter, then to 2 stops darker.
    const std::vector<double> stops = {0, 0, 0, 3, 3, 3, 3, -2, -2, -2, -2, -2};
    std::string dir;

    void SetUp() override
    {
        dir = test::scratch_dir("exposure_sequence");
        for (int f = 1; f <= 12; ++f) {
            Frame fr = grey_frame(32, 16, float(std::exp2(stops[std::size_t(f - 1)])));
            fr.number = f;
            write_exr(fr, dir + "/in." + std::to_string(1000 + f).substr(1) + ".exr", {});
        }
    }

    Graph graph(const std::string &params) const
    {
        Graph g = Graph::parse(R"({"nodes": [
            {"id": "src", "type": "read", "params": {"path": ")" +
                                   dir + R"(/in.###.exr"}},
            {"id": "x", "type": "exposure", "inputs": {"image": "src"}, "params": )" +
                                   params + R"(},
            {"id": "out", "type": "write", "inputs": {"image": "x"},
             "params": {"path": ")" +
                                   dir + R"(/out.###.exr"}}]})",
                               "exposure_sequence.json",
                               nodes::catalog());
        g.set_capture("x");
        return g;
    }
};

TEST_F(ExposureSequence, EveryFrameFollowsTheAdaptation)
{
    const Graph g = graph(R"({"mode": "auto", "adaptation_frames": 5})");
    for (int n = 1; n <= 12; ++n) {
        std::vector<filter::MeterSample> samples;
        for (int k = std::max(1, n - 5); k <= n; ++k) {
            samples.emplace_back(k, stops[std::size_t(k - 1)] - std::log2(0.18));
        }
        const double a = filter::adapt_ev(samples, 24.0, 3.0, 1.0);
        const Frame out = g.evaluate(n);
        const double in = std::exp2(stops[std::size_t(n - 1)]);
        EXPECT_NEAR(out.image("color").at(5, 5, 1) / in, std::exp2(-a), 1e-5 * std::exp2(-a))
            << "frame " << n;
    }
}

TEST_F(ExposureSequence, ChunkedRunEqualsWholeRunAndParallelEqualsSerial)
{
    const std::string params = R"({"mode": "auto", "adaptation_frames": 6})";
    std::vector<Frame> whole;
    {
        const Graph g = graph(params);
        for (int n = 1; n <= 12; ++n) {
            whole.push_back(g.evaluate(n));
        }
    }
    {
        // A fresh process's view: frames 7-12 only, the warm-up evaluated from history.
        const Graph g = graph(params);
        for (int n = 7; n <= 12; ++n) {
            EXPECT_TRUE(
                g.evaluate(n).image("color").bit_equal(whole[std::size_t(n - 1)].image("color")))
                << "frame " << n;
        }
    }
    {
        // Frames in flight together, last first, sharing the node's cache of meterings.
        const Graph g = graph(params);
        std::vector<Frame> got(12);
        std::vector<std::thread> threads;
        for (int n = 12; n >= 1; --n) {
            threads.emplace_back([&, n] { got[std::size_t(n - 1)] = g.evaluate(n); });
        }
        for (std::thread &t : threads) {
            t.join();
        }
        for (int n = 1; n <= 12; ++n) {
            EXPECT_TRUE(got[std::size_t(n - 1)].image("color").bit_equal(
                whole[std::size_t(n - 1)].image("color")))
                << "frame " << n;
        }
    }
}

TEST(Exposure, NonFiniteValuesStayInTheirPixel)
{
    Frame in = grey_frame(16, 16, 0.5f);
    Image img = in.image("color");
    img.at(3, 3, 0) = std::numeric_limits<float>::quiet_NaN();
    img.at(4, 4, 1) = std::numeric_limits<float>::infinity();
    in.set("color", std::make_shared<const Image>(img), {"R", "G", "B", "A"});
    const Frame out = test::run_node("exposure", in, R"({"mode": "auto"})");
    const Image &o = out.image("color");
    EXPECT_TRUE(std::isnan(o.at(3, 3, 0)));
    EXPECT_TRUE(std::isinf(o.at(4, 4, 1)));
    // Metered on the finite pixels: 0.5 brought to 0.18.
    EXPECT_NEAR(o.at(8, 8, 0), 0.18f, 1e-5f);
}

}  // namespace
}  // namespace posthaste
