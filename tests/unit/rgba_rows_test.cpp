// Nodes whose kernels take RGBA rows (tonemap, grain) on other layouts: an RGB pass gives the RGB
// of the same pass with alpha 1 added, and a five-channel pass keeps its alpha and fifth channel
// and gives the RGB of its first four channels (filter/rgba_rows.h).

#include <gtest/gtest.h>

#include "test_util.h"

namespace posthaste {
namespace {

Frame frame_with(int channels)
{
    Image img(24, 10, channels);
    for (int y = 0; y < 10; ++y) {
        for (int x = 0; x < 24; ++x) {
            for (int c = 0; c < channels; ++c) {
                img.at(x, y, c) = c == 3 ? 0.5f : 0.01f * float(1 + x + 3 * y + 7 * c);
            }
        }
    }
    Frame f;
    f.number = 3;
    f.set_size(24, 10);
    f.set("color",
          std::move(img),
          channels == 3 ? std::vector<std::string>{"R", "G", "B"}
                        : std::vector<std::string>{"R", "G", "B", "A", "Z"});
    return f;
}

TEST(RgbaRows, OtherLayoutsGiveTheRgbaResult)
{
    for (const char *type : {"tonemap", "grain"}) {
        SCOPED_TRACE(type);
        // Three channels against the same values with alpha 1.
        const Frame rgb = frame_with(3);
        Frame rgba = rgb;
        Image with_alpha(24, 10, 4);
        for (int y = 0; y < 10; ++y) {
            for (int x = 0; x < 24; ++x) {
                for (int c = 0; c < 3; ++c) {
                    with_alpha.at(x, y, c) = rgb.image("color").at(x, y, c);
                }
                with_alpha.at(x, y, 3) = 1.0f;
            }
        }
        rgba.erase("color");
        rgba.set("color", with_alpha);
        const Image a = test::run_node(type, rgb, "{}", 3).image("color");
        const Image b = test::run_node(type, rgba, "{}", 3).image("color");
        ASSERT_EQ(a.channels(), 3);
        // Five channels against their first four.
        const Frame five = frame_with(5);
        Image four_img(24, 10, 4);
        for (int y = 0; y < 10; ++y) {
            for (int x = 0; x < 24; ++x) {
                for (int c = 0; c < 4; ++c) {
                    four_img.at(x, y, c) = five.image("color").at(x, y, c);
                }
            }
        }
        Frame four;
        four.number = 3;
        four.set_size(24, 10);
        four.set("color", four_img);
        const Image e = test::run_node(type, five, "{}", 3).image("color");
        const Image g = test::run_node(type, four, "{}", 3).image("color");
        bool changed = false;
        for (int y = 0; y < 10; ++y) {
            for (int x = 0; x < 24; ++x) {
                for (int c = 0; c < 3; ++c) {
                    ASSERT_EQ(a.at(x, y, c), b.at(x, y, c)) << x << " " << y << " " << c;
                    ASSERT_EQ(e.at(x, y, c), g.at(x, y, c)) << x << " " << y << " " << c;
                    changed = changed || a.at(x, y, c) != rgb.image("color").at(x, y, c);
                }
                ASSERT_EQ(e.at(x, y, 3), 0.5f);
                ASSERT_EQ(e.at(x, y, 4), five.image("color").at(x, y, 4));
            }
        }
        EXPECT_TRUE(changed);  // the node did something
    }
}

}  // namespace
}  // namespace posthaste
