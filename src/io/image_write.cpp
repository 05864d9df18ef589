// Writing frames: EXR through OpenEXR (exr_write.cpp), in the layout of the file the frame was
// read from (parts, views, channel names and pixel types, windows, tiles and untouched mip
// levels), or rebuilt with canonical channel names; 8-bit previews (atomic writes:
// atomic_file.cpp).

#include <OpenImageIO/imageio.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
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

/// Closes a descriptor when it goes out of scope.
struct FdCloser {
    int fd;
    ~FdCloser() { ::close(fd); }
};

/// Write 8-bit interleaved pixels atomically: a PNG through the parallel encoder (png_write.h),
/// any other format encoded by OpenImageIO into a file that lives in memory (memfd), read back
/// whole, then written as bytes as the PNG is. Encoding onto the output's disk left a truncated
/// TIFF on a full disk without a word (libjpeg ended the process); OpenImageIO 2.4's in-memory
/// output (IOVecOutput) gave TIFFs whose header pointed at the wrong directory, unreadable.
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
    OIIO::ImageSpec spec(w, h, nch, OIIO::TypeDesc::UINT8);
    spec.attribute("oiio:ColorSpace", "sRGB");
    // The same bytes for the same pixels: OpenImageIO stamps a TIFF with the time of writing
    // unless DateTime is given, and leaves out an empty one.
    spec.attribute("DateTime", "");
    auto out = OIIO::ImageOutput::create(path);
    if (!out) {
        throw_runtime(path, ": no writer for this file type: ", OIIO::geterror());
    }
    const int fd = ::memfd_create("posthaste-preview", MFD_CLOEXEC);
    if (fd < 0) {
        throw_runtime(path, ": cannot encode preview: memfd_create: ", std::strerror(errno));
    }
    const FdCloser closer{fd};
    const std::string at = "/proc/self/fd/" + std::to_string(fd);
    if (!out->open(at, spec) || !out->write_image(OIIO::TypeDesc::UINT8, buf.data()) ||
        !out->close()) {
        throw_runtime(path, ": cannot encode preview: ", out->geterror());
    }
    // The encoder's file must decode whole (its reader by the writer's format name: the memory
    // file has no extension, and a reader made from the output's path looked for that file).
    std::vector<std::uint8_t> back(buf.size());
    auto in = OIIO::ImageInput::create(out->format_name());
    OIIO::ImageSpec read_spec;
    if (!in || !in->open(at, read_spec) ||
        !in->read_image(0, 0, 0, nch, OIIO::TypeDesc::UINT8, back.data())) {
        throw_runtime(path,
                      ": cannot encode preview: it does not read back (",
                      in ? in->geterror() : OIIO::geterror(),
                      ")");
    }
    in.reset();
    const off_t size = ::lseek(fd, 0, SEEK_END);
    std::vector<std::uint8_t> bytes(size > 0 ? std::size_t(size) : 0);
    std::size_t got = 0;
    while (got < bytes.size()) {
        const ssize_t n = ::pread(fd, bytes.data() + got, bytes.size() - got, off_t(got));
        if (n <= 0) {
            throw_runtime(path, ": cannot encode preview: reading it back: ", std::strerror(errno));
        }
        got += std::size_t(n);
    }
    write_file_bytes(path, bytes.data(), bytes.size());
}

/// Say once when an asked storage rounds a file's uint ids: float holds whole numbers to 2^24,
/// half to 2048 (storage "auto" keeps the uint channel).
void warn_of_rounded_ids(const std::vector<OutPart> &parts,
                         const Frame &frame,
                         const WriteOptions &options,
                         const std::string &path)
{
    if (!frame.source) {
        return;
    }
    std::string names;
    for (const OutPart &part : parts) {
        for (const OutChannel &c : part.channels) {
            if (c.type.basetype == OIIO::TypeDesc::UINT || c.raw || !c.image || c.pass.empty() ||
                !frame.has(c.pass)) {
                continue;
            }
            const Pass &p = frame.pass(c.pass, path);
            if (std::size_t(c.k) >= p.origin.size() || p.origin[std::size_t(c.k)].part < 0 ||
                p.origin[std::size_t(c.k)].part >= int(frame.source->parts.size())) {
                continue;
            }
            const ChannelOrigin &o = p.origin[std::size_t(c.k)];
            const SourcePart &sp = frame.source->parts[std::size_t(o.part)];
            if (sp.spec.channelformat(o.channel).basetype != OIIO::TypeDesc::UINT) {
                continue;
            }
            const bool half = c.type.basetype == OIIO::TypeDesc::HALF;
            bool rounded = !half && frame.source->raw.count({o.part, o.channel}) != 0;
            const std::size_t nch = std::size_t(c.image->channels());
            for (std::size_t i = 0, n = c.image->pixel_count(); half && !rounded && i < n; ++i) {
                rounded = c.image->data()[i * nch + std::size_t(c.k)] > 2048.0f;
            }
            if (rounded) {
                names += (names.empty() ? "" : ", ") + c.name;
            }
        }
    }
    if (!names.empty()) {
        const std::string line = str_cat("uint id channel(s) ",
                                         names,
                                         " written as floats lose the low bits of their larger ids "
                                         "(float holds whole numbers to 2^24, half to 2048); "
                                         "storage: auto keeps them as uint");
        if (options.warn) {
            options.warn(line);
        } else {
            std::fprintf(stderr, "warning: %s: %s\n", path.c_str(), line.c_str());
        }
    }
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
        // Plain decimals only (strtod took "1e3", " 5" and hex, which the writer read
        // otherwise): zip's levels are zlib's 1-9, DWA's a positive number up to 1000.
        const bool zip = base != "dwaa" && base != "dwab";
        const bool plain =
            !level.empty() &&
            level.find_first_not_of(zip ? "0123456789" : "0123456789.") == std::string::npos &&
            std::count(level.begin(), level.end(), '.') <= 1 && level != ".";
        const double v = plain ? std::strtod(level.c_str(), nullptr) : 0.0;
        if (!plain || !(v > 0.0) || v > (zip ? 9.0 : 1000.0)) {
            throw_usage(
                where,
                ": invalid compression level \"",
                level,
                zip ? "\" (zip's levels are 1 to 9)" : "\" (DWA's levels are above 0, up to 1000)");
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
    warn_of_rounded_ids(parts, frame, options, path);

    HalfOverflow overflow;
    atomic_write(
        path, [&](const std::string &tmp) { overflow = write_exr_parts(parts, frame, tmp, path); });
    if (overflow.values > 0) {
        std::string names;
        for (const std::string &c : overflow.channels) {
            names += (names.empty() ? "" : ", ") + c;
        }
        const std::string line = str_cat(
            "values beyond half's range (65504) were written as "
            "infinity in channel(s) ",
            names,
            "; storage: float keeps them");
        if (options.warn) {
            options.warn(line);
        } else {
            std::fprintf(stderr,
                         "warning: %s: %s (%llu values)\n",
                         path.c_str(),
                         line.c_str(),
                         static_cast<unsigned long long>(overflow.values));
        }
    }
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
    // A grey colour pass (Y, or Y and alpha) is grey on screen: its value in R, G and B (it
    // bypassed the display transform, which takes three channels, and G and B read 1: cyan).
    const int src_ch = color.channels();
    const bool grey = src_ch < 3;
    const int in_ch = grey ? src_ch + 2 : src_ch;
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
            std::fill_n(
                spread.begin() + std::ptrdiff_t((std::size_t(r) * std::size_t(w) + std::size_t(x)) *
                                                std::size_t(nch)),
                nch,
                t);
        }
    }
    parallel_for(0, h, [&](int y) {
        thread_local std::vector<float> row;
        row.assign(std::size_t(w) * std::size_t(in_ch), 0.0f);
        const int ay = y + display.y0;
        if (!inside.empty() && ay >= inside.y0 && ay < inside.y1 && grey) {
            const float *p = color.pixel(inside.x0 - data.x0, ay - data.y0);
            float *o = row.data() + std::size_t(inside.x0 - display.x0) * std::size_t(in_ch);
            for (int x = 0; x < inside.width(); ++x, p += src_ch, o += in_ch) {
                o[0] = o[1] = o[2] = p[0];
                if (src_ch == 2) {
                    o[3] = p[1];
                }
            }
        } else if (!inside.empty() && ay >= inside.y0 && ay < inside.y1) {
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
    write_8bit(path, buf, display_rgba.width(), display_rgba.height(), nch, 6, PngFilter::adaptive);
}

}  // namespace posthaste
