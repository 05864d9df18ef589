// Writing an EXR file's parts through OpenEXR's own API (write_layout.h). OpenEXR reads float
// passes and the file's own samples straight from memory, one slice per channel, and converts
// them while its threads compress; only the channels that change type or scale (float to half,
// float to uint, a depth written with an offset) are converted first, a band of rows at a time.
// MIP levels are copied as read, or made again from a touched part.

#include <OpenEXR/IexBaseExc.h>
#include <OpenEXR/IexThrowErrnoExc.h>
#include <OpenEXR/IlmThreadPool.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfIO.h>
#include <OpenEXR/ImfMultiPartOutputFile.h>
#include <OpenEXR/ImfOutputPart.h>
#include <OpenEXR/ImfTiledOutputPart.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <mutex>

#include "core/error.h"
#include "core/parallel.h"
#include "io/io_detail.h"
#include "io/mip_levels.h"
#include "io/write_layout.h"

namespace posthaste::io_detail {

namespace {

/// Convert `count` floats to `type` at dst + i * stride; returns how many finite values became
/// infinite halves.
std::size_t store_values(
    const float *v, int count, OIIO::TypeDesc type, unsigned char *dst, std::size_t stride)
{
    if (type.basetype == OIIO::TypeDesc::HALF) {
        return floats_to_halves(v, 1, count, dst, stride);
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
    return 0;
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

/// Channels at native types, interleaved, packed a band of rows at a time.
class PartPacker {
   public:
    PartPacker(const OutPart &part, const Frame &frame)
        : part_(part),
          frame_(frame),
          run_(part.channels.size(), 1),
          overflow_(std::make_unique<std::atomic<std::uint64_t>[]>(part.channels.size()))
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

    /// The finite values that became infinite halves so far, and their channels.
    HalfOverflow overflow() const
    {
        HalfOverflow o;
        for (std::size_t ci = 0; ci < part_.channels.size(); ++ci) {
            const std::uint64_t n = overflow_[ci].load(std::memory_order_relaxed);
            if (n > 0) {
                o.values += n;
                for (std::size_t k = ci; k < ci + run_[ci]; ++k) {
                    o.channels.push_back(part_.channels[k].name);
                }
            }
        }
        return o;
    }

    std::size_t pixel_bytes() const { return pixel_bytes_; }
    std::size_t offset(std::size_t channel) const { return offsets_[channel]; }
    std::size_t row_bytes() const { return pixel_bytes_ * std::size_t(part_.data_window.width()); }

    /// Rows [y_begin, y_end) of the data window (0 = its first row) into dst, in parallel.
    void pack(int y_begin, int y_end, unsigned char *dst) const
    {
        if (pixel_bytes_ == 0) {
            return;
        }
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
                    count_overflow(
                        ci,
                        floats_to_halves(src, n, dw.width(), dst, pixel_bytes_, img.channels()));
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
            count_overflow(ci, store_values(tmp.data(), dw.width(), c.type, dst, pixel_bytes_));
            ++ci;
        }
    }

    void count_overflow(std::size_t ci, std::size_t n) const
    {
        if (n > 0) {
            overflow_[ci].fetch_add(n, std::memory_order_relaxed);
        }
    }

    const OutPart &part_;
    const Frame &frame_;
    std::vector<std::size_t> offsets_;
    std::vector<std::size_t> run_;
    std::unique_ptr<std::atomic<std::uint64_t>[]> overflow_;
    std::size_t pixel_bytes_ = 0;
    bool inside_ = false;
};

/// Slices over `count` interleaved channels of a buffer whose pixel (origin) is at `base`.
void insert_interleaved(Imf::FrameBuffer &fb,
                        const std::vector<std::string> &names,
                        const std::vector<OIIO::TypeDesc> &types,
                        const unsigned char *base,
                        Imath::V2i origin,
                        int w,
                        int h)
{
    std::size_t pixel_bytes = 0;
    for (const OIIO::TypeDesc &t : types) {
        pixel_bytes += t.size();
    }
    std::size_t offset = 0;
    for (std::size_t c = 0; c < names.size(); ++c) {
        fb.insert(names[c],
                  Imf::Slice::Make(exr_pixel_type(types[c]),
                                   base + offset,
                                   origin,
                                   w,
                                   h,
                                   pixel_bytes,
                                   pixel_bytes * std::size_t(w)));
        offset += types[c].size();
    }
}

/// One part's level 0: float passes and the file's own samples as slices over memory, the
/// rest converted band by band.
HalfOverflow write_level0(Imf::MultiPartOutputFile &file,
                          int index,
                          const OutPart &part,
                          const Frame &frame)
{
    const Rect &dw = part.data_window, &fw = frame.data_window;
    const bool inside = fw.x0 <= dw.x0 && dw.x1 <= fw.x1 && fw.y0 <= dw.y0 && dw.y1 <= fw.y1;
    Imf::FrameBuffer direct;
    OutPart converted = part;
    converted.channels.clear();
    for (const OutChannel &c : part.channels) {
        if (c.raw) {
            const std::size_t size = c.type.size();
            direct.insert(c.name,
                          Imf::Slice::Make(exr_pixel_type(c.type),
                                           c.raw->data(),
                                           Imath::V2i(dw.x0, dw.y0),
                                           dw.width(),
                                           dw.height(),
                                           size,
                                           size * std::size_t(dw.width())));
        } else if (inside && c.type.basetype == OIIO::TypeDesc::FLOAT && c.scale == 1.0f &&
                   c.offset == 0.0f) {
            const Image &img = *c.image;
            const std::size_t pixel = sizeof(float) * std::size_t(img.channels());
            direct.insert(c.name,
                          Imf::Slice::Make(Imf::FLOAT,
                                           img.pixel(0, 0) + c.k,
                                           Imath::V2i(fw.x0, fw.y0),
                                           img.width(),
                                           img.height(),
                                           pixel,
                                           pixel * std::size_t(img.width())));
        } else {
            converted.channels.push_back(c);
        }
    }
    const PartPacker packer(converted, frame);
    const bool tiled = part.spec.tile_width > 0;
    // A band bounds the converted copy (about 4 MiB); each band ends with OpenEXR's threads
    // drained, so a part OpenEXR reads whole from memory is written in one call.
    const int band = converted.channels.empty()
                         ? dw.height()
                         : std::min(band_rows(part.spec, packer.row_bytes()), dw.height());
    auto buf = std::make_unique_for_overwrite<unsigned char[]>(
        std::max<std::size_t>(packer.row_bytes() * std::size_t(band), 1));
    std::unique_ptr<Imf::OutputPart> lines;
    std::unique_ptr<Imf::TiledOutputPart> tiles;
    if (tiled) {
        tiles = std::make_unique<Imf::TiledOutputPart>(file, index);
    } else {
        lines = std::make_unique<Imf::OutputPart>(file, index);
    }
    // Bands in the order the file stores its lines (bottom up for decreasing Y).
    const int bands = (dw.height() + band - 1) / band;
    const bool bottom_up = !tiled && lines->header().lineOrder() == Imf::DECREASING_Y;
    for (int b = 0; b < bands; ++b) {
        const int y = (bottom_up ? bands - 1 - b : b) * band;
        const int y_end = std::min(y + band, dw.height());
        packer.pack(y, y_end, buf.get());
        Imf::FrameBuffer fb = direct;
        for (std::size_t ci = 0; ci < converted.channels.size(); ++ci) {
            const OutChannel &c = converted.channels[ci];
            fb.insert(c.name,
                      Imf::Slice::Make(exr_pixel_type(c.type),
                                       buf.get() + packer.offset(ci),
                                       Imath::V2i(dw.x0, dw.y0 + y),
                                       dw.width(),
                                       y_end - y,
                                       packer.pixel_bytes(),
                                       packer.row_bytes()));
        }
        if (tiled) {
            const int th = tiles->tileYSize();
            tiles->setFrameBuffer(fb);
            tiles->writeTiles(0, tiles->numXTiles(0) - 1, y / th, (y_end - 1) / th, 0);
        } else {
            lines->setFrameBuffer(fb);
            lines->writePixels(y_end - y);
        }
    }
    return packer.overflow();
}

/// A level's floats (W x H x C) stored at the part's types and written as level (lx, ly).
void write_level(Imf::TiledOutputPart &out,
                 const OutPart &part,
                 const std::vector<float> &level,
                 int w,
                 int h,
                 int lx,
                 int ly)
{
    if (w != out.levelWidth(lx) || h != out.levelHeight(ly)) {
        throw Iex::ArgExc("a made level's size differs from the file's");
    }
    const std::size_t nch = part.channels.size();
    std::vector<std::string> names;
    std::vector<OIIO::TypeDesc> types;
    std::size_t pixel_bytes = 0;
    for (const OutChannel &c : part.channels) {
        names.push_back(c.name);
        types.push_back(c.type);
        pixel_bytes += c.type.size();
    }
    std::vector<unsigned char> buf(std::size_t(w) * std::size_t(h) * pixel_bytes);
    std::vector<float> column(std::size_t(w) * std::size_t(h));
    std::size_t offset = 0;
    for (std::size_t c = 0; c < nch; ++c) {
        for (std::size_t i = 0; i < column.size(); ++i) {
            column[i] = level[i * nch + c];
        }
        store_values(column.data(), int(column.size()), types[c], buf.data() + offset, pixel_bytes);
        offset += types[c].size();
    }
    Imf::FrameBuffer fb;
    insert_interleaved(
        fb, names, types, buf.data(), Imath::V2i(part.data_window.x0, part.data_window.y0), w, h);
    out.setFrameBuffer(fb);
    out.writeTiles(0, out.numXTiles(lx) - 1, 0, out.numYTiles(ly) - 1, lx, ly);
}

/// A touched MIP- or rip-mapped part's other levels, made again from its new pixels: a MIP
/// map's by halving both sides, a ripmap's (lx, ly) by halving the width lx times and the
/// height ly times.
void write_made_levels(Imf::TiledOutputPart &out, const OutPart &part, const Frame &frame)
{
    const int nch = int(part.channels.size());
    const bool up = out.levelRoundingMode() == Imf::ROUND_UP;
    const bool rip = out.levelMode() == Imf::RIPMAP_LEVELS;
    std::vector<float> column = part_floats(part, frame);  // level (0, ly)
    int cw = part.data_window.width(), ch = part.data_window.height();
    for (int ly = 0; ly < (rip ? out.numYLevels() : out.numLevels()); ++ly) {
        if (ly > 0) {
            column = halve(column, cw, ch, nch, !rip, true, up, cw, ch);
            if (!rip) {
                write_level(out, part, column, cw, ch, ly, ly);
                continue;
            }
            write_level(out, part, column, cw, ch, 0, ly);
        }
        if (!rip) {
            continue;
        }
        std::vector<float> level = column;
        int w = cw, h = ch;
        for (int lx = 1; lx < out.numXLevels(); ++lx) {
            level = halve(level, w, h, nch, true, false, up, w, h);
            write_level(out, part, level, w, h, lx, ly);
        }
    }
}

/// An untouched MIP- or rip-mapped part's other levels, as read.
void write_copied_levels(Imf::TiledOutputPart &out, const OutPart &part, const std::string &path)
{
    const Imath::V2i origin(part.data_window.x0, part.data_window.y0);
    const int count = out.levelMode() == Imf::RIPMAP_LEVELS ? out.numXLevels() * out.numYLevels()
                                                            : out.numLevels();
    if (int(part.source->levels.size()) + 1 != count) {
        throw_runtime(path,
                      ": part \"",
                      part.spec.get_string_attribute("name"),
                      "\" has ",
                      part.source->levels.size() + 1,
                      " levels where its tiles need ",
                      count);
    }
    for (const SourceLevel &level : part.source->levels) {
        Imf::FrameBuffer fb;
        insert_interleaved(
            fb,
            level.spec.channelnames,
            level.spec.channelformats.empty()
                ? std::vector<OIIO::TypeDesc>(level.spec.channelnames.size(), level.spec.format)
                : level.spec.channelformats,
            level.pixels->data(),
            origin,
            level.spec.width,
            level.spec.height);
        out.setFrameBuffer(fb);
        out.writeTiles(
            0, out.numXTiles(level.lx) - 1, 0, out.numYTiles(level.ly) - 1, level.lx, level.ly);
    }
}

/// The file OpenEXR writes through, remembering any failure: OpenEXR writes a part's offset
/// table when the file object is destroyed and drops what fails there, so a disk that fills
/// up at the very end would otherwise leave a file without its offsets, renamed into place.
class CheckedFile : public Imf::OStream {
   public:
    explicit CheckedFile(const std::string &name) : Imf::OStream(name.c_str())
    {
        out_.open(name, std::ios::binary | std::ios::trunc);
        if (!out_) {
            Iex::throwErrnoExc();
        }
    }
    void write(const char c[], int n) override
    {
        errno = 0;
        out_.write(c, n);
        check();
    }
    uint64_t tellp() override { return uint64_t(std::streamoff(out_.tellp())); }
    void seekp(uint64_t pos) override
    {
        out_.seekp(std::streamoff(pos));
        check();
    }
    /// Flush and close; throws if this or any earlier write failed.
    void close()
    {
        if (!failed_) {
            errno = 0;
            out_.close();
        }
        if (failed_ || out_.fail()) {
            failed_ = true;
            if (errno != 0) {
                Iex::throwErrnoExc();
            }
            throw Iex::IoExc("file output failed");
        }
    }

   private:
    void check()
    {
        if (!out_) {
            failed_ = true;
            if (errno != 0) {
                Iex::throwErrnoExc();
            }
            throw Iex::IoExc("file output failed");
        }
    }

    std::ofstream out_;
    bool failed_ = false;
};

}  // namespace

HalfOverflow write_exr_parts(const std::vector<OutPart> &parts,
                             const Frame &frame,
                             const std::string &file,
                             const std::string &path)
{
    HalfOverflow overflow;
    std::vector<Imf::Header> headers;
    for (std::size_t i = 0; i < parts.size(); ++i) {
        headers.push_back(exr_header(parts[i], int(i), int(parts.size()), path));
    }
    // OpenEXR's pool compresses the blocks: sized to the threads the job has (set_thread_count),
    // as OpenImageIO sizes it when it opens an EXR (a frame that read no EXR would otherwise
    // compress on one thread).
    {
        static std::mutex mutex;
        std::lock_guard lock(mutex);
        const int threads = thread_count();
        if (IlmThread::ThreadPool::globalThreadPool().numThreads() != threads) {
            IlmThread::ThreadPool::globalThreadPool().setNumThreads(threads);
        }
    }
    try {
        CheckedFile stream(file);
        {
            Imf::MultiPartOutputFile out(stream, headers.data(), int(headers.size()));
            for (std::size_t i = 0; i < parts.size(); ++i) {
                const OutPart &part = parts[i];
                const HalfOverflow o = write_level0(out, int(i), part, frame);
                overflow.values += o.values;
                overflow.channels.insert(
                    overflow.channels.end(), o.channels.begin(), o.channels.end());
                if (part.make_levels || part.copy_levels) {
                    Imf::TiledOutputPart tiles(out, int(i));
                    if (part.make_levels) {
                        write_made_levels(tiles, part, frame);
                    } else {
                        write_copied_levels(tiles, part, path);
                    }
                }
            }
        }  // OpenEXR writes the offset tables here, and swallows what fails
        stream.close();
    } catch (const Iex::BaseExc &e) {
        std::string m = e.what();
        std::replace(m.begin(), m.end(), '\n', ' ');
        // OpenEXR names the temporary file; the user's is the one to name.
        for (auto at = m.find(file); at != std::string::npos; at = m.find(file, at + path.size())) {
            m.replace(at, file.size(), path);
        }
        throw_runtime(path, ": cannot write: ", m);
    }
    return overflow;
}

}  // namespace posthaste::io_detail
