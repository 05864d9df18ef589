// The previews' PNG encoder: files libpng (through OpenImageIO) reads back exactly, the filters'
// bytes as the PNG specification defines them, a valid zlib stream over several pieces, the
// same bytes whatever the thread count, and one-line errors.

#include "io/png_write.h"

#include <OpenImageIO/imageio.h>
#include <gtest/gtest.h>
#include <zlib.h>

#include <cstring>
#include <fstream>
#include <stdexcept>

#include "core/parallel.h"
#include "io/color.h"
#include "io/image_file.h"
#include "test_util.h"

namespace posthaste {
namespace {

using test::scratch_dir;

struct Chunk {
    std::string type;
    std::vector<std::uint8_t> data;
    bool crc_ok;
};

std::uint32_t be32(const std::uint8_t *p)
{
    return std::uint32_t(p[0]) << 24 | std::uint32_t(p[1]) << 16 | std::uint32_t(p[2]) << 8 |
           std::uint32_t(p[3]);
}

std::vector<Chunk> chunks_of(const std::vector<std::uint8_t> &png)
{
    std::vector<Chunk> out;
    const std::uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    EXPECT_TRUE(png.size() >= 8 && std::memcmp(png.data(), signature, 8) == 0);
    std::size_t i = 8;
    while (i + 12 <= png.size()) {
        const std::uint32_t n = be32(png.data() + i);
        EXPECT_LE(i + 12 + n, png.size());
        Chunk c;
        c.type.assign(reinterpret_cast<const char *>(png.data() + i + 4), 4);
        c.data.assign(png.begin() + std::ptrdiff_t(i + 8), png.begin() + std::ptrdiff_t(i + 8 + n));
        c.crc_ok = crc32(0, png.data() + i + 4, n + 4) == be32(png.data() + i + 8 + n);
        out.push_back(std::move(c));
        i += 12 + n;
    }
    EXPECT_EQ(i, png.size());
    return out;
}

/// The filtered bytes (a filter byte before each row), inflated from the IDAT chunks by zlib,
/// which checks the stream's Adler-32.
std::vector<std::uint8_t> inflated(const std::vector<std::uint8_t> &png, std::size_t expect)
{
    std::vector<std::uint8_t> z;
    for (const Chunk &c : chunks_of(png)) {
        if (c.type == "IDAT") {
            z.insert(z.end(), c.data.begin(), c.data.end());
        }
    }
    std::vector<std::uint8_t> out(expect + 1);
    uLongf size = uLongf(out.size());
    EXPECT_EQ(uncompress(out.data(), &size, z.data(), uLong(z.size())), Z_OK);
    out.resize(size);
    return out;
}

/// Pixels that compress somewhat: gradients, a hash's noise and flat runs.
std::vector<std::uint8_t> test_pixels(int w, int h, int nch)
{
    std::vector<std::uint8_t> p(std::size_t(w) * std::size_t(h) * std::size_t(nch));
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < nch; ++c) {
                const std::uint32_t hash = (std::uint32_t(x) * 73856093u) ^
                                           (std::uint32_t(y) * 19349663u) ^
                                           (std::uint32_t(c) * 83492791u);
                const int v = (x / 40) % 2 ? 200 : (x + 2 * y + 50 * c) % 256;
                p[(std::size_t(y) * std::size_t(w) + std::size_t(x)) * std::size_t(nch) +
                  std::size_t(c)] = std::uint8_t(v + int((hash >> 13) % 5));
            }
        }
    }
    return p;
}

// Every filter and level, RGB and RGBA, from one pixel to images of several pieces: libpng
// (through OpenImageIO) reads back every pixel exactly.
TEST(PngWrite, LibpngReadsBackEveryPixel)
{
    const std::string dir = scratch_dir("png_write");
    const struct {
        int w, h;
    } sizes[] = {{1, 1}, {7, 3}, {700, 400}};
    for (const auto size : sizes) {
        for (const int nch : {3, 4}) {
            const std::vector<std::uint8_t> pixels = test_pixels(size.w, size.h, nch);
            for (const PngFilter f : {PngFilter::none,
                                      PngFilter::sub,
                                      PngFilter::up,
                                      PngFilter::average,
                                      PngFilter::paeth,
                                      PngFilter::adaptive}) {
                for (const int level : {0, 1, 6, 9}) {
                    const std::string path = dir + "/p.png";
                    const std::vector<std::uint8_t> png =
                        encode_png(pixels.data(), size.w, size.h, nch, level, f, "p.png");
                    write_file_bytes(path, png.data(), png.size());
                    // The file's straight values, as they are (not premultiplied on read).
                    OIIO::ImageSpec config;
                    config.attribute("oiio:UnassociatedAlpha", 1);
                    auto in = OIIO::ImageInput::open(path, &config);
                    ASSERT_TRUE(in) << OIIO::geterror();
                    ASSERT_EQ(in->spec().width, size.w);
                    ASSERT_EQ(in->spec().height, size.h);
                    ASSERT_EQ(in->spec().nchannels, nch);
                    std::vector<std::uint8_t> got(pixels.size());
                    ASSERT_TRUE(in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, got.data()))
                        << in->geterror();
                    ASSERT_EQ(got, pixels) << size.w << "x" << size.h << " channels " << nch
                                           << " filter " << int(f) << " level " << level;
                }
            }
        }
    }
}

// The chunks: IHDR's fields, sRGB with its gAMA and cHRM, IDATs, IEND last, every CRC right;
// a 1080p frame's rows make several pieces, one IDAT each, joined into one valid zlib stream.
TEST(PngWrite, ChunksAndPieces)
{
    const int w = 1920, h = 1080;
    const std::vector<std::uint8_t> pixels = test_pixels(w, h, 3);
    const std::vector<std::uint8_t> png =
        encode_png(pixels.data(), w, h, 3, 1, PngFilter::none, "frame.png");
    const std::vector<Chunk> chunks = chunks_of(png);
    ASSERT_GE(chunks.size(), 6u);
    EXPECT_EQ(chunks.front().type, "IHDR");
    EXPECT_EQ(chunks.back().type, "IEND");
    const std::vector<std::uint8_t> ihdr = {0, 0, 7, 128, 0, 0, 4, 56, 8, 2, 0, 0, 0};
    EXPECT_EQ(chunks.front().data, ihdr);
    int idats = 0;
    bool srgb = false;
    for (const Chunk &c : chunks) {
        EXPECT_TRUE(c.crc_ok) << c.type;
        idats += c.type == "IDAT";
        srgb |= c.type == "sRGB" && c.data == std::vector<std::uint8_t>{0};
    }
    EXPECT_TRUE(srgb);
    const std::size_t stride = std::size_t(w) * 3 + 1;
    const std::size_t piece_rows = kPngPieceBytes / stride;
    EXPECT_EQ(std::size_t(idats), (std::size_t(h) + piece_rows - 1) / piece_rows);
    EXPECT_GT(idats, 1);
    // The zlib header says a 32 KiB window, no dictionary, level 1's "fastest".
    const std::vector<std::uint8_t> &first = chunks[4].data;
    ASSERT_EQ(chunks[4].type, "IDAT");
    EXPECT_EQ(first[0], 0x78);
    EXPECT_EQ(first[1], 0x01);
    const std::vector<std::uint8_t> rows = inflated(png, stride * std::size_t(h));
    ASSERT_EQ(rows.size(), stride * std::size_t(h));
    for (int y = 0; y < h; ++y) {
        const std::uint8_t *r = rows.data() + std::size_t(y) * stride;
        ASSERT_EQ(r[0], 0) << "row " << y;  // filter none
        ASSERT_EQ(std::memcmp(r + 1, pixels.data() + std::size_t(y) * std::size_t(w) * 3, w * 3), 0)
            << "row " << y;
    }
}

// Each filter's bytes on a hand-computed 2x2 RGB image (PNG specification, section 9.2), and
// the adaptive choice: sub on a row that steps evenly across, up on a row equal to the one above.
TEST(PngWrite, FiltersAsSpecified)
{
    // Row 0: (10, 20, 30) (50, 40, 30); row 1: (12, 200, 0) (60, 10, 255).
    const std::vector<std::uint8_t> px = {10, 20, 30, 50, 40, 30, 12, 200, 0, 60, 10, 255};
    auto rows_of = [&](PngFilter f) {
        return inflated(encode_png(px.data(), 2, 2, 3, 6, f, "t.png"), 14);
    };
    using V = std::vector<std::uint8_t>;
    EXPECT_EQ(rows_of(PngFilter::none), (V{0, 10, 20, 30, 50, 40, 30, 0, 12, 200, 0, 60, 10, 255}));
    // sub: minus the pixel to the left (0 before the first).
    EXPECT_EQ(rows_of(PngFilter::sub),
              (V{1, 10, 20, 30, 40, 20, 0, 1, 12, 200, 0, 48, std::uint8_t(10 - 200), 255}));
    // up: minus the pixel above (0 above the first row).
    EXPECT_EQ(rows_of(PngFilter::up),
              (V{2,
                 10,
                 20,
                 30,
                 50,
                 40,
                 30,
                 2,
                 2,
                 180,
                 std::uint8_t(0 - 30),
                 10,
                 std::uint8_t(10 - 40),
                 225}));
    // average: minus floor((left + up) / 2).
    EXPECT_EQ(rows_of(PngFilter::average),
              (V{3,
                 10,
                 20,
                 30,
                 45,
                 30,
                 15,
                 3,
                 7,
                 190,
                 std::uint8_t(0 - 15),
                 29,
                 std::uint8_t(10 - 120),
                 240}));
    // paeth: the neighbour (left, up, up-left) nearest to left + up - up-left. Row 1, pixel 1:
    // channel 0: a 12 b 50 c 10, p 52: b; channel 1: a 200 b 40 c 20, p 220: a;
    // channel 2: a 0 b 30 c 30, p 0: a.
    EXPECT_EQ(rows_of(PngFilter::paeth),
              (V{4,
                 10,
                 20,
                 30,
                 40,
                 20,
                 0,
                 4,
                 2,
                 180,
                 std::uint8_t(0 - 30),
                 10,
                 std::uint8_t(10 - 200),
                 255}));

    // A ramp that steps by 3 along x, repeated on the next row.
    std::vector<std::uint8_t> ramp(2 * 16 * 3);
    for (int y = 0; y < 2; ++y) {
        for (int i = 0; i < 16 * 3; ++i) {
            ramp[std::size_t(y * 48 + i)] = std::uint8_t(100 + 3 * (i / 3));
        }
    }
    const V rows =
        inflated(encode_png(ramp.data(), 16, 2, 3, 6, PngFilter::adaptive, "ramp.png"), 2 * 49);
    ASSERT_EQ(rows.size(), 98u);
    EXPECT_EQ(rows[0], 1);   // sub: 100 100 100, then 3s
    EXPECT_EQ(rows[49], 2);  // up: all zero
}

// The same bytes at one thread as at two (the pieces depend on the image's size only).
TEST(PngWrite, SameBytesWhateverTheThreads)
{
    const int w = 1000, h = 700;
    const std::vector<std::uint8_t> pixels = test_pixels(w, h, 4);
    const int before = thread_count();
    set_thread_count(1);
    const std::vector<std::uint8_t> one =
        encode_png(pixels.data(), w, h, 4, 1, PngFilter::adaptive, "a.png");
    set_thread_count(2);
    const std::vector<std::uint8_t> two =
        encode_png(pixels.data(), w, h, 4, 1, PngFilter::adaptive, "a.png");
    set_thread_count(before);
    EXPECT_EQ(one, two);
}

// A preview with alpha holds straight colour, as PNG defines it: the premultiplied values
// divided by alpha (code floor(v 255 + 0.5) without dither); alpha 0 stays black.
TEST(PngWrite, PreviewAlphaIsStraight)
{
    Image img(2, 1, 4);
    const float px[8] = {0.25f, 0.5f, 0.1f, 0.5f, 0.0f, 0.0f, 0.0f, 0.0f};
    std::copy_n(px, 8, img.pixel(0, 0));
    const ColorProcessor identity = ColorProcessor::between("lin_rec709", "lin_rec709", "test");
    PreviewOptions o;
    o.alpha = true;
    o.dither = false;
    const std::string path = scratch_dir("png_alpha") + "/a.png";
    const Rect window{0, 0, 2, 1};
    write_display_preview(img, window, window, identity, path, o);
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::open(path, &config);
    ASSERT_TRUE(in);
    std::uint8_t got[8] = {};
    ASSERT_TRUE(in->read_image(0, 0, 0, 4, OIIO::TypeDesc::UINT8, got));
    const std::uint8_t want[8] = {128, 255, 51, 128, 0, 0, 0, 0};
    for (int i = 0; i < 8; ++i) {
        EXPECT_EQ(int(got[i]), int(want[i])) << "value " << i;
    }
}

// Sizes a PNG cannot hold, and a file that cannot be created: one line naming the image.
TEST(PngWrite, ErrorsNameTheImage)
{
    const std::uint8_t px[4] = {1, 2, 3, 4};
    auto message = [&](auto &&fn) {
        try {
            fn();
        } catch (const std::exception &e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    const int sizes[][3] = {{0, 1, 3}, {1, 0, 3}, {1, 1, 2}};  // width, height, channels
    for (const auto &size : sizes) {
        const std::string m = message(
            [&] { encode_png(px, size[0], size[1], size[2], 1, PngFilter::none, "thumb.png"); });
        EXPECT_NE(m.find("thumb.png"), std::string::npos) << m;
        EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    }
    // A preview whose folder cannot be made (a file stands in its place).
    const std::string dir = scratch_dir("png_errors");
    std::ofstream(dir + "/file") << "x";
    Image img(1, 1, 3);
    const ColorProcessor identity = ColorProcessor::between("lin_rec709", "lin_rec709", "test");
    const Rect window{0, 0, 1, 1};
    const std::string path = dir + "/file/x.png";
    const std::string m =
        message([&] { write_display_preview(img, window, window, identity, path, {}); });
    EXPECT_EQ(m.rfind(path + ": cannot create directory", 0), 0u) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
}

}  // namespace
}  // namespace posthaste
