#include "core/image.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/error.h"
#include "core/frame.h"
#include "core/hash.h"
#include "core/parallel.h"

namespace posthaste {
namespace {

TEST(Image, ZeroFilledAndIndexedRowMajor)
{
    Image img(3, 2, 2);
    EXPECT_EQ(img.value_count(), 12u);
    for (std::size_t i = 0; i < img.value_count(); ++i) {
        EXPECT_EQ(img.data()[i], 0.0f);
    }
    img.at(2, 1, 1) = 5.0f;
    EXPECT_EQ(img.data()[(1 * 3 + 2) * 2 + 1], 5.0f);
}

TEST(Image, BorderModes)
{
    Image img(2, 2, 1);
    img.at(0, 0, 0) = 1.0f;
    img.at(1, 0, 0) = 2.0f;
    img.at(0, 1, 0) = 3.0f;
    img.at(1, 1, 0) = 4.0f;
    EXPECT_EQ(img.load_clamped(-5, -5, 0), 1.0f);
    EXPECT_EQ(img.load_clamped(7, 9, 0), 4.0f);
    EXPECT_EQ(img.load_zero(-1, 0, 0), 0.0f);
    EXPECT_EQ(img.load_zero(1, 1, 0), 4.0f);
}

TEST(Image, BilinearAtCentresAndMidpoints)
{
    Image img(2, 2, 1);
    img.at(0, 0, 0) = 1.0f;
    img.at(1, 0, 0) = 2.0f;
    img.at(0, 1, 0) = 3.0f;
    img.at(1, 1, 0) = 4.0f;
    EXPECT_FLOAT_EQ(img.sample_bilinear_clamped(0.5f, 0.5f).x, 1.0f);
    EXPECT_FLOAT_EQ(img.sample_bilinear_clamped(1.0f, 0.5f).x, 1.5f);
    EXPECT_FLOAT_EQ(img.sample_bilinear_clamped(1.0f, 1.0f).x, 2.5f);
    EXPECT_FLOAT_EQ(img.sample_bilinear_clamped(-3.0f, 1.5f).x, 3.0f);
}

TEST(Image, AbsurdSizesThrow)
{
    EXPECT_THROW(Image(-1, 4, 1), Error);
    EXPECT_THROW(Image(4, 4, 0), Error);
    EXPECT_THROW(Image(100000, 4, 1), Error);
    EXPECT_THROW(Image(65536, 65536, 4), Error);
}

TEST(Image, BitEqualSeesNaNBits)
{
    Image a(2, 1, 1), b(2, 1, 1);
    a.at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    b.at(0, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(a.bit_equal(b));
    b.at(1, 0, 0) = -0.0f;
    EXPECT_FALSE(a.bit_equal(b));
}

TEST(Frame, CanonicalChannelsAndSizeCheck)
{
    Frame f;
    f.set("color", Image(4, 3, 4));
    EXPECT_EQ(f.width(), 4);
    EXPECT_EQ(f.pass("color").channels, (std::vector<std::string>{"R", "G", "B", "A"}));
    f.set("normal", Image(4, 3, 3));
    EXPECT_EQ(f.pass("normal").channels, (std::vector<std::string>{"X", "Y", "Z"}));
    EXPECT_THROW(f.set("depth", Image(5, 3, 1)), Error);
    try {
        f.pass("motion", "node \"mb\"");
        FAIL();
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("no pass \"motion\" (have: color, normal)"),
                  std::string::npos)
            << e.what();
    }
}

// Passes given no channel names get names a reader of the EXR understands: a colour of three
// channels is R, G, B (it was "0", "1", "2"), of one Y; a canonical pass with fewer channels
// than its own takes the first ones; an unknown RGB(A) pass R, G, B (A).
TEST(Frame, DefaultChannelNames)
{
    using V = std::vector<std::string>;
    EXPECT_EQ(default_channel_names("color", 3), (V{"R", "G", "B"}));
    EXPECT_EQ(default_channel_names("color", 1), (V{"Y"}));
    EXPECT_EQ(default_channel_names("color", 2), (V{"Y", "A"}));
    EXPECT_EQ(default_channel_names("color", 5), (V{"0", "1", "2", "3", "4"}));
    EXPECT_EQ(default_channel_names("normal", 2), (V{"X", "Y"}));
    EXPECT_EQ(default_channel_names("beauty", 3), (V{"R", "G", "B"}));
    EXPECT_EQ(default_channel_names("beauty", 4), (V{"R", "G", "B", "A"}));
    EXPECT_EQ(default_channel_names("mask", 1), (V{"Y"}));
    EXPECT_EQ(default_channel_names("uv", 2), (V{"0", "1"}));
    Frame f;
    f.set("color", Image(2, 2, 3));
    EXPECT_EQ(f.pass("color").channels, (V{"R", "G", "B"}));
}

TEST(Parallel, TilesCoverEveryPixelOnce)
{
    Image img(130, 67, 1);
    parallel_for_tiles(img.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                img.at(x, y, 0) += 1.0f;
            }
        }
    });
    for (std::size_t i = 0; i < img.value_count(); ++i) {
        ASSERT_EQ(img.data()[i], 1.0f);
    }
}

TEST(Parallel, TheThreadCountReachesOpenImageIOAndOpenExr)
{
    // --threads bounds the image libraries' pools too: OpenEXR compresses a file's blocks on
    // its own threads, which otherwise number the machine's cores whatever the job was given.
    const auto oiio = [](const char *name) {
        int v = -1;
        OIIO::getattribute(name, v);
        return v;
    };
    set_thread_count(1);
    EXPECT_EQ(thread_count(), 1);
    EXPECT_EQ(oiio("threads"), 1);
    EXPECT_EQ(oiio("exr_threads"), 1);
    set_thread_count(3);
    EXPECT_EQ(oiio("exr_threads"), 3);
    set_thread_count(0);  // back to the defaults: the hardware's count
    EXPECT_EQ(oiio("exr_threads"), 0);
}

TEST(Hash, UnitRangeAndDeterminism)
{
    double sum = 0.0;
    for (int i = 0; i < 10000; ++i) {
        const float u = hash_unit(i % 100, i / 100, 3, 7u);
        ASSERT_GE(u, 0.0f);
        ASSERT_LT(u, 1.0f);
        sum += u;
    }
    EXPECT_NEAR(sum / 10000.0, 0.5, 0.02);
    EXPECT_EQ(hash_unit(5, 6, 7, 8u), hash_unit(5, 6, 7, 8u));
}

TEST(Hash, RadicalInverseReversesBits)
{
    EXPECT_EQ(radical_inverse_base2(0), 0.0f);
    EXPECT_EQ(radical_inverse_base2(1), 0.5f);
    EXPECT_EQ(radical_inverse_base2(2), 0.25f);
    EXPECT_EQ(radical_inverse_base2(3), 0.75f);
    EXPECT_EQ(radical_inverse_base2(6), 0.375f);
}

}  // namespace
}  // namespace posthaste

#include "core/sanitize.h"

namespace posthaste {
namespace {

TEST(Sanitize, FiniteViewCopiesOnlyWhenNeeded)
{
    Image clean(3, 2, 2);
    clean.at(1, 1, 1) = 5.0f;
    Image storage;
    EXPECT_EQ(&finite_view(clean, 0.0f, storage), &clean);  // no copy
    Image depth(2, 1, 1);
    depth.at(0, 0, 0) = std::numeric_limits<float>::infinity();
    EXPECT_EQ(&finite_view(depth, 1.0f, storage, true), &depth);  // +inf allowed for depth
    depth.at(1, 0, 0) = std::numeric_limits<float>::quiet_NaN();
    const Image &fixed = finite_view(depth, -1.0f, storage, true);
    EXPECT_EQ(&fixed, &storage);
    EXPECT_TRUE(std::isinf(fixed.at(0, 0, 0)));
    EXPECT_EQ(fixed.at(1, 0, 0), -1.0f);
    clean.at(2, 0, 0) = -std::numeric_limits<float>::infinity();
    EXPECT_EQ(finite_view(clean, 7.0f, storage).at(2, 0, 0), 7.0f);
    EXPECT_EQ(finite_view(clean, 7.0f, storage).at(1, 1, 1), 5.0f);
}

}  // namespace
}  // namespace posthaste
