// Tests for src/metrics/diff.h: pass selection, verdicts and exit codes, images, JSON, summary.

#include "metrics/diff.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>

#include "core/error.h"
#include "core/hash.h"

namespace posthaste::metrics {
namespace {

Image ramp(int w, int h, int c, std::uint32_t seed)
{
    Image img(w, h, c);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int k = 0; k < c; ++k) {
                img.at(x, y, k) = 0.1f + 0.8f * hash_unit(x / 3, y / 3, k, seed);
            }
        }
    }
    return img;
}

Frame make_frame(int number = 7)
{
    Frame f;
    f.number = number;
    f.set("color", ramp(12, 8, 4, 1));
    f.set("depth", ramp(12, 8, 1, 2));
    return f;
}

TEST(Diff, IdenticalFramesPass)
{
    const Frame a = make_frame();
    const DiffReport r = diff_frames(a, a);
    EXPECT_EQ(r.verdict, Verdict::Pass);
    EXPECT_EQ(r.exit_code(), 0);
    ASSERT_EQ(r.passes.size(), 2u);
    EXPECT_EQ(r.passes[0].name, "color");
    EXPECT_EQ(r.passes[1].name, "depth");
    EXPECT_EQ(r.passes[0].stats.all.max_error, 0.0);
    ASSERT_TRUE(r.flip.has_value());
    EXPECT_TRUE(r.flip->hdr);
    EXPECT_EQ(r.flip->result.mean, 0.0);
    EXPECT_TRUE(r.messages.empty());
}

TEST(Diff, OneChangedPixelFailsWithLocationImagesAndFlip)
{
    const Frame a = make_frame();
    Frame b = make_frame();
    Image color = *b.pass("color").image;
    color.at(5, 3, 1) += 0.25f;
    b.set("color", std::move(color));
    DiffOptions o;
    o.difference_scale = 16.0f;
    const DiffReport r = diff_frames(a, b, o);
    EXPECT_EQ(r.verdict, Verdict::Failure);
    EXPECT_EQ(r.exit_code(), 2);
    const PassDiff &c = r.passes[0];
    ASSERT_TRUE(c.compared);
    EXPECT_EQ(c.verdict, Verdict::Failure);
    EXPECT_NEAR(c.stats.all.max_error, 0.25, 1e-6);
    EXPECT_EQ(c.stats.all.max_x, 5);
    EXPECT_EQ(c.stats.all.max_y, 3);
    EXPECT_EQ(c.stats.all.max_channel, 1);
    EXPECT_EQ(c.stats.all.fail_count, 1u);
    EXPECT_NEAR(c.stats.all.mean_error, 0.25 / (12 * 8 * 4), 1e-8);
    EXPECT_NEAR(c.stats.channels[1].mean_error, 0.25 / (12 * 8), 1e-8);
    EXPECT_EQ(c.stats.channels[0].max_error, 0.0);
    EXPECT_NEAR(c.difference.at(5, 3, 1), 4.0f, 1e-5f);
    EXPECT_EQ(c.difference.at(0, 0, 1), 0.0f);
    EXPECT_EQ(r.passes[1].verdict, Verdict::Pass);

    ASSERT_TRUE(r.flip.has_value());
    EXPECT_GT(r.flip->result.mean, 0.0);
    EXPECT_EQ(r.flip->result.max_x, 5);
    EXPECT_EQ(r.flip->result.max_y, 3);
    EXPECT_EQ(r.flip->heatmap.channels(), 3);
    EXPECT_EQ(r.flip->result.error_map.width(), 12);

    // Loosened thresholds (idiff -fail 0.3 -warn 0.1) make it a warning, then a pass.
    o.thresholds.fail = 0.3f;
    o.thresholds.warn = 0.1f;
    EXPECT_EQ(diff_frames(a, b, o).verdict, Verdict::Pass);  // nothing fails: pass outright
    o.thresholds.fail = 0.2f;
    o.thresholds.fail_percent = 5.0f;
    EXPECT_EQ(diff_frames(a, b, o).verdict, Verdict::Warning);

    const std::string line = summary_line(r);
    EXPECT_NE(line.find("frame 7: FAILURE"), std::string::npos) << line;
    EXPECT_NE(line.find("color mean"), std::string::npos) << line;
    EXPECT_NE(line.find("@ (5, 3, G)"), std::string::npos) << line;
    EXPECT_NE(line.find("flip(hdr) mean"), std::string::npos) << line;
}

TEST(Diff, JsonReport)
{
    const Frame a = make_frame();
    Frame b = make_frame();
    Image depth = *b.pass("depth").image;
    depth.at(2, 1, 0) = std::numeric_limits<float>::infinity();
    b.set("depth", std::move(depth));
    DiffOptions o;
    o.flip = FlipMode::Ldr;
    const auto j = nlohmann::json::parse(to_json(diff_frames(a, b, o)));
    EXPECT_EQ(j["frame"], 7);
    EXPECT_EQ(j["verdict"], "FAILURE");  // an infinity against a number fails (idiff: PASS)
    EXPECT_EQ(j["exit_code"], 2);
    ASSERT_EQ(j["passes"].size(), 2u);
    EXPECT_EQ(j["passes"][1]["name"], "depth");
    EXPECT_EQ(j["passes"][1]["stats"]["max_error"], "inf");
    EXPECT_EQ(j["passes"][1]["stats"]["max_pixel"], nlohmann::json({2, 1}));
    EXPECT_EQ(j["passes"][1]["stats"]["max_channel"], "Z");
    EXPECT_EQ(j["passes"][0]["per_channel"]["A"]["max_error"], 0.0);
    EXPECT_EQ(j["passes"][0]["stats"]["psnr"], "inf");
    EXPECT_EQ(j["flip"]["mode"], "ldr");
    EXPECT_EQ(j["flip"]["mean"], 0.0);
    EXPECT_EQ(j["thresholds"]["hard_fail"], "inf");
    EXPECT_FLOAT_EQ(j["thresholds"]["fail"].get<float>(), 1e-6f);
}

TEST(Diff, PassesOnlyInOneFrameWarn)
{
    const Frame a = make_frame();
    Frame b = make_frame();
    b.erase("depth");
    b.set("normal", ramp(12, 8, 3, 5));
    const DiffReport r = diff_frames(a, b);
    EXPECT_EQ(r.verdict, Verdict::Warning);
    EXPECT_EQ(r.only_in_a, std::vector<std::string>{"depth"});
    EXPECT_EQ(r.only_in_b, std::vector<std::string>{"normal"});
    ASSERT_EQ(r.passes.size(), 1u);
    ASSERT_FALSE(r.messages.empty());
    EXPECT_NE(r.messages[0].find("only in a: depth; only in b: normal"), std::string::npos);
}

TEST(Diff, RequestedMissingPassIsFileError)
{
    const Frame a = make_frame();
    Frame b = make_frame();
    b.erase("depth");
    DiffOptions o;
    o.passes = {"depth", "color"};
    const DiffReport r = diff_frames(a, b, o);
    EXPECT_EQ(r.verdict, Verdict::FileError);
    EXPECT_EQ(r.exit_code(), 4);
    ASSERT_EQ(r.passes.size(), 1u);
    EXPECT_EQ(r.passes[0].name, "color");
    ASSERT_EQ(r.messages.size(), 1u);
    EXPECT_EQ(r.messages[0], "frame b has no pass \"depth\" (have: color)");
}

TEST(Diff, ChannelMismatchAndFrameSize)
{
    const Frame a = make_frame();
    Frame b = make_frame();
    b.set("depth", ramp(12, 8, 2, 2), {"Z", "W"});
    DiffReport r = diff_frames(a, b);
    EXPECT_EQ(r.verdict, Verdict::SizeMismatch);
    EXPECT_EQ(r.exit_code(), 3);
    EXPECT_FALSE(r.passes[1].compared);
    EXPECT_NE(r.passes[1].note.find("1 channels (Z) vs 2 channels (Z, W)"), std::string::npos)
        << r.passes[1].note;

    Frame c = make_frame();
    c.set("depth", *a.pass("depth").image, {"depth"});
    r = diff_frames(a, c);
    EXPECT_EQ(r.verdict, Verdict::Warning);  // same values, renamed channel
    EXPECT_TRUE(r.passes[1].compared);

    Frame small;
    small.set("color", ramp(6, 4, 4, 1));
    r = diff_frames(a, small);
    EXPECT_EQ(r.verdict, Verdict::SizeMismatch);
    EXPECT_TRUE(r.passes.empty());
    EXPECT_EQ(r.messages[0], "data window 12x8 at (0, 0) vs 6x4 at (0, 0)");
    EXPECT_EQ(summary_line(r).find("frame 7", 1), std::string::npos) << summary_line(r);
}

TEST(Diff, FlipSkippedWithoutColorAndOptionsChecked)
{
    Frame a;
    a.set("depth", ramp(4, 4, 1, 3));
    const DiffReport r = diff_frames(a, a);
    EXPECT_FALSE(r.flip.has_value());
    EXPECT_EQ(r.verdict, Verdict::Pass);
    ASSERT_EQ(r.messages.size(), 1u);
    EXPECT_NE(r.messages[0].find("FLIP skipped"), std::string::npos);
    DiffOptions o;
    o.flip = FlipMode::Off;
    EXPECT_TRUE(diff_frames(a, a, o).messages.empty());
    o.pixels_per_degree = 0.0f;
    EXPECT_THROW(diff_frames(a, a, o), Error);
}

}  // namespace
}  // namespace posthaste::metrics
