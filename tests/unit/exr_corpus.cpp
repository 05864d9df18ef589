// Test support for the EXR reader/writer: writes the EXR corpus with OpenEXR's own C++ API and
// checks files with OpenEXR only (no posthaste code): compare_exr for lossless pass-through,
// flatten_deep as a reference deep compositor and rgba_of for luminance/chroma files.

#include "exr_corpus.h"

#include <ImathBox.h>
#include <ImathFun.h>
#include <ImathMatrix.h>
#include <ImfChannelList.h>
#include <ImfCompression.h>
#include <ImfCompressionAttribute.h>
#include <ImfDeepFrameBuffer.h>
#include <ImfDeepImageStateAttribute.h>
#include <ImfDeepScanLineInputPart.h>
#include <ImfDeepScanLineOutputFile.h>
#include <ImfDeepTiledInputPart.h>
#include <ImfDeepTiledOutputFile.h>
#include <ImfDoubleAttribute.h>
#include <ImfEnvmap.h>
#include <ImfEnvmapAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputPart.h>
#include <ImfIntAttribute.h>
#include <ImfLineOrderAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOpaqueAttribute.h>
#include <ImfOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfPreviewImageAttribute.h>
#include <ImfRgbaFile.h>
#include <ImfStandardAttributes.h>
#include <ImfStdIO.h>
#include <ImfStringVectorAttribute.h>
#include <ImfTileDescription.h>
#include <ImfTiledInputPart.h>
#include <ImfTiledOutputFile.h>
#include <ImfTiledOutputPart.h>
#include <half.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace posthaste::test::corpus {
namespace {

using Imath::Box2i;
using Imath::V2i;

// ---------------------------------------------------------------------------------------------
// Pixel values
// ---------------------------------------------------------------------------------------------

/// A 32-bit integer finaliser (lowbias32): every input bit affects every output bit.
std::uint32_t mix32(std::uint32_t v)
{
    v ^= v >> 16;
    v *= 0x7feb352dU;
    v ^= v >> 15;
    v *= 0x846ca68bU;
    v ^= v >> 16;
    return v;
}

/// Hash of one sample's coordinates.
std::uint32_t sample_hash(int x, int y, int channel, int part, int level)
{
    std::uint32_t h = mix32(static_cast<std::uint32_t>(part) * 0x9e3779b9U + 0x632be5abU);
    h = mix32(h ^ static_cast<std::uint32_t>(level) * 0x85ebca6bU);
    h = mix32(h ^ static_cast<std::uint32_t>(channel) * 0xc2b2ae35U);
    h = mix32(h ^ static_cast<std::uint32_t>(x));
    return mix32(h ^ static_cast<std::uint32_t>(y) * 0x27d4eb2fU);
}

/// Bits of a half: a quarter of the values are simple fractions k/16 in [0, 4), the others
/// arbitrary finite normal halves of either sign with magnitudes in [2^-5, 2^3).
std::uint16_t half_bits_for(std::uint32_t h)
{
    if (h % 4 == 0) return half(static_cast<float>((h >> 8) & 63u) / 16.0f).bits();
    const std::uint32_t sign = (h >> 3) & 1u;
    const std::uint32_t exponent = 10u + (h >> 4) % 8u;
    const std::uint32_t mantissa = (h >> 12) & 0x3ffu;
    return static_cast<std::uint16_t>(sign << 15 | exponent << 10 | mantissa);
}

/// Bits of a float that no half can represent (lowest mantissa bit set), magnitude in
/// [2^-7, 2^9), either sign.
std::uint32_t float_bits_for(std::uint32_t h)
{
    const std::uint32_t sign = h & 1u;
    const std::uint32_t exponent = 120u + (h >> 1) % 16u;
    const std::uint32_t mantissa = ((h >> 9) & 0x7fffffu) | 1u;
    return sign << 31 | exponent << 23 | mantissa;
}

/// Float `v`, nudged by one ulp when a half would represent it exactly.
std::uint32_t not_half_bits(float v)
{
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    if (static_cast<float>(half(v)) == v) bits ^= 1u;
    return bits;
}

constexpr std::uint16_t kHalfSpecials[] = {0x8000, 0x7c00, 0xfc00, 0x0001, 0x03ff, 0x7bff, 0x7e00};
constexpr std::uint32_t kFloatSpecials[] = {
    0x80000000U, 0x7f800000U, 0xff800000U, 0x00000001U, 0x7f7fffffU, 0x7fc00000U, 0x477fe001U};
constexpr std::uint32_t kUintSpecials[] = {0xfffffff0U, 16777217U, 0xffffffffU, 0U, 16777216U};

/// Which values a part gets.
struct Values {
    int part = 0;
    int level = 0;
    bool smooth = false;    ///< Mostly a compressible ramp, 1 in 16 samples hashed.
    bool specials = false;  ///< The first samples of half/float channels are special values.
    bool large = false;     ///< Set per level for large images: ramp, 1 in 256 samples hashed.
};

/// Write the value of sample (x, y) of channel `channel` (the `index`-th sample of its plane)
/// to `out` in the representation of `type`.
void sample_value(Imf::PixelType type,
                  int x,
                  int y,
                  int channel,
                  std::size_t index,
                  const Values &values,
                  char *out)
{
    const std::uint32_t h = sample_hash(x, y, channel, values.part, values.level);
    const bool ramp = (values.smooth && h % 16 != 0) || (values.large && h % 256 != 0);
    const auto ux = static_cast<std::uint32_t>(x), uy = static_cast<std::uint32_t>(y);
    const auto uc = static_cast<std::uint32_t>(channel);
    if (type == Imf::HALF) {
        std::uint16_t bits = half_bits_for(h);
        if (ramp) {
            const std::uint32_t k = (ux * (uc + 1) + uy * (uc + 3)) & 1023u;
            bits = half(static_cast<float>(k) / 64.0f).bits();
        }
        if (values.specials && index < std::size(kHalfSpecials)) bits = kHalfSpecials[index];
        std::memcpy(out, &bits, 2);
    } else if (type == Imf::FLOAT) {
        std::uint32_t bits = float_bits_for(h);
        if (ramp) {
            // Constant exponent (2048 <= v < 4096 for -256 <= x < 1024), so that the bits
            // are a linear ramp; the fraction makes it unrepresentable in half.
            bits = not_half_bits(2304.0f + static_cast<float>(x % 1024) +
                                 static_cast<float>(y % 512) / 512.0f +
                                 static_cast<float>(channel % 8) * 64.0f + 1.0f / 3.0f);
        }
        if (values.specials && index < std::size(kFloatSpecials)) bits = kFloatSpecials[index];
        std::memcpy(out, &bits, 4);
    } else {
        std::uint32_t v = ramp ? ux * 7919u + uy * 104729u + uc : h;
        if (index < std::size(kUintSpecials)) v = kUintSpecials[index];
        std::memcpy(out, &v, 4);
    }
}

// ---------------------------------------------------------------------------------------------
// Flat planes (one buffer per channel, subsampling aware)
// ---------------------------------------------------------------------------------------------

/// Bytes of one sample of `type`.
std::size_t pixel_size(Imf::PixelType type)
{
    return type == Imf::HALF ? 2 : 4;
}

/// Smallest multiple of `s` that is >= `lo`.
int first_sample(int lo, int s)
{
    return Imath::divp(lo + s - 1, s) * s;
}

/// Number of multiples of `s` in [lo, hi].
int sample_count(int lo, int hi, int s)
{
    const int first = first_sample(lo, s);
    return first > hi ? 0 : (hi - first) / s + 1;
}

/// The samples of one channel over a window: sample (i, j) is pixel
/// (x_first + i * xs, y_first + j * ys), stored row-major in `bytes`.
struct Plane {
    std::string name;
    Imf::Channel channel;
    int x_first = 0, y_first = 0, nx = 0, ny = 0;
    std::vector<char> bytes;
};

/// Zeroed planes for every channel of `channels` over `window`.
std::vector<Plane> planes_for(const Imf::ChannelList &channels, const Box2i &window)
{
    std::vector<Plane> planes;
    for (auto it = channels.begin(); it != channels.end(); ++it) {
        Plane p;
        p.name = it.name();
        p.channel = it.channel();
        const int xs = std::max(1, p.channel.xSampling), ys = std::max(1, p.channel.ySampling);
        p.x_first = first_sample(window.min.x, xs);
        p.y_first = first_sample(window.min.y, ys);
        p.nx = sample_count(window.min.x, window.max.x, xs);
        p.ny = sample_count(window.min.y, window.max.y, ys);
        p.bytes.assign(static_cast<std::size_t>(p.nx) * static_cast<std::size_t>(p.ny) *
                           pixel_size(p.channel.type),
                       0);
        planes.push_back(std::move(p));
    }
    return planes;
}

/// OpenEXR addresses sample (x, y) at base + divp(x, xs) * xStride + divp(y, ys) * yStride.
/// The base lies outside the buffer for non-zero origins, hence the integer arithmetic.
char *slice_base(Plane &p, std::size_t x_stride, std::size_t y_stride)
{
    const int xs = std::max(1, p.channel.xSampling), ys = std::max(1, p.channel.ySampling);
    const std::intptr_t offset =
        static_cast<std::intptr_t>(p.x_first / xs) * static_cast<std::intptr_t>(x_stride) +
        static_cast<std::intptr_t>(p.y_first / ys) * static_cast<std::intptr_t>(y_stride);
    return reinterpret_cast<char *>(reinterpret_cast<std::intptr_t>(p.bytes.data()) - offset);
}

/// A frame buffer over `planes` (which must outlive it).
Imf::FrameBuffer frame_buffer_for(std::vector<Plane> &planes)
{
    Imf::FrameBuffer fb;
    for (Plane &p : planes) {
        const std::size_t xstride = pixel_size(p.channel.type);
        const std::size_t ystride = xstride * static_cast<std::size_t>(p.nx);
        fb.insert(p.name,
                  Imf::Slice(p.channel.type,
                             slice_base(p, xstride, ystride),
                             xstride,
                             ystride,
                             p.channel.xSampling,
                             p.channel.ySampling));
    }
    return fb;
}

/// Fill every plane with the corpus values.
void fill_planes(std::vector<Plane> &planes, const Values &values)
{
    for (std::size_t c = 0; c < planes.size(); ++c) {
        Plane &p = planes[c];
        const std::size_t size = pixel_size(p.channel.type);
        const int xs = std::max(1, p.channel.xSampling), ys = std::max(1, p.channel.ySampling);
        for (int j = 0; j < p.ny; ++j) {
            for (int i = 0; i < p.nx; ++i) {
                const std::size_t index = static_cast<std::size_t>(j) * p.nx + i;
                sample_value(p.channel.type,
                             p.x_first + i * xs,
                             p.y_first + j * ys,
                             static_cast<int>(c),
                             index,
                             values,
                             p.bytes.data() + index * size);
            }
        }
    }
}

/// The (lx, ly) levels a tiled part has.
std::vector<std::pair<int, int>> levels_of(Imf::LevelMode mode, int num_x, int num_y)
{
    std::vector<std::pair<int, int>> levels;
    if (mode == Imf::MIPMAP_LEVELS) {
        for (int l = 0; l < num_x; ++l) levels.emplace_back(l, l);
    } else if (mode == Imf::RIPMAP_LEVELS) {
        for (int ly = 0; ly < num_y; ++ly) {
            for (int lx = 0; lx < num_x; ++lx) levels.emplace_back(lx, ly);
        }
    } else {
        levels.emplace_back(0, 0);
    }
    return levels;
}

/// Large images get compressible values so that the files stay small.
bool is_large(const Box2i &window)
{
    const long long w = static_cast<long long>(window.max.x) - window.min.x + 1;
    const long long h = static_cast<long long>(window.max.y) - window.min.y + 1;
    return w * h > 64 * 64;
}

/// Write all scanlines of a flat scanline part (OutputFile or OutputPart).
template <class Out>
void write_scanlines(Out &out, const Imf::Header &header, Values values)
{
    const Box2i window = header.dataWindow();
    values.large = is_large(window);
    std::vector<Plane> planes = planes_for(header.channels(), window);
    fill_planes(planes, values);
    out.setFrameBuffer(frame_buffer_for(planes));
    out.writePixels(window.max.y - window.min.y + 1);
}

/// Write every tile of every level of a flat tiled part (TiledOutputFile or TiledOutputPart);
/// each level gets its own values.
template <class Out>
void write_tiles(Out &out, const Imf::Header &header, Values values)
{
    for (auto [lx, ly] : levels_of(out.levelMode(), out.numXLevels(), out.numYLevels())) {
        const Box2i window = out.dataWindowForLevel(lx, ly);
        values.level = lx * 64 + ly;
        values.large = is_large(window);
        std::vector<Plane> planes = planes_for(header.channels(), window);
        fill_planes(planes, values);
        out.setFrameBuffer(frame_buffer_for(planes));
        out.writeTiles(0, out.numXTiles(lx) - 1, 0, out.numYTiles(ly) - 1, lx, ly);
    }
}

// ---------------------------------------------------------------------------------------------
// Deep planes
// ---------------------------------------------------------------------------------------------

/// Deep samples over a window: per-pixel counts and, per channel, all samples concatenated in
/// pixel order with a per-pixel pointer table for OpenEXR.
struct DeepPlanes {
    Box2i window;
    int width = 0, height = 0;
    std::vector<unsigned int> counts;
    std::vector<std::string> names;
    std::vector<Imf::PixelType> types;
    std::vector<std::vector<char>> samples;
    std::vector<std::vector<char *>> pointers;
};

/// Empty deep planes (counts zero, no samples) for `channels` over `window`.
DeepPlanes deep_planes_for(const Imf::ChannelList &channels, const Box2i &window)
{
    DeepPlanes d;
    d.window = window;
    d.width = window.max.x - window.min.x + 1;
    d.height = window.max.y - window.min.y + 1;
    const std::size_t n = static_cast<std::size_t>(d.width) * static_cast<std::size_t>(d.height);
    d.counts.assign(n, 0);
    for (auto it = channels.begin(); it != channels.end(); ++it) {
        d.names.push_back(it.name());
        d.types.push_back(it.channel().type);
        d.samples.emplace_back();
        d.pointers.emplace_back(n, nullptr);
    }
    return d;
}

/// Size the sample buffers after `counts` and point the pointer tables into them.
void allocate_samples(DeepPlanes &d)
{
    const std::size_t total = std::accumulate(d.counts.begin(), d.counts.end(), std::size_t{0});
    for (std::size_t c = 0; c < d.names.size(); ++c) {
        const std::size_t size = pixel_size(d.types[c]);
        d.samples[c].assign(std::max<std::size_t>(total, 1) * size, 0);
        std::size_t offset = 0;
        for (std::size_t i = 0; i < d.counts.size(); ++i) {
            d.pointers[c][i] = d.samples[c].data() + offset * size;
            offset += d.counts[i];
        }
    }
}

/// Base for a table addressed at base + x * x_stride + y * y_stride over d.window.
char *deep_base(char *data, const DeepPlanes &d, std::size_t x_stride)
{
    const std::intptr_t offset =
        static_cast<std::intptr_t>(d.window.min.x) * static_cast<std::intptr_t>(x_stride) +
        static_cast<std::intptr_t>(d.window.min.y) * static_cast<std::intptr_t>(x_stride) * d.width;
    return reinterpret_cast<char *>(reinterpret_cast<std::intptr_t>(data) - offset);
}

/// A deep frame buffer over `d` (which must outlive it).
Imf::DeepFrameBuffer deep_frame_buffer_for(DeepPlanes &d)
{
    Imf::DeepFrameBuffer fb;
    const std::size_t cs = sizeof(unsigned int);
    fb.insertSampleCountSlice(
        Imf::Slice(Imf::UINT,
                   deep_base(reinterpret_cast<char *>(d.counts.data()), d, cs),
                   cs,
                   cs * static_cast<std::size_t>(d.width)));
    const std::size_t ps = sizeof(char *);
    for (std::size_t c = 0; c < d.names.size(); ++c) {
        fb.insert(d.names[c],
                  Imf::DeepSlice(d.types[c],
                                 deep_base(reinterpret_cast<char *>(d.pointers[c].data()), d, ps),
                                 ps,
                                 ps * static_cast<std::size_t>(d.width),
                                 pixel_size(d.types[c])));
    }
    return fb;
}

/// One premultiplied deep sample.
struct DeepSample {
    float r, g, b, a, z;
};

/// Premultiplied deep samples of pixel (x, y) of part `part`, in file order: 0..4 samples
/// (some pixels empty), partial alphas (some opaque), Z in deliberately unsorted order (back to
/// front on every other pixel, hashed order otherwise) with a Z tie on some pixels.
std::vector<DeepSample> deep_samples_at(int x, int y, int part)
{
    const std::uint32_t h = sample_hash(x, y, 99, part, 0);
    int n = static_cast<int>(h % 5);
    if (Imath::modp(x + 3 * y, 7) == 0) n = 0;
    if (Imath::modp(x + y, 5) == 1) n = 4;
    static constexpr float kAlphas[] = {0.25f, 0.5f, 0.125f, 0.75f, 1.0f, 0.3f, 0.0625f, 0.6f};
    std::vector<DeepSample> out;
    for (int s = 0; s < n; ++s) {
        const std::uint32_t hs = sample_hash(x, y, s, part, 1);
        DeepSample d;
        d.a = kAlphas[(hs >> 4) % 8];
        d.r = d.a * static_cast<float>((hs >> 8) & 255u) / 255.0f;
        d.g = d.a * static_cast<float>((hs >> 16) & 255u) / 255.0f;
        d.b = d.a * static_cast<float>((hs >> 24) & 255u) / 255.0f;
        std::uint32_t zbits = not_half_bits(1.0f + static_cast<float>(hs % 997) / 7.0f);
        std::memcpy(&d.z, &zbits, 4);
        out.push_back(d);
    }
    if (Imath::modp(x + y, 2) == 0) {
        std::stable_sort(out.begin(), out.end(), [](const DeepSample &l, const DeepSample &r) {
            return l.z > r.z;
        });
    }
    if (n >= 3 && Imath::modp(x, 4) == 2) out[2].z = out[0].z;  // A tie, not in first place.
    return out;
}

/// Deep planes over `window` filled with deep_samples_at for channels R, G, B, A, Z.
DeepPlanes deep_values(const Imf::ChannelList &channels, const Box2i &window, int part)
{
    DeepPlanes d = deep_planes_for(channels, window);
    std::vector<std::vector<DeepSample>> pixels;
    for (int y = window.min.y; y <= window.max.y; ++y) {
        for (int x = window.min.x; x <= window.max.x; ++x) {
            pixels.push_back(deep_samples_at(x, y, part));
            d.counts[pixels.size() - 1] = static_cast<unsigned int>(pixels.back().size());
        }
    }
    allocate_samples(d);
    for (std::size_t c = 0; c < d.names.size(); ++c) {
        const std::string &name = d.names[c];
        std::size_t k = 0;
        for (const auto &pixel : pixels) {
            for (const DeepSample &s : pixel) {
                const float v = name == "R"   ? s.r
                                : name == "G" ? s.g
                                : name == "B" ? s.b
                                : name == "A" ? s.a
                                              : s.z;
                char *out = d.samples[c].data() + k * pixel_size(d.types[c]);
                if (d.types[c] == Imf::HALF) {
                    const std::uint16_t bits = half(v).bits();
                    std::memcpy(out, &bits, 2);
                } else {
                    std::memcpy(out, &v, 4);
                }
                ++k;
            }
        }
    }
    return d;
}

// ---------------------------------------------------------------------------------------------
// Writing the corpus
// ---------------------------------------------------------------------------------------------

/// Box (x0,y0)-(x1,y1), inclusive.
Box2i box(int x0, int y0, int x1, int y1)
{
    return Box2i(V2i(x0, y0), V2i(x1, y1));
}

/// A header with the given windows, compression and channels (full resolution).
Imf::Header make_header(const Box2i &display,
                        const Box2i &data,
                        Imf::Compression compression,
                        const std::vector<std::pair<std::string, Imf::PixelType>> &channels)
{
    Imf::Header header(display, data, 1.0f, Imath::V2f(0, 0), 1.0f, Imf::INCREASING_Y, compression);
    for (const auto &[name, type] : channels) header.channels().insert(name, Imf::Channel(type));
    return header;
}

/// Camera-like standard attributes, for attribute pass-through checks.
void add_camera(Imf::Header &header)
{
    const float m[4][4] = {{0.5f, 0.25f, 0.0f, 0.0f},
                           {-0.25f, 0.5f, 0.125f, 0.0f},
                           {0.0f, -0.125f, 1.0f, 0.0f},
                           {3.5f, -2.25f, 10.75f, 1.0f}};
    Imf::addWorldToCamera(header, Imath::M44f(m));
    Imf::addAperture(header, 2.8f);
    Imf::addOwner(header, "posthaste exr corpus");
}

const std::vector<std::pair<std::string, Imf::PixelType>> kRgbaZ = {
    {"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}, {"Z", Imf::FLOAT}};
const std::vector<std::pair<std::string, Imf::PixelType>> kRgb = {
    {"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}};

/// Collects entries while writing.
class Writer {
   public:
    explicit Writer(std::string dir) : dir_(std::move(dir)) {}

    /// Record an entry and return its path.
    std::string add(const std::string &name, Kind kind, const std::string &what)
    {
        const std::string path = (std::filesystem::path(dir_) / (name + ".exr")).string();
        entries_.push_back({name, path, kind, what});
        return path;
    }

    std::vector<Entry> take() { return std::move(entries_); }

   private:
    std::string dir_;
    std::vector<Entry> entries_;
};

/// A single-part flat scanline file.
void write_scanline_file(const std::string &path, const Imf::Header &header, Values values = {})
{
    Imf::OutputFile out(path.c_str(), header);
    write_scanlines(out, header, values);
}

/// A single-part flat tiled file (every level).
void write_tiled_file(const std::string &path, const Imf::Header &header, Values values = {})
{
    Imf::TiledOutputFile out(path.c_str(), header);
    write_tiles(out, header, values);
}

/// A multi-part flat file; every header must have a name and a type.
void write_multipart_file(const std::string &path, const std::vector<Imf::Header> &headers)
{
    Imf::MultiPartOutputFile out(path.c_str(), headers.data(), static_cast<int>(headers.size()));
    for (int i = 0; i < static_cast<int>(headers.size()); ++i) {
        const Values values{i, 0, false, false};
        if (Imf::isTiled(headers[i].type())) {
            Imf::TiledOutputPart part(out, i);
            write_tiles(part, headers[i], values);
        } else {
            Imf::OutputPart part(out, i);
            write_scanlines(part, headers[i], values);
        }
    }
}

/// Corpus group: windows.
void write_windows(Writer &w)
{
    struct Case {
        const char *name;
        Box2i display, data;
        const char *what;
    };
    const Case cases[] = {
        {"window_inside",
         box(0, 0, 63, 47),
         box(5, 7, 44, 38),
         "data window (5,7)-(44,38) inside display (0,0)-(63,47); camera attributes"},
        {"overscan_around",
         box(30, 20, 399, 299),
         box(0, 0, 399, 299),
         "overscan: data (0,0)-(399,299) contains display (30,20)-(399,299)"},
        {"offset_outside",
         box(0, 0, 31, 31),
         box(40, -20, 59, -5),
         "data window (40,-20)-(59,-5) entirely outside display (0,0)-(31,31)"},
        {"overlap",
         box(0, 0, 47, 31),
         box(32, -6, 71, 17),
         "data window (32,-6)-(71,17) partly overlapping display (0,0)-(47,31); DECREASING_Y"},
        {"negative_origin",
         box(-16, -8, 47, 39),
         box(-20, -10, 30, 30),
         "negative origins: display (-16,-8)-(47,39), data (-20,-10)-(30,30)"},
        {"one_pixel", box(0, 0, 7, 7), box(3, 4, 3, 4), "1x1 data window at (3,4), 8x8 display"},
        {"small_in_large",
         box(0, 0, 2047, 1555),
         box(100, 200, 186, 275),
         "87x76 data window at (100,200) inside a 2048x1556 display"},
    };
    int part = 0;
    for (const Case &c : cases) {
        const std::string path =
            w.add(c.name, Kind::Flat, std::string(c.what) + "; R,G,B,A half + Z float, ZIP");
        Imf::Header header = make_header(c.display, c.data, Imf::ZIP_COMPRESSION, kRgbaZ);
        if (std::string(c.name) == "window_inside") add_camera(header);
        if (std::string(c.name) == "overlap") header.lineOrder() = Imf::DECREASING_Y;
        write_scanline_file(path, header, Values{part++, 0, false, false});
    }
}

/// Corpus group: tiled.
void write_tiled(Writer &w)
{
    {
        const std::string path = w.add("cube_mip",
                                       Kind::Flat,
                                       "cube envmap 32x192 (6 faces), display 32x32, tiled 16x16, "
                                       "MIPMAP ROUND_DOWN (8 levels), R,G,B half");
        Imf::Header header =
            make_header(box(0, 0, 31, 31), box(0, 0, 31, 191), Imf::ZIP_COMPRESSION, kRgb);
        header.setTileDescription(
            Imf::TileDescription(16, 16, Imf::MIPMAP_LEVELS, Imf::ROUND_DOWN));
        Imf::addEnvmap(header, Imf::ENVMAP_CUBE);
        write_tiled_file(path, header, Values{10, 0, false, false});
    }
    {
        const std::string path = w.add("latlong_mip",
                                       Kind::Flat,
                                       "lat-long envmap 64x32, tiled 32x32, MIPMAP ROUND_UP "
                                       "(7 levels), R,G,B half, PIZ");
        Imf::Header header =
            make_header(box(0, 0, 63, 31), box(0, 0, 63, 31), Imf::PIZ_COMPRESSION, kRgb);
        header.setTileDescription(Imf::TileDescription(32, 32, Imf::MIPMAP_LEVELS, Imf::ROUND_UP));
        Imf::addEnvmap(header, Imf::ENVMAP_LATLONG);
        write_tiled_file(path, header, Values{11, 0, false, false});
    }
    {
        const std::string path = w.add("tiled_one_level",
                                       Kind::Flat,
                                       "tiled 16x8 ONE_LEVEL, data (3,5)-(42,24) (partial tiles), "
                                       "R,G,B,A float, ZIPS");
        Imf::Header header = make_header(
            box(0, 0, 47, 31),
            box(3, 5, 42, 24),
            Imf::ZIPS_COMPRESSION,
            {{"R", Imf::FLOAT}, {"G", Imf::FLOAT}, {"B", Imf::FLOAT}, {"A", Imf::FLOAT}});
        header.setTileDescription(Imf::TileDescription(16, 8, Imf::ONE_LEVEL, Imf::ROUND_DOWN));
        write_tiled_file(path, header, Values{12, 0, false, false});
    }
    {
        const std::string path =
            w.add("ripmap",
                  Kind::Flat,
                  "tiled 8x8 RIPMAP ROUND_UP, 20x12 (6x5 levels), R,G,B half + "
                  "Z float, RLE");
        Imf::Header header =
            make_header(box(0, 0, 19, 11),
                        box(0, 0, 19, 11),
                        Imf::RLE_COMPRESSION,
                        {{"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"Z", Imf::FLOAT}});
        header.setTileDescription(Imf::TileDescription(8, 8, Imf::RIPMAP_LEVELS, Imf::ROUND_UP));
        write_tiled_file(path, header, Values{13, 0, false, false});
    }
}

/// Corpus group: parts taller than the band of rows read and written at once (32 rows of a
/// 4100-wide uncompressed float RGBA + uint part; 96 rows, four rows of 64x24 tiles, of the tiled
/// one), ending in a partial band, with data windows that start at odd rows.
void write_bands(Writer &w)
{
    {
        const std::string path = w.add("bands_scanline",
                                       Kind::Flat,
                                       "4100x100 scanlines, data (0,-3)-(4099,96), R,G,B,A float "
                                       "+ id uint (kept as the file's bits), uncompressed: four "
                                       "bands of rows, the last partial");
        Imf::Header header = make_header(box(0, 0, 4099, 95),
                                         box(0, -3, 4099, 96),
                                         Imf::NO_COMPRESSION,
                                         {{"R", Imf::FLOAT},
                                          {"G", Imf::FLOAT},
                                          {"B", Imf::FLOAT},
                                          {"A", Imf::FLOAT},
                                          {"id", Imf::UINT}});
        write_scanline_file(path, header, Values{14, 0, false, false});
    }
    {
        const std::string path =
            w.add("bands_tiled",
                  Kind::Flat,
                  "4100x200 tiled 64x24, data (5,-7)-(4104,192), R,G,B half "
                  "+ Z float, PIZ: three bands of tile rows, the last partial");
        Imf::Header header =
            make_header(box(0, 0, 4109, 199),
                        box(5, -7, 4104, 192),
                        Imf::PIZ_COMPRESSION,
                        {{"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"Z", Imf::FLOAT}});
        header.setTileDescription(Imf::TileDescription(64, 24, Imf::ONE_LEVEL, Imf::ROUND_DOWN));
        write_tiled_file(path, header, Values{15, 0, false, false});
    }
}

/// Corpus group: compressions.
void write_compressions(Writer &w)
{
    const std::pair<const char *, Imf::Compression> kinds[] = {
        {"no", Imf::NO_COMPRESSION},
        {"rle", Imf::RLE_COMPRESSION},
        {"zips", Imf::ZIPS_COMPRESSION},
        {"zip", Imf::ZIP_COMPRESSION},
        {"piz", Imf::PIZ_COMPRESSION},
        {"pxr24", Imf::PXR24_COMPRESSION},
        {"b44", Imf::B44_COMPRESSION},
        {"b44a", Imf::B44A_COMPRESSION},
        {"dwaa", Imf::DWAA_COMPRESSION},
        {"dwab", Imf::DWAB_COMPRESSION},
    };
    const bool lossy[] = {false, false, false, false, false, true, true, true, true, true};
    int part = 20;
    for (std::size_t i = 0; i < std::size(kinds); ++i) {
        const std::string name = std::string("comp_") + kinds[i].first;
        const std::string what = name + ": 40x24 mostly smooth, R,G,B,A half + Z, N.x float" +
                                 (lossy[i] ? " (lossy codec: compare decoded samples)" : "");
        const std::string path = w.add(name, Kind::Flat, what);
        auto channels = kRgbaZ;
        channels.emplace_back("N.x", Imf::FLOAT);
        const Imf::Header header =
            make_header(box(0, 0, 39, 23), box(0, 0, 39, 23), kinds[i].second, channels);
        // Mostly smooth values: random data would be stored uncompressed by every codec.
        write_scanline_file(path, header, Values{part++, 0, true, false});
    }
}

/// Corpus group: channel sets.
void write_channel_sets(Writer &w)
{
    const Box2i display = box(0, 0, 31, 23);
    write_scanline_file(w.add("rgb_no_alpha", Kind::Flat, "R,G,B half, no alpha"),
                        make_header(display, display, Imf::ZIP_COMPRESSION, kRgb),
                        Values{40, 0, false, false});
    {
        // Every attribute type OpenEXR defines that a header carries beside the picture,
        // standard names and a studio's own.
        const std::string path = w.add("attributes",
                                       Kind::Flat,
                                       "R,G,B half with attributes of every type: int, float, "
                                       "double, string, vectors, matrices, boxes, string and "
                                       "float vectors, rational, time and key codes, "
                                       "chromaticities, and the standard capDate, comments, owner, "
                                       "expTime, aperture, xDensity, utcOffset");
        Imf::Header h = make_header(display, display, Imf::PIZ_COMPRESSION, kRgb);
        h.insert("studio:int", Imf::IntAttribute(-7));
        h.insert("studio:float", Imf::FloatAttribute(0.1f));
        h.insert("studio:double", Imf::DoubleAttribute(1.0 / 3.0));
        h.insert("studio:string", Imf::StringAttribute("shot 010, take 3"));
        h.insert("studio:v2i", Imf::V2iAttribute(Imath::V2i(3, -4)));
        h.insert("studio:v2f", Imf::V2fAttribute(Imath::V2f(0.25f, -1.5f)));
        h.insert("studio:v2d", Imf::V2dAttribute(Imath::V2d(0.1, 0.2)));
        h.insert("studio:v3i", Imf::V3iAttribute(Imath::V3i(1, 2, 3)));
        h.insert("studio:v3f", Imf::V3fAttribute(Imath::V3f(0.5f, 0.25f, 0.125f)));
        h.insert("studio:v3d", Imf::V3dAttribute(Imath::V3d(0.1, 0.2, 0.3)));
        h.insert("studio:m33f", Imf::M33fAttribute(Imath::M33f(1, 2, 3, 4, 5, 6, 7, 8, 9.5f)));
        h.insert("studio:m33d", Imf::M33dAttribute(Imath::M33d(1, 2, 3, 4, 5, 6, 7, 8, 0.1)));
        Imath::M44f m44f;
        Imath::M44d m44d;
        for (int i = 0; i < 16; ++i) {
            m44f[i / 4][i % 4] = float(i) * 0.3f - 1.0f;
            m44d[i / 4][i % 4] = double(i) * 0.7 - 2.0;
        }
        h.insert("studio:m44f", Imf::M44fAttribute(m44f));
        h.insert("studio:m44d", Imf::M44dAttribute(m44d));
        h.insert("studio:box2i", Imf::Box2iAttribute(box(-3, 4, 50, 60)));
        h.insert(
            "studio:box2f",
            Imf::Box2fAttribute(Imath::Box2f(Imath::V2f(-0.5f, 0.0f), Imath::V2f(1.0f, 2.5f))));
        h.insert("studio:strings",
                 Imf::StringVectorAttribute(Imf::StringVector{"alpha", "", "gamma delta"}));
        h.insert("studio:floats",
                 Imf::FloatVectorAttribute(Imf::FloatVector{1.0f, -2.0f, 0.5f, 1e-20f, 3e30f}));
        h.insert("studio:rational", Imf::RationalAttribute(Imf::Rational(-24000, 1001)));
        Imf::addFramesPerSecond(h, Imf::Rational(24000, 1001));
        Imf::addTimeCode(h, Imf::TimeCode(1, 2, 3, 4, true, false, true, true, 5));
        Imf::addKeyCode(h, Imf::KeyCode(12, 34, 567890, 1234, 56, 4, 64));
        Imf::addChromaticities(h,
                               Imf::Chromaticities(Imath::V2f(0.7f, 0.3f),
                                                   Imath::V2f(0.2f, 0.7f),
                                                   Imath::V2f(0.15f, 0.06f),
                                                   Imath::V2f(0.3127f, 0.329f)));
        Imf::addCapDate(h, "2026:11:30 01:02:03");
        Imf::addComments(h, "a comment");
        Imf::addOwner(h, "a studio");
        Imf::addExpTime(h, 0.02f);
        Imf::addAperture(h, 2.8f);
        Imf::addXDensity(h, 72.0f);
        Imf::addUtcOffset(h, -3600.0f);
        // Types OpenImageIO reads as others or not at all: chromaticities under another name,
        // float vectors of 1, 2, 3, 8 and 16 (read as float arrays, written back as v2f, v3f,
        // m44f), compression, envmap, line order and deep state typed attributes of a
        // studio's own, a preview, and a type OpenEXR does not know (opaque).
        h.insert("studio:chromaticities",
                 Imf::ChromaticitiesAttribute(Imf::Chromaticities(Imath::V2f(0.64f, 0.33f),
                                                                  Imath::V2f(0.3f, 0.6f),
                                                                  Imath::V2f(0.15f, 0.06f),
                                                                  Imath::V2f(0.3127f, 0.329f))));
        for (int n : {1, 2, 3, 8, 16}) {
            Imf::FloatVector v;
            for (int i = 0; i < n; ++i) {
                v.push_back(0.5f * float(i) - 1.0f);
            }
            h.insert("studio:floats" + std::to_string(n), Imf::FloatVectorAttribute(v));
        }
        h.insert("studio:compression", Imf::CompressionAttribute(Imf::DWAB_COMPRESSION));
        h.insert("studio:envmap", Imf::EnvmapAttribute(Imf::ENVMAP_CUBE));
        h.insert("studio:lineOrder", Imf::LineOrderAttribute(Imf::DECREASING_Y));
        h.insert("studio:deepState", Imf::DeepImageStateAttribute(Imf::DIS_TIDY));
        Imf::PreviewImage preview(3, 2);
        for (unsigned i = 0; i < 6; ++i) {
            preview.pixels()[i] =
                Imf::PreviewRgba((unsigned char)(40 * i), (unsigned char)(255 - 40 * i), 7, 255);
        }
        h.setPreviewImage(preview);
        {
            Imf::OpaqueAttribute blob("studioBlob");
            Imf::StdISStream bytes;
            bytes.str(std::string("\x01\x00\xffopaque\x7f", 10));
            blob.readValueFrom(bytes, 10, 2);
            h.insert("studio:blob", blob);
        }
        write_scanline_file(path, h, Values{43, 0, false, false});
    }
    write_scanline_file(
        w.add("y_only", Kind::LumaOnly, "luminance only: a single Y half channel, no chroma"),
        make_header(display, display, Imf::ZIP_COMPRESSION, {{"Y", Imf::HALF}}),
        Values{41, 0, false, false});
    {
        const std::string path = w.add(
            "luma_chroma",
            Kind::LumaChroma,
            "RgbaOutputFile WRITE_YCA: Y full res, RY/BY subsampled 2x2, A; data (2,4)-(41,27)");
        const Box2i data = box(2, 4, 41, 27);
        Imf::Header header(box(0, 0, 47, 31), data);
        header.compression() = Imf::PIZ_COMPRESSION;
        // Attributes the luminance/chroma read must carry (it dropped every one).
        Imf::addComments(header, "luma comments");
        Imf::addAperture(header, 2.8f);
        Imf::addTimeCode(header, Imf::TimeCode(1, 2, 3, 4));
        header.insert("studio:double", Imf::DoubleAttribute(1.0 / 3.0));
        const int width = data.max.x - data.min.x + 1, height = data.max.y - data.min.y + 1;
        std::vector<Imf::Rgba> pixels(static_cast<std::size_t>(width) * height);
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                const std::uint32_t h = sample_hash(x + data.min.x, y + data.min.y, 0, 42, 0);
                Imf::Rgba &p = pixels[static_cast<std::size_t>(y) * width + x];
                // Smooth-ish colour with hashed detail, alpha in [0, 1].
                p.r = 0.05f + static_cast<float>(x) / 40.0f + static_cast<float>(h & 63u) / 256.0f;
                p.g = 0.05f + static_cast<float>(y) / 24.0f +
                      static_cast<float>((h >> 6) & 63u) / 256.0f;
                p.b = 0.5f + static_cast<float>((h >> 12) & 255u) / 512.0f;
                p.a = static_cast<float>((h >> 20) & 255u) / 255.0f;
            }
        }
        Imf::RgbaOutputFile out(path.c_str(), header, Imf::WRITE_YCA);
        out.setFrameBuffer(Imf::ComputeBasePointer(pixels.data(), data), 1, width);
        out.writePixels(height);
    }
    write_scanline_file(w.add("single_g", Kind::Flat, "a single half channel named G"),
                        make_header(display, display, Imf::ZIP_COMPRESSION, {{"G", Imf::HALF}}),
                        Values{43, 0, false, false});
    write_scanline_file(
        w.add("odd_name", Kind::Flat, "a single half channel named weird-name_01"),
        make_header(display, display, Imf::RLE_COMPRESSION, {{"weird-name_01", Imf::HALF}}),
        Values{44, 0, false, false});
    write_scanline_file(w.add("types_mixed",
                              Kind::Flat,
                              "R,G,B half, depth.Z float, id uint (> 2^24); first samples -0, "
                              "+-inf, denormals, max, NaN"),
                        make_header(display,
                                    display,
                                    Imf::ZIP_COMPRESSION,
                                    {{"R", Imf::HALF},
                                     {"G", Imf::HALF},
                                     {"B", Imf::HALF},
                                     {"depth.Z", Imf::FLOAT},
                                     {"id", Imf::UINT}}),
                        Values{45, 0, false, true});
}

/// Corpus group: multipart.
void write_multipart(Writer &w)
{
    const Box2i display = box(0, 0, 47, 35);
    {
        const std::string path = w.add("multipart_layers",
                                       Kind::Flat,
                                       "3 scanline parts rgba/depth/motion, own channels and data "
                                       "windows, ZIP/PIZ/RLE; camera attributes on rgba");
        std::vector<Imf::Header> headers;
        headers.push_back(
            make_header(display,
                        display,
                        Imf::ZIP_COMPRESSION,
                        {{"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}}));
        headers.back().setName("rgba");
        add_camera(headers.back());
        headers.push_back(
            make_header(display, box(4, 2, 39, 29), Imf::PIZ_COMPRESSION, {{"Z", Imf::FLOAT}}));
        headers.back().setName("depth");
        headers.push_back(make_header(display,
                                      box(-4, -4, 51, 39),
                                      Imf::RLE_COMPRESSION,
                                      {{"motion.X", Imf::FLOAT}, {"motion.Y", Imf::FLOAT}}));
        headers.back().setName("motion");
        for (Imf::Header &h : headers) h.setType(Imf::SCANLINEIMAGE);
        write_multipart_file(path, headers);
    }
    const Imf::StringVector views = {"left", "right"};
    const Box2i stereo_display = box(0, 0, 31, 23);
    {
        const std::string path = w.add("stereo_multipart",
                                       Kind::Flat,
                                       "8 parts layer x view (rgba/depth/mask/forward . left/"
                                       "right) with view attributes and multiView on every part");
        struct Layer {
            const char *name;
            std::vector<std::pair<std::string, Imf::PixelType>> channels;
            Box2i data;
        };
        const Layer layers[] = {
            {"rgba",
             {{"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}},
             stereo_display},
            {"depth", {{"Z", Imf::FLOAT}}, box(2, 2, 29, 21)},
            {"mask", {{"whitebarmask.mask", Imf::HALF}}, stereo_display},
            {"forward", {{"forward.u", Imf::FLOAT}, {"forward.v", Imf::FLOAT}}, stereo_display},
        };
        std::vector<Imf::Header> headers;
        for (const Layer &layer : layers) {
            for (const std::string &view : views) {
                headers.push_back(
                    make_header(stereo_display, layer.data, Imf::ZIP_COMPRESSION, layer.channels));
                headers.back().setName(std::string(layer.name) + "." + view);
                headers.back().setType(Imf::SCANLINEIMAGE);
                headers.back().setView(view);
                Imf::addMultiView(headers.back(), views);
            }
        }
        write_multipart_file(path, headers);
    }
    {
        const std::string path =
            w.add("stereo_singlepart",
                  Kind::Flat,
                  "one part, multiView [left,right]: R,G,B,A,Z,N.X (left, default) and "
                  "right.R..right.Z, N.right.X");
        std::vector<std::pair<std::string, Imf::PixelType>> channels = kRgbaZ;
        for (const auto &[name, type] : kRgbaZ) channels.emplace_back("right." + name, type);
        channels.emplace_back("N.X", Imf::FLOAT);
        channels.emplace_back("N.right.X", Imf::FLOAT);
        Imf::Header header =
            make_header(stereo_display, stereo_display, Imf::ZIP_COMPRESSION, channels);
        Imf::addMultiView(header, views);
        add_camera(header);
        write_scanline_file(path, header, Values{50, 0, false, false});
    }
}

/// Corpus group: deep.
void write_deep(Writer &w)
{
    const std::vector<std::pair<std::string, Imf::PixelType>> half_rgba = {
        {"R", Imf::HALF}, {"G", Imf::HALF}, {"B", Imf::HALF}, {"A", Imf::HALF}, {"Z", Imf::FLOAT}};
    const std::vector<std::pair<std::string, Imf::PixelType>> float_rgba = {{"R", Imf::FLOAT},
                                                                            {"G", Imf::FLOAT},
                                                                            {"B", Imf::FLOAT},
                                                                            {"A", Imf::FLOAT},
                                                                            {"Z", Imf::FLOAT}};
    {
        const std::string path = w.add("deep_scanline",
                                       Kind::Deep,
                                       "deep scanline 16x12, R,G,B,A half + Z float, 0..4 samples "
                                       "unsorted in Z, ties, partial alpha, empty pixels, ZIPS");
        const Box2i window = box(0, 0, 15, 11);
        Imf::Header header = make_header(window, window, Imf::ZIPS_COMPRESSION, half_rgba);
        header.setType(Imf::DEEPSCANLINE);
        add_camera(header);
        DeepPlanes d = deep_values(header.channels(), window, 60);
        Imf::DeepScanLineOutputFile out(path.c_str(), header);
        out.setFrameBuffer(deep_frame_buffer_for(d));
        out.writePixels(d.height);
    }
    {
        const std::string path =
            w.add("deep_tiled",
                  Kind::Deep,
                  "deep tiled 8x8, data (-3,2)-(16,15) partial tiles, R,G,B,A,Z "
                  "float, 0..4 unsorted samples, RLE");
        const Box2i window = box(-3, 2, 16, 15);
        Imf::Header header =
            make_header(box(0, 0, 15, 15), window, Imf::RLE_COMPRESSION, float_rgba);
        header.setType(Imf::DEEPTILE);
        header.setTileDescription(Imf::TileDescription(8, 8, Imf::ONE_LEVEL, Imf::ROUND_DOWN));
        DeepPlanes d = deep_values(header.channels(), window, 61);
        Imf::DeepTiledOutputFile out(path.c_str(), header);
        out.setFrameBuffer(deep_frame_buffer_for(d));
        out.writeTiles(0, out.numXTiles(0) - 1, 0, out.numYTiles(0) - 1, 0, 0);
    }
}

// ---------------------------------------------------------------------------------------------
// Reading and comparing
// ---------------------------------------------------------------------------------------------

/// One level of one part, read completely.
struct LevelData {
    int lx = 0, ly = 0;
    Box2i window;
    std::vector<Plane> planes;  // Flat parts.
    DeepPlanes deep;            // Deep parts.
};

/// The part type, also for single-part files without a "type" attribute.
std::string type_of(const Imf::Header &header)
{
    if (header.hasType()) return header.type();
    return header.hasTileDescription() ? Imf::TILEDIMAGE : Imf::SCANLINEIMAGE;
}

/// Read a deep level: counts first, then the samples.
template <class Part, class ReadCounts, class ReadSamples>
DeepPlanes read_deep(Part &part,
                     const Box2i &window,
                     ReadCounts read_counts,
                     ReadSamples read_samples)
{
    DeepPlanes d = deep_planes_for(part.header().channels(), window);
    part.setFrameBuffer(deep_frame_buffer_for(d));
    read_counts();
    allocate_samples(d);
    read_samples();
    return d;
}

/// Every level of part `index`, read in the file's own pixel types.
std::vector<LevelData> read_part(Imf::MultiPartInputFile &file, int index)
{
    const Imf::Header &header = file.header(index);
    const std::string type = type_of(header);
    std::vector<LevelData> levels;
    if (type == Imf::SCANLINEIMAGE) {
        Imf::InputPart part(file, index);
        LevelData level;
        level.window = header.dataWindow();
        level.planes = planes_for(header.channels(), level.window);
        part.setFrameBuffer(frame_buffer_for(level.planes));
        part.readPixels(level.window.min.y, level.window.max.y);
        levels.push_back(std::move(level));
    } else if (type == Imf::TILEDIMAGE) {
        Imf::TiledInputPart part(file, index);
        for (auto [lx, ly] : levels_of(part.levelMode(), part.numXLevels(), part.numYLevels())) {
            LevelData level;
            level.lx = lx;
            level.ly = ly;
            level.window = part.dataWindowForLevel(lx, ly);
            level.planes = planes_for(header.channels(), level.window);
            part.setFrameBuffer(frame_buffer_for(level.planes));
            part.readTiles(0, part.numXTiles(lx) - 1, 0, part.numYTiles(ly) - 1, lx, ly);
            levels.push_back(std::move(level));
        }
    } else if (type == Imf::DEEPSCANLINE) {
        Imf::DeepScanLineInputPart part(file, index);
        LevelData level;
        level.window = header.dataWindow();
        const int y0 = level.window.min.y, y1 = level.window.max.y;
        level.deep = read_deep(
            part,
            level.window,
            [&] { part.readPixelSampleCounts(y0, y1); },
            [&] { part.readPixels(y0, y1); });
        levels.push_back(std::move(level));
    } else if (type == Imf::DEEPTILE) {
        Imf::DeepTiledInputPart part(file, index);
        for (auto lxy : levels_of(part.levelMode(), part.numXLevels(), part.numYLevels())) {
            const int lx = lxy.first, ly = lxy.second;  // Lambdas below capture them.
            LevelData level;
            level.lx = lx;
            level.ly = ly;
            level.window = part.dataWindowForLevel(lx, ly);
            const int tx = part.numXTiles(lx) - 1, ty = part.numYTiles(ly) - 1;
            level.deep = read_deep(
                part,
                level.window,
                [&] { part.readPixelSampleCounts(0, tx, 0, ty, lx, ly); },
                [&] { part.readTiles(0, tx, 0, ty, lx, ly); });
            levels.push_back(std::move(level));
        }
    } else {
        throw std::runtime_error("unknown part type '" + type + "'");
    }
    return levels;
}

/// "0x3c00" for a half, "0x3f800000" for a float or uint sample, and the value.
std::string hex_of(Imf::PixelType type, const char *bytes)
{
    char text[64];
    if (type == Imf::HALF) {
        std::uint16_t bits;
        std::memcpy(&bits, bytes, 2);
        half h;
        h.setBits(bits);
        std::snprintf(text, sizeof text, "0x%04x (%.9g)", bits, static_cast<double>(float(h)));
    } else {
        std::uint32_t bits;
        std::memcpy(&bits, bytes, 4);
        float f;
        std::memcpy(&f, bytes, 4);
        if (type == Imf::FLOAT) {
            std::snprintf(text, sizeof text, "0x%08x (%.9g)", bits, static_cast<double>(f));
        } else {
            std::snprintf(text, sizeof text, "0x%08x (%u)", bits, bits);
        }
    }
    return text;
}

/// "part 1 'depth'" or "part 0".
std::string part_label(int index, const Imf::Header &header)
{
    std::string label = "part " + std::to_string(index);
    if (header.hasName()) label += " '" + header.name() + "'";
    return label;
}

/// "(x0,y0)-(x1,y1)".
std::string box_text(const Box2i &b)
{
    std::ostringstream s;
    s << "(" << b.min.x << "," << b.min.y << ")-(" << b.max.x << "," << b.max.y << ")";
    return s.str();
}

/// "[a,b]".
std::string join(const Imf::StringVector &v)
{
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? "," : "") + v[i];
    return s + "]";
}

/// Name of a level mode.
std::string level_mode_text(Imf::LevelMode m)
{
    return m == Imf::ONE_LEVEL       ? "ONE_LEVEL"
           : m == Imf::MIPMAP_LEVELS ? "MIPMAP_LEVELS"
           : m == Imf::RIPMAP_LEVELS ? "RIPMAP_LEVELS"
                                     : "level mode " + std::to_string(static_cast<int>(m));
}

/// "16x16 MIPMAP_LEVELS ROUND_DOWN".
std::string tile_text(const Imf::TileDescription &t)
{
    return std::to_string(t.xSize) + "x" + std::to_string(t.ySize) + " " + level_mode_text(t.mode) +
           (t.roundingMode == Imf::ROUND_UP ? " ROUND_UP" : " ROUND_DOWN");
}

/// Name of a pixel type.
std::string type_name(Imf::PixelType t)
{
    return t == Imf::HALF ? "HALF" : t == Imf::FLOAT ? "FLOAT" : t == Imf::UINT ? "UINT" : "?";
}

/// "Z FLOAT sampling 1x1" (+ " pLinear").
std::string channel_text(const std::string &name, const Imf::Channel &c)
{
    return name + " " + type_name(c.type) + " sampling " + std::to_string(c.xSampling) + "x" +
           std::to_string(c.ySampling) + (c.pLinear ? " pLinear" : "");
}

/// First header difference of part `i`, or "".
std::string compare_headers(int i, const Imf::Header &a, const Imf::Header &b, bool single)
{
    const std::string part = part_label(i, a);
    if (a.hasName() != b.hasName() && !(single && !a.hasName())) {
        return part + ": name " + (a.hasName() ? "'" + a.name() + "'" : "(none)") + " vs " +
               (b.hasName() ? "'" + b.name() + "'" : "(none)");
    }
    if (a.hasName() && a.name() != b.name()) {
        return part + ": name '" + a.name() + "' vs '" + b.name() + "'";
    }
    if (a.hasView() != b.hasView() || (a.hasView() && a.view() != b.view())) {
        return part + ": view " + (a.hasView() ? "'" + a.view() + "'" : "(none)") + " vs " +
               (b.hasView() ? "'" + b.view() + "'" : "(none)");
    }
    if (type_of(a) != type_of(b)) return part + ": type " + type_of(a) + " vs " + type_of(b);
    if (a.dataWindow() != b.dataWindow()) {
        return part + ": data window " + box_text(a.dataWindow()) + " vs " +
               box_text(b.dataWindow());
    }
    if (a.displayWindow() != b.displayWindow()) {
        return part + ": display window " + box_text(a.displayWindow()) + " vs " +
               box_text(b.displayWindow());
    }
    if (Imf::isTiled(type_of(a))) {
        const Imf::TileDescription &ta = a.tileDescription(), &tb = b.tileDescription();
        if (ta.xSize != tb.xSize || ta.ySize != tb.ySize || ta.mode != tb.mode ||
            ta.roundingMode != tb.roundingMode) {
            return part + ": tiles " + tile_text(ta) + " vs " + tile_text(tb);
        }
    }
    auto ia = a.channels().begin(), ib = b.channels().begin();
    for (; ia != a.channels().end() && ib != b.channels().end(); ++ia, ++ib) {
        const Imf::Channel &ca = ia.channel(), &cb = ib.channel();
        if (std::string(ia.name()) != ib.name() || ca.type != cb.type ||
            ca.xSampling != cb.xSampling || ca.ySampling != cb.ySampling ||
            ca.pLinear != cb.pLinear) {
            return part + ": channel " + channel_text(ia.name(), ca) + " vs " +
                   channel_text(ib.name(), cb);
        }
    }
    if (ia != a.channels().end()) return part + ": channel " + ia.name() + " missing in B";
    if (ib != b.channels().end()) return part + ": extra channel " + ib.name() + " in B";
    if (const auto *mv = a.findTypedAttribute<Imf::StringVectorAttribute>("multiView")) {
        const auto *mb = b.findTypedAttribute<Imf::StringVectorAttribute>("multiView");
        if (!mb) return part + ": multiView " + join(mv->value()) + " missing in B";
        if (mv->value() != mb->value()) {
            return part + ": multiView " + join(mv->value()) + " vs " + join(mb->value());
        }
    }
    if (const auto *ea = a.findTypedAttribute<Imf::EnvmapAttribute>("envmap")) {
        const auto *eb = b.findTypedAttribute<Imf::EnvmapAttribute>("envmap");
        if (!eb) return part + ": envmap missing in B";
        if (ea->value() != eb->value()) {
            return part + ": envmap " + std::to_string(static_cast<int>(ea->value())) + " vs " +
                   std::to_string(static_cast<int>(eb->value()));
        }
    }
    return "";
}

/// First sample difference between two reads of the same level, or "".
std::string compare_level(const std::string &part, const LevelData &a, const LevelData &b)
{
    const std::string level = " level (" + std::to_string(a.lx) + "," + std::to_string(a.ly) + ")";
    if (a.window != b.window) {
        return part + level + ": window " + box_text(a.window) + " vs " + box_text(b.window);
    }
    for (std::size_t c = 0; c < a.planes.size() && c < b.planes.size(); ++c) {
        const Plane &pa = a.planes[c], &pb = b.planes[c];
        if (pa.bytes.size() != pb.bytes.size()) {
            return part + " channel " + pa.name + level + ": sample count differs";
        }
        if (std::memcmp(pa.bytes.data(), pb.bytes.data(), pa.bytes.size()) == 0) continue;
        const std::size_t size = pixel_size(pa.channel.type);
        for (std::size_t k = 0; k * size < pa.bytes.size(); ++k) {
            const char *va = pa.bytes.data() + k * size, *vb = pb.bytes.data() + k * size;
            if (std::memcmp(va, vb, size) == 0) continue;
            const int x = pa.x_first + static_cast<int>(k % pa.nx) * pa.channel.xSampling;
            const int y = pa.y_first + static_cast<int>(k / pa.nx) * pa.channel.ySampling;
            return part + " channel " + pa.name + level + " pixel " + std::to_string(x) + " " +
                   std::to_string(y) + ": A=" + hex_of(pa.channel.type, va) +
                   " B=" + hex_of(pa.channel.type, vb);
        }
    }
    const DeepPlanes &da = a.deep, &db = b.deep;
    for (std::size_t i = 0; i < da.counts.size() && i < db.counts.size(); ++i) {
        if (da.counts[i] == db.counts[i]) continue;
        const int x = da.window.min.x + static_cast<int>(i) % da.width;
        const int y = da.window.min.y + static_cast<int>(i) / da.width;
        return part + level + " pixel " + std::to_string(x) + " " + std::to_string(y) +
               ": deep sample count A=" + std::to_string(da.counts[i]) +
               " B=" + std::to_string(db.counts[i]);
    }
    for (std::size_t c = 0; c < da.names.size() && c < db.names.size(); ++c) {
        const std::size_t size = pixel_size(da.types[c]);
        for (std::size_t i = 0; i < da.counts.size(); ++i) {
            for (unsigned int s = 0; s < da.counts[i]; ++s) {
                const char *va = da.pointers[c][i] + s * size, *vb = db.pointers[c][i] + s * size;
                if (std::memcmp(va, vb, size) == 0) continue;
                const int x = da.window.min.x + static_cast<int>(i) % da.width;
                const int y = da.window.min.y + static_cast<int>(i) / da.width;
                return part + " channel " + da.names[c] + level + " pixel " + std::to_string(x) +
                       " " + std::to_string(y) + " sample " + std::to_string(s) +
                       ": A=" + hex_of(da.types[c], va) + " B=" + hex_of(db.types[c], vb);
            }
        }
    }
    return "";
}

/// First difference between two files, or "" (throws on read errors).
std::string compare_files(const std::string &path_a, const std::string &path_b)
{
    Imf::MultiPartInputFile a(path_a.c_str()), b(path_b.c_str());
    if (a.parts() != b.parts()) {
        return "parts: A has " + std::to_string(a.parts()) + ", B has " + std::to_string(b.parts());
    }
    const bool single = a.parts() == 1;
    for (int i = 0; i < a.parts(); ++i) {
        const std::string diff = compare_headers(i, a.header(i), b.header(i), single);
        if (!diff.empty()) return diff;
    }
    for (int i = 0; i < a.parts(); ++i) {
        const std::vector<LevelData> la = read_part(a, i), lb = read_part(b, i);
        const std::string part = part_label(i, a.header(i));
        if (la.size() != lb.size()) {
            return part + ": levels A=" + std::to_string(la.size()) +
                   " B=" + std::to_string(lb.size());
        }
        for (std::size_t l = 0; l < la.size(); ++l) {
            const std::string diff = compare_level(part, la[l], lb[l]);
            if (!diff.empty()) return diff;
        }
    }
    return "";
}

/// `text` on one line.
std::string one_line(std::string text)
{
    std::replace(text.begin(), text.end(), '\n', ' ');
    std::replace(text.begin(), text.end(), '\r', ' ');
    return text;
}

/// The value of deep sample `s` of pixel `i` of channel `c` as a float.
float deep_float(const DeepPlanes &d, std::size_t c, std::size_t i, unsigned int s)
{
    const char *p = d.pointers[c][i] + s * pixel_size(d.types[c]);
    if (d.types[c] == Imf::HALF) {
        std::uint16_t bits;
        std::memcpy(&bits, p, 2);
        half h;
        h.setBits(bits);
        return float(h);
    }
    if (d.types[c] == Imf::FLOAT) {
        float f;
        std::memcpy(&f, p, 4);
        return f;
    }
    std::uint32_t u;
    std::memcpy(&u, p, 4);
    return static_cast<float>(u);
}

}  // namespace

std::vector<Entry> write_corpus(const std::string &dir)
{
    std::filesystem::create_directories(dir);
    Writer w(dir);
    write_windows(w);
    write_tiled(w);
    write_bands(w);
    write_compressions(w);
    write_channel_sets(w);
    write_multipart(w);
    write_deep(w);
    return w.take();
}

namespace {

/// An attribute's value as the bytes OpenEXR writes for it.
class ValueBytes : public Imf::OStream {
   public:
    ValueBytes() : Imf::OStream("attribute value") {}
    void write(const char c[], int n) override { bytes.append(c, std::size_t(n)); }
    uint64_t tellp() override { return bytes.size(); }
    void seekp(uint64_t) override {}
    std::string bytes;
};

std::string value_bytes(const Imf::Attribute &a)
{
    ValueBytes out;
    a.writeValueTo(out, 2);
    return out.bytes;
}

}  // namespace

std::string compare_attributes(const std::string &a,
                               const std::string &b,
                               const std::vector<std::string> &ignore)
{
    try {
        Imf::MultiPartInputFile fa(a.c_str()), fb(b.c_str());
        if (fa.parts() != fb.parts()) {
            return "parts: " + std::to_string(fa.parts()) + " vs " + std::to_string(fb.parts());
        }
        auto ignored = [&](const char *name) {
            return std::find(ignore.begin(), ignore.end(), name) != ignore.end();
        };
        for (int p = 0; p < fa.parts(); ++p) {
            const Imf::Header &ha = fa.header(p), &hb = fb.header(p);
            for (auto it = ha.begin(); it != ha.end(); ++it) {
                if (ignored(it.name())) {
                    continue;
                }
                const Imf::Attribute *other =
                    hb.find(it.name()) != hb.end() ? &hb[it.name()] : nullptr;
                if (!other) {
                    return "part " + std::to_string(p) + ": \"" + it.name() + "\" missing";
                }
                if (std::string(other->typeName()) != it.attribute().typeName()) {
                    return "part " + std::to_string(p) + ": \"" + it.name() + "\" is " +
                           other->typeName() + ", was " + it.attribute().typeName();
                }
                if (value_bytes(*other) != value_bytes(it.attribute())) {
                    return "part " + std::to_string(p) + ": \"" + it.name() + "\" differs";
                }
            }
            for (auto it = hb.begin(); it != hb.end(); ++it) {
                if (!ignored(it.name()) && ha.find(it.name()) == ha.end()) {
                    return "part " + std::to_string(p) + ": \"" + it.name() + "\" added";
                }
            }
        }
        return "";
    } catch (const std::exception &e) {
        return std::string("cannot compare: ") + e.what();
    }
}

std::string compare_exr(const std::string &a, const std::string &b)
{
    try {
        return one_line(compare_files(a, b));
    } catch (const std::exception &e) {
        return one_line(std::string("error: ") + e.what());
    } catch (...) {
        return "error: unknown exception";
    }
}

Flat flatten_deep(const std::string &path)
{
    Imf::MultiPartInputFile file(path.c_str());
    const std::string type = type_of(file.header(0));
    if (!Imf::isDeepData(type)) throw std::runtime_error(path + ": part 0 is not deep");
    const std::vector<LevelData> levels = read_part(file, 0);
    const DeepPlanes &d = levels.front().deep;
    auto find = [&](const char *name) {
        const auto it = std::find(d.names.begin(), d.names.end(), name);
        return it == d.names.end() ? -1 : static_cast<int>(it - d.names.begin());
    };
    const int r = find("R"), g = find("G"), b = find("B"), a = find("A"), zc = find("Z");
    if (zc < 0) throw std::runtime_error(path + ": part 0 has no Z channel");
    const auto z = static_cast<std::size_t>(zc);

    Flat flat{d.window.min.x, d.window.min.y, d.width, d.height, {}};
    flat.rgbaz.reserve(d.counts.size() * 5);
    std::vector<unsigned int> order;
    for (std::size_t i = 0; i < d.counts.size(); ++i) {
        order.resize(d.counts[i]);
        std::iota(order.begin(), order.end(), 0u);
        std::stable_sort(order.begin(), order.end(), [&](unsigned int l, unsigned int m) {
            return deep_float(d, z, i, l) < deep_float(d, z, i, m);
        });
        auto value = [&](int c, unsigned int s, float missing) {
            return c < 0 ? missing : deep_float(d, static_cast<std::size_t>(c), i, s);
        };
        float cr = 0.0f, cg = 0.0f, cb = 0.0f, acc = 0.0f;
        float zmin = std::numeric_limits<float>::infinity();
        for (unsigned int s : order) {
            const float t = 1.0f - acc;
            cr += t * value(r, s, 0.0f);
            cg += t * value(g, s, 0.0f);
            cb += t * value(b, s, 0.0f);
            acc += t * value(a, s, 1.0f);
            zmin = std::min(zmin, deep_float(d, z, i, s));
        }
        flat.rgbaz.insert(flat.rgbaz.end(), {cr, cg, cb, acc, zmin});
    }
    return flat;
}

Rgba rgba_of(const std::string &path)
{
    Imf::RgbaInputFile in(path.c_str());
    const Box2i window = in.dataWindow();
    const int width = window.max.x - window.min.x + 1, height = window.max.y - window.min.y + 1;
    std::vector<Imf::Rgba> pixels(static_cast<std::size_t>(width) * height);
    in.setFrameBuffer(Imf::ComputeBasePointer(pixels.data(), window), 1, width);
    in.readPixels(window.min.y, window.max.y);
    Rgba out{window.min.x, window.min.y, width, height, {}};
    out.rgba.reserve(pixels.size() * 4);
    for (const Imf::Rgba &p : pixels) {
        out.rgba.insert(out.rgba.end(), {float(p.r), float(p.g), float(p.b), float(p.a)});
    }
    return out;
}

}  // namespace posthaste::test::corpus
