// Writing frames: EXR through OpenImageIO, in the layout of the file the frame was read from
// (parts, views, channel names and pixel types, windows, tiles and untouched mip levels), or
// rebuilt with canonical channel names; 8-bit previews (atomic writes: atomic_file.cpp).

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>

#include "core/error.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "io/color.h"
#include "io/image_file.h"
#include "io/io_detail.h"
#include "io/png_write.h"
#include "io/source_file.h"
#include "io/write_layout.h"

namespace posthaste {

using namespace io_detail;

namespace {

namespace fs = std::filesystem;

/// Convert `count` floats to `type` at dst + i * stride.
void store_values(
    const float *v, int count, OIIO::TypeDesc type, unsigned char *dst, std::size_t stride)
{
    if (type.basetype == OIIO::TypeDesc::HALF) {
        floats_to_halves(v, 1, count, dst, stride);
    } else if (type.basetype == OIIO::TypeDesc::UINT) {
        for (int i = 0; i < count; ++i, dst += stride) {
            const float f = v[i];
            const std::uint32_t u = !(f > 0.0f)          ? 0u
                                    : f >= 4294967295.0f ? 0xffffffffu
                                                         : std::uint32_t(std::lround(f));
            std::memcpy(dst, &u, sizeof(u));
        }
    } else {
        scatter_floats(v, 1, count, dst, stride);
    }
}

/// The part's channels as floats over its data window (W x H x C), for making mip levels.
std::vector<float> part_floats(const OutPart &part, const Frame &frame)
{
    const Rect &dw = part.data_window, fw = frame.data_window;
    const std::size_t nch = part.channels.size();
    std::vector<float> out(std::size_t(dw.width()) * std::size_t(dw.height()) * nch, 0.0f);
    parallel_for(0, dw.height(), [&](int y) {
        const int ay = y + dw.y0;
        for (std::size_t ci = 0; ci < nch; ++ci) {
            const OutChannel &c = part.channels[ci];
            float *dst = out.data() + std::size_t(y) * std::size_t(dw.width()) * nch + ci;
            if (c.raw) {
                const std::size_t size = c.type.size();
                convert_channel(c.raw->data() + std::size_t(y) * std::size_t(dw.width()) * size,
                                size,
                                c.type,
                                dst,
                                nch,
                                dw.width());
                continue;
            }
            for (int x = 0; x < dw.width(); ++x) {
                const int ax = x + dw.x0;
                if (ay >= fw.y0 && ay < fw.y1 && ax >= fw.x0 && ax < fw.x1) {
                    const float v = c.image->at(ax - fw.x0, ay - fw.y0, c.k);
                    dst[std::size_t(x) * nch] = (v - c.offset) / c.scale;
                }
            }
        }
    });
    return out;
}

/// The next MIP level (OpenEXR's round-down sizes): each pixel the mean of the 2x2 (or 2x1,
/// 1x2) block above it; the odd last row or column of the level above is dropped, as maketx's
/// box filter does for round-down levels.
std::vector<float> half_size(const std::vector<float> &src, int w, int h, int nch, int &nw, int &nh)
{
    nw = std::max(1, w / 2);
    nh = std::max(1, h / 2);
    std::vector<float> dst(std::size_t(nw) * std::size_t(nh) * std::size_t(nch));
    const int fx = w > 1 ? 2 : 1, fy = h > 1 ? 2 : 1;
    for (int y = 0; y < nh; ++y) {
        for (int x = 0; x < nw; ++x) {
            for (int c = 0; c < nch; ++c) {
                float sum = 0.0f;
                for (int j = 0; j < fy; ++j) {
                    for (int i = 0; i < fx; ++i) {
                        sum += src[(std::size_t(y * fy + j) * std::size_t(w) +
                                    std::size_t(x * fx + i)) *
                                       std::size_t(nch) +
                                   std::size_t(c)];
                    }
                }
                dst[(std::size_t(y) * std::size_t(nw) + std::size_t(x)) * std::size_t(nch) +
                    std::size_t(c)] = sum / float(fx * fy);
            }
        }
    }
    return dst;
}

/// A part's pixels at native types, interleaved as the file stores them, packed a band of rows
/// at a time so that the writer never holds the whole part a second time.
class PartPacker {
   public:
    PartPacker(const OutPart &part, const Frame &frame)
        : part_(part), frame_(frame), run_(part.channels.size(), 1)
    {
        for (const OutChannel &c : part.channels) {
            offsets_.push_back(pixel_bytes_);
            pixel_bytes_ += c.type.size();
        }
        // Runs of channels that are consecutive channels of one image, same type, written as
        // they are: converted together (four halves at once for RGBA).
        for (std::size_t ci = part.channels.size(); ci-- > 1;) {
            const OutChannel &a = part.channels[ci - 1], &b = part.channels[ci];
            if (!a.raw && !b.raw && a.image && a.image == b.image && b.k == a.k + 1 &&
                a.type == b.type && a.scale == 1.0f && a.offset == 0.0f && b.scale == 1.0f &&
                b.offset == 0.0f) {
                run_[ci - 1] = run_[ci] + 1;
            }
        }
        const Rect &dw = part.data_window, &fw = frame.data_window;
        inside_ = fw.x0 <= dw.x0 && dw.x1 <= fw.x1 && fw.y0 <= dw.y0 && dw.y1 <= fw.y1;
    }

    std::size_t row_bytes() const { return pixel_bytes_ * std::size_t(part_.data_window.width()); }

    /// Rows [y_begin, y_end) of the data window (0 = its first row) into dst, in parallel.
    void pack(int y_begin, int y_end, unsigned char *dst) const
    {
        parallel_for(y_begin, y_end, [&](int y) {
            pack_row(y, dst + std::size_t(y - y_begin) * row_bytes());
        });
    }

   private:
    void pack_row(int y, unsigned char *row) const
    {
        const Rect &dw = part_.data_window, &fw = frame_.data_window;
        const int ay = y + dw.y0;
        std::vector<float> tmp;
        for (std::size_t ci = 0; ci < part_.channels.size();) {
            const OutChannel &c = part_.channels[ci];
            unsigned char *dst = row + offsets_[ci];
            const std::size_t size = c.type.size();
            if (c.raw) {
                const unsigned char *src =
                    c.raw->data() + std::size_t(y) * std::size_t(dw.width()) * size;
                for (int x = 0; x < dw.width(); ++x) {
                    std::memcpy(
                        dst + std::size_t(x) * pixel_bytes_, src + std::size_t(x) * size, size);
                }
                ++ci;
                continue;
            }
            const Image &img = *c.image;
            const bool identity = c.scale == 1.0f && c.offset == 0.0f;
            if (inside_ && identity && c.type.basetype != OIIO::TypeDesc::UINT) {
                const int n = int(run_[ci]);
                const float *src = img.pixel(dw.x0 - fw.x0, ay - fw.y0) + c.k;
                if (c.type.basetype == OIIO::TypeDesc::HALF) {
                    floats_to_halves(src, n, dw.width(), dst, pixel_bytes_, img.channels());
                } else {
                    scatter_floats(src, n, dw.width(), dst, pixel_bytes_, img.channels());
                }
                ci += std::size_t(n);
                continue;
            }
            tmp.resize(std::size_t(dw.width()));
            const bool whole_row = ay >= fw.y0 && ay < fw.y1;
            for (int x = 0; x < dw.width(); ++x) {
                const int ax = x + dw.x0;
                float v = 0.0f;
                if (whole_row && ax >= fw.x0 && ax < fw.x1) {
                    v = img.at(ax - fw.x0, ay - fw.y0, c.k);
                }
                tmp[std::size_t(x)] = identity ? v : (v - c.offset) / c.scale;
            }
            store_values(tmp.data(), dw.width(), c.type, dst, pixel_bytes_);
            ++ci;
        }
    }

    const OutPart &part_;
    const Frame &frame_;
    std::vector<std::size_t> offsets_;
    std::vector<std::size_t> run_;
    std::size_t pixel_bytes_ = 0;
    bool inside_ = false;
};

/// Level 0 of a part, packed and written band by band.
void write_part_pixels(OIIO::ImageOutput &out,
                       const OutPart &part,
                       const Frame &frame,
                       const std::string &path)
{
    const PartPacker packer(part, frame);
    const Rect &dw = part.data_window;
    const int band = std::min(band_rows(part.spec, packer.row_bytes()), dw.height());
    auto buf =
        std::make_unique_for_overwrite<unsigned char[]>(packer.row_bytes() * std::size_t(band));
    for (int y = 0; y < dw.height(); y += band) {
        const int y_end = std::min(y + band, dw.height());
        packer.pack(y, y_end, buf.get());
        const bool ok =
            part.spec.tile_width > 0
                ? out.write_tiles(
                      dw.x0, dw.x1, dw.y0 + y, dw.y0 + y_end, 0, 1, OIIO::TypeUnknown, buf.get())
                : out.write_scanlines(dw.y0 + y, dw.y0 + y_end, 0, OIIO::TypeUnknown, buf.get());
        if (!ok) {
            throw_runtime(path, ": cannot write pixels: ", out.geterror());
        }
    }
}

/// The extension of `path` in lower case (".exr").
std::string lower_extension(const std::string &path)
{
    std::string ext = fs::path(path).extension().string();
    std::transform(
        ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext;
}

bool is_png_path(const std::string &path)
{
    return lower_extension(path) == ".png";
}

/// Write 8-bit interleaved pixels atomically: a PNG through the parallel encoder (png_write.h),
/// any other format through OpenImageIO.
void write_8bit(const std::string &path,
                const std::vector<std::uint8_t> &buf,
                int w,
                int h,
                int nch,
                int png_level,
                PngFilter png_filter)
{
    if (is_png_path(path)) {
        const std::vector<std::uint8_t> png =
            encode_png(buf.data(), w, h, nch, png_level, png_filter, path);
        write_file_bytes(path, png.data(), png.size());
        return;
    }
    atomic_write(path, [&](const std::string &tmp) {
        auto out = OIIO::ImageOutput::create(path);
        if (!out) {
            throw_runtime(path, ": no writer for this file type: ", OIIO::geterror());
        }
        OIIO::ImageSpec spec(w, h, nch, OIIO::TypeDesc::UINT8);
        spec.attribute("oiio:ColorSpace", "sRGB");
        if (!out->open(tmp, spec) || !out->write_image(OIIO::TypeDesc::UINT8, buf.data()) ||
            !out->close()) {
            throw_runtime(path, ": cannot write preview: ", out->geterror());
        }
    });
}

}  // namespace

bool is_exr_path(const std::string &path)
{
    const std::string ext = lower_extension(path);
    return ext == ".exr" || ext == ".sxr" || ext == ".mxr";
}

bool is_lossy_compression(const std::string &compression)
{
    const std::string base = compression.substr(0, compression.find(':'));
    return base == "dwaa" || base == "dwab" || base == "pxr24" || base == "b44" || base == "b44a";
}

void check_compression(const std::string &compression, const std::string &where)
{
    static const std::vector<std::string> kNames = {
        "auto", "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};
    std::string base = compression.substr(0, compression.find(':'));
    if (std::find(kNames.begin(), kNames.end(), base) == kNames.end()) {
        throw_usage(where,
                    ": unknown EXR compression \"",
                    compression,
                    "\" (expected auto, none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab)");
    }
    if (auto colon = compression.find(':'); colon != std::string::npos) {
        const std::string level = compression.substr(colon + 1);
        if (base.rfind("dwa", 0) != 0 && base != "zip" && base != "zips") {
            throw_usage(where, ": compression \"", base, "\" takes no level");
        }
        char *end = nullptr;
        const double v = std::strtod(level.c_str(), &end);
        if (level.empty() || *end != '\0' || !(v > 0.0) || v > 1000.0) {
            throw_usage(where, ": invalid compression level \"", level, "\"");
        }
    }
}

void write_exr(const Frame &frame, const std::string &path, const WriteOptions &options)
{
    check_compression(options.compression, path);
    const std::vector<std::string> names = passes_to_write(frame, options);
    if (names.empty()) {
        throw_runtime(path, ": nothing to write: the frame has no passes");
    }
    ExrLayout layout = options.layout;
    if (options.multipart) {
        layout = ExrLayout::Multipart;
    }
    std::vector<OutPart> parts =
        layout == ExrLayout::Auto && frame.source
            ? source_layout(frame, names, options, path)
            : rebuilt_layout(frame, names, layout == ExrLayout::Multipart, options, path);
    if (parts.empty()) {
        throw_runtime(path, ": nothing to write: the frame has no passes");
    }
    for (const OutPart &p : parts) {
        if (p.channels.size() > std::size_t(kMaxChannels) * 4) {
            throw_runtime(path, ": too many channels (", p.channels.size(), ")");
        }
    }
    finish_specs(parts, frame, options, path);

    atomic_write(path, [&](const std::string &tmp) {
        auto out = OIIO::ImageOutput::create("exr");
        if (!out) {
            throw_runtime(path, ": no EXR writer: ", OIIO::geterror());
        }
        std::vector<OIIO::ImageSpec> specs;
        for (const OutPart &p : parts) {
            specs.push_back(p.spec);
        }
        if (!out->open(tmp, int(specs.size()), specs.data())) {
            throw_runtime(path, ": cannot open for writing: ", out->geterror());
        }
        for (std::size_t i = 0; i < parts.size(); ++i) {
            const OutPart &part = parts[i];
            if (i > 0 && !out->open(tmp, specs[i], OIIO::ImageOutput::AppendSubimage)) {
                throw_runtime(path, ": cannot append part ", i, ": ", out->geterror());
            }
            write_part_pixels(*out, part, frame, path);
            if (part.make_levels) {
                // A touched MIP-mapped part: its levels are made again from the new pixels.
                const int nch = int(part.channels.size());
                std::vector<float> level = part_floats(part, frame);
                int w = part.data_window.width(), h = part.data_window.height();
                std::size_t pixel_bytes = 0;
                for (const OutChannel &c : part.channels) {
                    pixel_bytes += c.type.size();
                }
                while (w > 1 || h > 1) {
                    int nw = 0, nh = 0;
                    level = half_size(level, w, h, nch, nw, nh);
                    w = nw;
                    h = nh;
                    std::vector<unsigned char> buf(std::size_t(w) * std::size_t(h) * pixel_bytes);
                    std::size_t offset = 0;
                    std::vector<float> column(std::size_t(w) * std::size_t(h));
                    for (int c = 0; c < nch; ++c) {
                        for (std::size_t i = 0; i < column.size(); ++i) {
                            column[i] = level[i * std::size_t(nch) + std::size_t(c)];
                        }
                        store_values(column.data(),
                                     int(column.size()),
                                     part.channels[std::size_t(c)].type,
                                     buf.data() + offset,
                                     pixel_bytes);
                        offset += part.channels[std::size_t(c)].type.size();
                    }
                    OIIO::ImageSpec ls = specs[i];
                    ls.width = ls.full_width = w;
                    ls.height = ls.full_height = h;
                    ls.x = ls.y = ls.full_x = ls.full_y = 0;
                    if (!out->open(tmp, ls, OIIO::ImageOutput::AppendMIPLevel) ||
                        !out->write_image(OIIO::TypeUnknown, buf.data())) {
                        throw_runtime(
                            path, ": cannot write mip level of part ", i, ": ", out->geterror());
                    }
                }
                continue;
            }
            if (!part.copy_levels) {
                continue;
            }
            for (const SourceLevel &level : part.source->levels) {
                OIIO::ImageSpec ls = specs[i];
                ls.x = level.spec.x;
                ls.y = level.spec.y;
                ls.width = level.spec.width;
                ls.height = level.spec.height;
                ls.full_x = level.spec.full_x;
                ls.full_y = level.spec.full_y;
                ls.full_width = level.spec.full_width;
                ls.full_height = level.spec.full_height;
                // The level's bytes are in the source's channel order; write in that order.
                ls.channelnames = level.spec.channelnames;
                ls.channelformats = level.spec.channelformats;
                if (!out->open(tmp, ls, OIIO::ImageOutput::AppendMIPLevel) ||
                    !out->write_image(OIIO::TypeUnknown, level.pixels->data())) {
                    throw_runtime(
                        path, ": cannot write mip level of part ", i, ": ", out->geterror());
                }
            }
        }
        if (!out->close()) {
            throw_runtime(path, ": cannot finish writing: ", out->geterror());
        }
    });
}

void write_display_preview(const Image &color,
                           const Rect &data,
                           const Rect &display,
                           const ColorProcessor &to_display,
                           const std::string &path,
                           const PreviewOptions &options)
{
    static constexpr int kBayer[8][8] = {{0, 32, 8, 40, 2, 34, 10, 42},
                                         {48, 16, 56, 24, 50, 18, 58, 26},
                                         {12, 44, 4, 36, 14, 46, 6, 38},
                                         {60, 28, 52, 20, 62, 30, 54, 22},
                                         {3, 35, 11, 43, 1, 33, 9, 41},
                                         {51, 19, 59, 27, 49, 17, 57, 25},
                                         {15, 47, 7, 39, 13, 45, 5, 37},
                                         {63, 31, 55, 23, 61, 29, 53, 21}};
    const int in_ch = color.channels();
    const int nch = options.alpha && in_ch >= 4 ? 4 : 3;
    const int w = display.width(), h = display.height();
    std::vector<std::uint8_t> buf(std::size_t(w) * std::size_t(h) * std::size_t(nch));
    const Rect inside = data.intersect(display);
    // A PNG's alpha is straight (unassociated): its colour is the display values divided by
    // alpha (OpenImageIO's other formats take them premultiplied and convert themselves).
    // Alpha is written only from an input that has it, so such a row is always flat (below).
    const bool straight = nch == 4 && is_png_path(path);
    // When the input has every channel the output writes, a row (its first nch channels) is
    // quantised as one flat run of values (a loop the compiler vectorises).
    const bool flat = in_ch >= nch;
    // The dither thresholds, (pattern + 0.5) / 64, spread over every value a row writes: the
    // eight rows of the pattern (one without dither), w * nch values each.
    const int pattern_rows = options.dither ? 8 : 1;
    std::vector<float> spread(std::size_t(pattern_rows) * std::size_t(w) * std::size_t(nch));
    for (int r = 0; r < pattern_rows; ++r) {
        for (int x = 0; x < w; ++x) {
            const int k = kBayer[r][(x + display.x0) & 7];
            const float t = options.dither ? (float(k) + 0.5f) / 64.0f : 0.5f;
            std::fill_n(spread.begin() + std::ptrdiff_t((std::size_t(r) * std::size_t(w) +
                                                          std::size_t(x)) *
                                                         std::size_t(nch)),
                        nch,
                        t);
        }
    }
    parallel_for(0, h, [&](int y) {
        thread_local std::vector<float> row;
        row.assign(std::size_t(w) * std::size_t(in_ch), 0.0f);
        const int ay = y + display.y0;
        if (!inside.empty() && ay >= inside.y0 && ay < inside.y1) {
            std::copy_n(color.pixel(inside.x0 - data.x0, ay - data.y0),
                        std::size_t(inside.width()) * std::size_t(in_ch),
                        row.data() + std::size_t(inside.x0 - display.x0) * std::size_t(in_ch));
        }
        to_display.apply_row(row.data(), w, in_ch, /*unpremultiply=*/true);
        std::uint8_t *out = buf.data() + std::size_t(y) * std::size_t(w) * std::size_t(nch);
        const float *t = spread.data() + std::size_t(options.dither ? (ay & 7) : 0) *
                                             std::size_t(w) * std::size_t(nch);
        // floor(v 255 + t) clamped to [0, 255], as the truncation of the clamped value (the same
        // for every value: both are 0 below 0 and 255 from 255 up); 0 for NaN and infinities.
        auto quantise = [](float v, float t) {
            const float q =
                std::isfinite(v) ? std::min(std::max(v * 255.0f + t, 0.0f), 255.0f) : 0.0f;
            return std::uint8_t(q);
        };
        if (flat) {
            if (straight) {
                for (int x = 0; x < w; ++x) {
                    float *p = row.data() + std::size_t(x) * 4;
                    const float a = p[3];
                    for (int c = 0; a > 0.0f && a != 1.0f && c < 3; ++c) {
                        p[c] /= a;
                    }
                }
            }
            const float *v = row.data();
            if (in_ch > nch) {  // keep the first nch channels of each pixel
                thread_local std::vector<float> kept;
                kept.resize(std::size_t(w) * std::size_t(nch));
                for (int x = 0; x < w; ++x) {
                    std::copy_n(row.data() + std::size_t(x) * std::size_t(in_ch),
                                nch,
                                kept.data() + std::size_t(x) * std::size_t(nch));
                }
                v = kept.data();
            }
            const std::size_t n = std::size_t(w) * std::size_t(nch);
            for (std::size_t i = 0; i < n; ++i) {
                // quantise() without branches: v - v is 0 exactly when v is finite, and the
                // comparisons send NaN to 0.
                float q = v[i] * 255.0f + t[i];
                q = q > 0.0f ? q : 0.0f;
                q = q < 255.0f ? q : 255.0f;
                out[i] = std::uint8_t(v[i] - v[i] == 0.0f ? q : 0.0f);
            }
            return;
        }
        // Fewer input channels than the output writes (a grey pass): the rest read 1.
        for (int x = 0; x < w; ++x) {
            const float *p = row.data() + std::size_t(x) * std::size_t(in_ch);
            const float tx = t[std::size_t(x) * std::size_t(nch)];
            std::uint8_t *o = out + std::size_t(x) * std::size_t(nch);
            for (int c = 0; c < nch; ++c) {
                o[c] = quantise(c < in_ch ? p[c] : 1.0f, tx);
            }
        }
    });
    write_8bit(path, buf, w, h, nch, options.png_level, options.png_filter);
}

void write_preview(const Image &display_rgba, const std::string &path, bool with_alpha)
{
    const int nch = with_alpha && display_rgba.channels() >= 4 ? 4 : 3;
    const bool straight = nch == 4 && is_png_path(path);  // as write_display_preview
    std::vector<std::uint8_t> buf(display_rgba.pixel_count() * std::size_t(nch));
    for (int y = 0; y < display_rgba.height(); ++y) {
        for (int x = 0; x < display_rgba.width(); ++x) {
            const float *p = display_rgba.pixel(x, y);
            const float a = straight ? p[3] : 1.0f;
            for (int c = 0; c < nch; ++c) {
                float v = c < display_rgba.channels() ? p[c] : 1.0f;
                v = c < 3 && a > 0.0f && a != 1.0f ? v / a : v;
                v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
                buf[(std::size_t(y) * std::size_t(display_rgba.width()) + std::size_t(x)) *
                        std::size_t(nch) +
                    std::size_t(c)] = std::uint8_t(std::lround(v * 255.0f));
            }
        }
    }
    write_8bit(
        path, buf, display_rgba.width(), display_rgba.height(), nch, 6, PngFilter::adaptive);
}

}  // namespace posthaste
