// The previews' PNG encoder (png_write.h): rows filtered in parallel, then deflated in pieces of
// a fixed size in parallel and joined into the one zlib stream a PNG holds.

#include "io/png_write.h"

#include <zlib.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"

namespace posthaste {

namespace {

constexpr std::size_t kWindow = 32768;  // deflate's window: what a piece is primed with

void put_u32(std::vector<std::uint8_t> &out, std::uint32_t v)
{
    out.push_back(std::uint8_t(v >> 24));
    out.push_back(std::uint8_t(v >> 16));
    out.push_back(std::uint8_t(v >> 8));
    out.push_back(std::uint8_t(v));
}

/// Append a chunk: length, type, data, CRC-32 of type and data.
void put_chunk(std::vector<std::uint8_t> &out,
               const char (&type)[5],
               const std::uint8_t *data,
               std::size_t size)
{
    put_u32(out, std::uint32_t(size));
    const std::size_t at = out.size();
    out.insert(out.end(), type, type + 4);
    out.insert(out.end(), data, data + size);
    const uLong crc = crc32(0, out.data() + at, uInt(size + 4));
    put_u32(out, std::uint32_t(crc));
}

std::uint8_t paeth(std::uint8_t a, std::uint8_t b, std::uint8_t c)
{
    const int p = int(a) + int(b) - int(c);
    const int pa = std::abs(p - int(a)), pb = std::abs(p - int(b)), pc = std::abs(p - int(c));
    return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/// Filter one row of `n` bytes (`prior`: the row above, or null for the first) with `f` into
/// out[0] (the filter's byte) and out[1..n].
void filter_row(PngFilter f,
                const std::uint8_t *row,
                const std::uint8_t *prior,
                std::size_t n,
                std::size_t bpp,
                std::uint8_t *out)
{
    out[0] = std::uint8_t(f);  // none 0, sub 1, up 2, average 3, paeth 4
    std::uint8_t *o = out + 1;
    auto left = [&](std::size_t i) { return i >= bpp ? row[i - bpp] : std::uint8_t(0); };
    auto up = [&](std::size_t i) { return prior ? prior[i] : std::uint8_t(0); };
    auto up_left = [&](std::size_t i) {
        return prior && i >= bpp ? prior[i - bpp] : std::uint8_t(0);
    };
    switch (f) {
        case PngFilter::none:
        case PngFilter::adaptive:
            std::memcpy(o, row, n);
            break;
        case PngFilter::sub:
            for (std::size_t i = 0; i < n; ++i) {
                o[i] = std::uint8_t(row[i] - left(i));
            }
            break;
        case PngFilter::up:
            for (std::size_t i = 0; i < n; ++i) {
                o[i] = std::uint8_t(row[i] - up(i));
            }
            break;
        case PngFilter::average:
            for (std::size_t i = 0; i < n; ++i) {
                o[i] = std::uint8_t(row[i] - ((int(left(i)) + int(up(i))) >> 1));
            }
            break;
        case PngFilter::paeth:
            for (std::size_t i = 0; i < n; ++i) {
                o[i] = std::uint8_t(row[i] - paeth(left(i), up(i), up_left(i)));
            }
            break;
    }
}

/// The sum of |b| over a filtered row's bytes taken as signed: the adaptive filter's cost.
std::uint64_t signed_sum(const std::uint8_t *o, std::size_t n)
{
    std::uint64_t s = 0;
    for (std::size_t i = 0; i < n; ++i) {
        s += o[i] < 128 ? o[i] : 256u - o[i];
    }
    return s;
}

/// Deflate `size` bytes at `data` as raw deflate primed with the `dict_size` bytes before them,
/// ended by a sync flush (a byte boundary; more pieces follow) or, when `last`, a final block.
/// Empty on failure.
std::vector<std::uint8_t> deflate_piece(
    const std::uint8_t *data, std::size_t size, std::size_t dict_size, int level, bool last)
{
    z_stream z{};
    if (deflateInit2(&z, level, Z_DEFLATED, -15, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
        return {};
    }
    std::vector<std::uint8_t> out;
    bool ok = dict_size == 0 || deflateSetDictionary(&z, data - dict_size, uInt(dict_size)) == Z_OK;
    if (ok) {
        out.resize(deflateBound(&z, uLong(size)) + 16);
        z.next_in = const_cast<Bytef *>(data);
        z.avail_in = uInt(size);
        const int flush = last ? Z_FINISH : Z_SYNC_FLUSH;
        for (;;) {
            if (z.total_out == out.size()) {
                out.resize(out.size() * 2);
            }
            z.next_out = out.data() + z.total_out;
            z.avail_out = uInt(out.size() - z.total_out);
            const int r = deflate(&z, flush);
            // Done: the final block written, or all input consumed and flushed (room left over;
            // a flush with nothing left to do answers Z_BUF_ERROR).
            if (last ? r == Z_STREAM_END : (z.avail_out > 0 && (r == Z_OK || r == Z_BUF_ERROR))) {
                break;
            }
            if (r != Z_OK && r != Z_BUF_ERROR) {
                ok = false;
                break;
            }
        }
        out.resize(z.total_out);
    }
    deflateEnd(&z);
    return ok ? out : std::vector<std::uint8_t>{};
}

}  // namespace

std::vector<std::uint8_t> encode_png(const std::uint8_t *pixels,
                                     int width,
                                     int height,
                                     int channels,
                                     int level,
                                     PngFilter filter,
                                     const std::string &what)
{
    constexpr std::int64_t kMaxDimension = std::numeric_limits<std::int32_t>::max();
    if (width < 1 || height < 1 || width > kMaxDimension / 4 || (channels != 3 && channels != 4)) {
        throw_usage(
            what, ": a PNG cannot hold ", width, "x", height, " pixels of ", channels, " channels");
    }
    level = std::clamp(level, 0, 9);
    const std::size_t bpp = std::size_t(channels);
    const std::size_t row_bytes = std::size_t(width) * bpp;
    const std::size_t stride = row_bytes + 1;  // the filter's byte, then the row
    const std::size_t rows = std::size_t(height);
    if (stride > std::numeric_limits<uInt>::max() / 4) {
        throw_usage(what, ": a PNG row of ", width, " pixels is too wide to compress");
    }

    // Filter every row (each reads only its own and the row above's pixels).
    std::vector<std::uint8_t> filtered(stride * rows);
    parallel_for(0, height, [&](int y) {
        const std::uint8_t *row = pixels + std::size_t(y) * row_bytes;
        const std::uint8_t *prior = y > 0 ? row - row_bytes : nullptr;
        std::uint8_t *out = filtered.data() + std::size_t(y) * stride;
        if (filter != PngFilter::adaptive) {
            filter_row(filter, row, prior, row_bytes, bpp, out);
            return;
        }
        thread_local std::vector<std::uint8_t> trial;
        trial.resize(stride);
        std::uint64_t best = std::numeric_limits<std::uint64_t>::max();
        for (const PngFilter f : {PngFilter::none,
                                  PngFilter::sub,
                                  PngFilter::up,
                                  PngFilter::average,
                                  PngFilter::paeth}) {
            filter_row(f, row, prior, row_bytes, bpp, trial.data());
            const std::uint64_t cost = signed_sum(trial.data() + 1, row_bytes);
            if (cost < best) {  // the first of equal costs, in the order above
                best = cost;
                std::copy(trial.begin(), trial.end(), out);
            }
        }
    });

    // Deflate pieces of whole rows, each primed with the window before it.
    const std::size_t piece_rows = std::max<std::size_t>(1, kPngPieceBytes / stride);
    const int pieces = int((rows + piece_rows - 1) / piece_rows);
    std::vector<std::vector<std::uint8_t>> packed(static_cast<std::size_t>(pieces));
    std::vector<uLong> adler(static_cast<std::size_t>(pieces));
    std::atomic<bool> failed{false};
    parallel_for(0, pieces, [&](int i) {
        const std::size_t begin = std::size_t(i) * piece_rows * stride;
        const std::size_t end = std::min(filtered.size(), begin + piece_rows * stride);
        const std::uint8_t *data = filtered.data() + begin;
        adler[std::size_t(i)] = adler32(adler32(0, nullptr, 0), data, uInt(end - begin));
        packed[std::size_t(i)] =
            deflate_piece(data, end - begin, std::min(begin, kWindow), level, i == pieces - 1);
        if (packed[std::size_t(i)].empty()) {
            failed = true;
        }
    });
    if (failed) {
        throw_runtime(what, ": cannot compress the PNG's pixels (zlib ran out of memory)");
    }

    std::vector<std::uint8_t> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    std::vector<std::uint8_t> ihdr;
    put_u32(ihdr, std::uint32_t(width));
    put_u32(ihdr, std::uint32_t(height));
    // 8 bits, colour type 2 (RGB) or 6 (RGBA), deflate, adaptive filtering, no interlace.
    ihdr.insert(ihdr.end(), {8, std::uint8_t(channels == 4 ? 6 : 2), 0, 0, 0});
    put_chunk(png, "IHDR", ihdr.data(), ihdr.size());
    // sRGB (perceptual intent), and the gAMA and cHRM the specification asks to go with it.
    const std::uint8_t intent = 0;
    put_chunk(png, "sRGB", &intent, 1);
    std::vector<std::uint8_t> gama;
    put_u32(gama, 45455);
    put_chunk(png, "gAMA", gama.data(), gama.size());
    std::vector<std::uint8_t> chrm;
    for (const std::uint32_t v : {31270u, 32900u, 64000u, 33000u, 30000u, 60000u, 15000u, 6000u}) {
        put_u32(chrm, v);
    }
    put_chunk(png, "cHRM", chrm.data(), chrm.size());

    // The zlib stream: header, the pieces (one IDAT each), the Adler-32 of all filtered bytes.
    const int flevel = level < 2 ? 0 : level < 6 ? 1 : level == 6 ? 2 : 3;
    const unsigned cmf = 0x78;  // deflate, 32 KiB window
    unsigned flg = unsigned(flevel) << 6;
    flg += 31 - (cmf * 256 + flg) % 31;
    uLong total_adler = adler32(0, nullptr, 0);
    for (int i = 0; i < pieces; ++i) {
        const std::size_t begin = std::size_t(i) * piece_rows * stride;
        const std::size_t end = std::min(filtered.size(), begin + piece_rows * stride);
        total_adler = adler32_combine(total_adler, adler[std::size_t(i)], z_off_t(end - begin));
        std::vector<std::uint8_t> &p = packed[std::size_t(i)];
        if (i == 0) {
            p.insert(p.begin(), {std::uint8_t(cmf), std::uint8_t(flg)});
        }
        if (i == pieces - 1) {
            put_u32(p, std::uint32_t(total_adler));
        }
        put_chunk(png, "IDAT", p.data(), p.size());
        std::vector<std::uint8_t>().swap(p);
    }
    put_chunk(png, "IEND", nullptr, 0);
    return png;
}

}  // namespace posthaste
