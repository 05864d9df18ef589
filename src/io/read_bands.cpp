// The frame's passes assembled from a file's parts, band by band (read_detail.h, FrameRows):
// what no part covers, each part's rows converted to float as they are read, the file's own
// bits of the channels a float cannot give back, and the bad values found per row.

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "core/srgb.h"
#include "io/io_detail.h"
#include "io/read_detail.h"

namespace posthaste::io_detail {

FrameRows::FrameRows(const std::string &path,
                     const FileInfo &info,
                     const Rect &window,
                     const ReadOptions &options,
                     bool count_kept)
    : raw_planes(info.parts.size()),
      path_(path),
      info_(info),
      window_(window),
      options_(options),
      count_kept_(count_kept)
{
}

void FrameRows::fill_uncovered()
{
    const FileInfo &info = info_;
    const Rect &window = window_;
    const int width = window.width(), height = window.height();
    parallel_for(0, height, [&](int y) {
        for (Out &out : outs) {
            const std::size_t step = out.ps->sources.size();
            float *row = out.img.pixel(0, y);
            for (std::size_t k = 0; k < step; ++k) {
                const ChannelSource &cs = out.ps->sources[k];
                float *dst = row + k;
                if (cs.part < 0) {
                    for (int x = 0; x < width; ++x) {
                        dst[std::size_t(x) * step] = cs.offset;
                    }
                    continue;
                }
                const Rect dw =
                    info.parts[std::size_t(cs.part)].data_window.offset(-window.x0, -window.y0);
                const float outside = (out.ps->pass == pass::kColor && k == 3) ? 0.0f
                                      : out.is_depth ? std::numeric_limits<float>::infinity()
                                                     : 0.0f;
                const int x0 = std::clamp(dw.x0, 0, width), x1 = std::clamp(dw.x1, 0, width);
                const bool row_inside = y >= dw.y0 && y < dw.y1 && x0 < x1;
                const int left = row_inside ? x0 : width, right = row_inside ? x1 : width;
                for (int x = 0; x < left; ++x) {
                    dst[std::size_t(x) * step] = outside;
                }
                for (int x = right; x < width; ++x) {
                    dst[std::size_t(x) * step] = outside;
                }
            }
        }
    });
}

void FrameRows::convert_rows(std::size_t p, const PartPixels &pd, int y_begin, int y_end)
{
    const FileInfo &info = info_;
    const Rect &window = window_;
    const ReadOptions &options = options_;
    const int width = window.width();
    const bool count_kept = count_kept_;
    const bool check_bad = options.bad_pixels != BadPixels::Keep;
    const FilePart &part = info.parts[p];
    const Rect dw = part.data_window.offset(-window.x0, -window.y0);
    const int x0 = std::clamp(dw.x0, 0, width), x1 = std::clamp(dw.x1, 0, width);
    if (x0 >= x1) {
        return;
    }
    parallel_for(y_begin, y_end, [&](int y) {
        for (Out &out : outs) {
            const std::size_t step = out.ps->sources.size();
            float *row = out.img.pixel(0, y);
            for (std::size_t k = 0; k < step; ++k) {
                const ChannelSource &cs = out.ps->sources[k];
                if (cs.part != int(p)) {
                    continue;
                }
                float *dst = row + k;
                const auto &nc = pd.channels[std::size_t(cs.channel - pd.chbegin)];
                const std::size_t first =
                    std::size_t(y - dw.y0 - pd.row0) * std::size_t(dw.width()) +
                    std::size_t(x0 - dw.x0);
                convert_channel(pd.data.get() + first * pd.pixel_bytes + nc.offset,
                                pd.pixel_bytes,
                                nc.type,
                                dst + std::size_t(x0) * step,
                                step,
                                x1 - x0);
                const bool affine = cs.scale != 1.0f || cs.offset != 0.0f;
                const bool lin = out.linearize && k < 3;
                const bool clip_inf = out.ps->infinite_above > 0.0f;
                if (count_kept) {
                    for (int x = x0; x < x1; ++x) {
                        const float v = dst[std::size_t(x) * step];
                        out.kept[std::size_t(y)] +=
                            !std::isfinite(v) && !(out.is_depth && v > 0.0f);
                    }
                }
                if (!(affine || lin || clip_inf || check_bad)) {
                    continue;
                }
                for (int x = x0; x < x1; ++x) {
                    float &v = dst[std::size_t(x) * step];
                    if (lin) {
                        v = srgb_to_linear(v);
                    }
                    if (affine) {
                        // Without an offset to add: -1 * +0 + 0 is +0, and the write's
                        // (v - 0) / -1 would give back -0 where the file had +0.
                        v = cs.offset != 0.0f ? cs.scale * v + cs.offset : cs.scale * v;
                    }
                    if (clip_inf && v >= out.ps->infinite_above) {
                        v = std::numeric_limits<float>::infinity();
                    }
                    if (check_bad && !std::isfinite(v) && !(out.is_depth && v > 0.0f)) {
                        auto &first_bad = out.bad[std::size_t(y)];
                        if (options.bad_pixels == BadPixels::Zero) {
                            v = 0.0f;
                        } else if (first_bad.first < 0 || std::make_pair(x, int(k)) < first_bad) {
                            first_bad = {x, int(k)};
                        }
                    }
                }
            }
        }
    });
}

void FrameRows::copy_raw(std::size_t p, const PartPixels &pd, int r_begin, int r_end)
{
    const std::size_t w = std::size_t(info_.parts[p].data_window.width());
    for (const RawPlane &plane : raw_planes[p]) {
        for (std::size_t i = std::size_t(r_begin) * w; i < std::size_t(r_end) * w; ++i) {
            std::memcpy(
                plane.dst + i * plane.size,
                pd.data.get() + (i - std::size_t(pd.row0) * w) * pd.pixel_bytes + plane.offset,
                plane.size);
        }
    }
}

void FrameRows::read_part(OIIO::ImageInput *in,
                          const OIIO::ImageSpec *spec,
                          std::size_t p,
                          PartPixels &pd)
{
    const FileInfo &info = info_;
    const Rect &window = window_;
    const std::string &path = path_;
    const int height = window.height();
    const Rect dw = info.parts[p].data_window.offset(-window.x0, -window.y0);
    const int rows = dw.height();
    // Frame rows of part rows [r_begin, r_end).
    auto frame_rows = [&](int r_begin, int r_end) {
        convert_rows(p, pd, std::max(0, r_begin + dw.y0), std::min(height, r_end + dw.y0));
        copy_raw(p, pd, r_begin, r_end);
    };
    if (!in) {
        frame_rows(0, rows);
        return;
    }
    const std::size_t row_bytes = std::size_t(spec->width) * pd.pixel_bytes;
    const int band = std::min(band_rows(*spec, row_bytes), rows);
    pd.data = raw_bytes(row_bytes * std::size_t(band), spec->width, band, pd.chend - pd.chbegin);
    for (int r = 0; r < rows; r += band) {
        const int r_end = std::min(r + band, rows);
        const bool ok = spec->tile_width > 0 ? in->read_tiles(int(p),
                                                              0,
                                                              spec->x,
                                                              spec->x + spec->width,
                                                              spec->y + r,
                                                              spec->y + r_end,
                                                              spec->z,
                                                              spec->z + std::max(1, spec->depth),
                                                              pd.chbegin,
                                                              pd.chend,
                                                              OIIO::TypeUnknown,
                                                              pd.data.get())
                                             : in->read_scanlines(int(p),
                                                                  0,
                                                                  spec->y + r,
                                                                  spec->y + r_end,
                                                                  spec->z,
                                                                  pd.chbegin,
                                                                  pd.chend,
                                                                  OIIO::TypeUnknown,
                                                                  pd.data.get());
        if (!ok) {
            std::string err = in->geterror();
            std::replace(err.begin(), err.end(), '\n', ' ');
            throw_runtime(
                path, ": cannot read pixels of part ", p, " (truncated or corrupt?): ", err);
        }
        pd.row0 = r;
        frame_rows(r, r_end);
    }
}

}  // namespace posthaste::io_detail
