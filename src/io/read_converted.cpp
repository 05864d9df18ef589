// Files OpenImageIO does not hand over as flat native pixels: luminance/chroma EXRs through
// OpenEXR's RGBA interface, deep parts flattened front to back, ripmap levels through OpenEXR
// (io/read_detail.h).

#include <IexBaseExc.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfMatrixAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfRgbaFile.h>
#include <ImfTiledInputPart.h>
#include <OpenImageIO/deepdata.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include "core/error.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "io/io_detail.h"
#include "io/read_detail.h"
#include "io/source_file.h"

namespace posthaste::io_detail {

bool is_luminance_chroma(const std::string &path)
{
    try {
        io_detail::check_exr_header(path);
        Imf::RgbaInputFile f(path.c_str());
        return (f.channels() & Imf::WRITE_C) != 0;
    } catch (const std::exception &) {
        return false;
    }
}

void check_window(const std::string &path, int part, const char *which, const Rect &w)
{
    const std::int64_t area = std::int64_t(w.width()) * std::int64_t(w.height());
    if (w.width() <= 0 || w.height() <= 0 || w.width() > kMaxImageSide ||
        w.height() > kMaxImageSide || area > kMaxFilePixels) {
        throw_runtime(path,
                      ": part ",
                      part,
                      " has an unsupported ",
                      which,
                      " window ",
                      w.width(),
                      "x",
                      w.height(),
                      " at (",
                      w.x0,
                      ", ",
                      w.y0,
                      ") (limit ",
                      kMaxImageSide,
                      " per side, ",
                      kMaxFilePixels,
                      " pixels)");
    }
}

FileInfo luminance_chroma_info(const std::string &path)
{
    FileInfo info;
    info.path = path;
    info.format = "openexr";
    info.conversion = "luminance/chroma";
    try {
        Imf::RgbaInputFile f(path.c_str());
        const Imath::Box2i dw = f.dataWindow(), disp = f.displayWindow();
        FilePart part;
        part.data_window = {dw.min.x, dw.min.y, dw.max.x + 1, dw.max.y + 1};
        part.display_window = {disp.min.x, disp.min.y, disp.max.x + 1, disp.max.y + 1};
        part.compression = "";
        for (const char *c : {"R", "G", "B"}) {
            part.channels.push_back({c, "half", "", 1, 1});
        }
        if (f.channels() & Imf::WRITE_A) {
            part.channels.push_back({"A", "half", "", 1, 1});
        }
        const Imf::Header &h = f.header();
        auto matrix = [&](const char *name, std::optional<glm::mat4> &out) {
            if (const auto *a = h.findTypedAttribute<Imf::M44fAttribute>(name)) {
                glm::mat4 m;
                for (int r = 0; r < 4; ++r) {
                    for (int c = 0; c < 4; ++c) {
                        m[r][c] = a->value()[r][c];  // same layout: row r of Imath, column r of glm
                    }
                }
                out = m;
            }
        };
        matrix(attr::kWorldToCamera, info.camera.world_to_camera);
        matrix(attr::kWorldToNDC, info.camera.world_to_ndc);
        info.parts.push_back(std::move(part));
    } catch (const std::exception &e) {
        std::string err = e.what();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read luminance/chroma image: ", err);
    }
    check_window(path, 0, "data", info.parts[0].data_window);
    check_window(path, 0, "display", info.parts[0].display_window);
    info.display_window = info.parts[0].display_window;
    info.data_window = info.parts[0].data_window;
    return info;
}

std::shared_ptr<unsigned char[]> raw_bytes(std::size_t n, int width, int height, int channels)
{
    reserve_image_memory(n, width, height, channels);
    try {
        return std::shared_ptr<unsigned char[]>(new unsigned char[n], [n](unsigned char *p) {
            delete[] p;
            release_image_memory(n);
        });
    } catch (...) {
        release_image_memory(n);
        throw;
    }
}

PartPixels read_luminance_chroma(const std::string &path, const FilePart &part)
{
    PartPixels pd;
    pd.chend = int(part.channels.size());
    for (int c = 0; c < pd.chend; ++c) {
        pd.channels.push_back({pd.pixel_bytes, OIIO::TypeDesc::FLOAT});
        pd.pixel_bytes += sizeof(float);
    }
    const Rect &dw = part.data_window;
    const std::size_t npix = std::size_t(dw.width()) * std::size_t(dw.height());
    std::vector<Imf::Rgba> rgba(npix);
    try {
        Imf::RgbaInputFile f(path.c_str());
        f.setFrameBuffer(
            rgba.data() - dw.x0 - std::ptrdiff_t(dw.y0) * dw.width(), 1, std::size_t(dw.width()));
        f.readPixels(dw.y0, dw.y1 - 1);
    } catch (const std::exception &e) {
        std::string err = e.what();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read pixels (truncated or corrupt?): ", err);
    }
    pd.bytes = npix * pd.pixel_bytes;
    pd.data = raw_bytes(pd.bytes, dw.width(), dw.height(), pd.chend);
    auto *out = reinterpret_cast<float *>(pd.data.get());
    for (std::size_t i = 0; i < npix; ++i) {
        const float v[4] = {float(rgba[i].r), float(rgba[i].g), float(rgba[i].b), float(rgba[i].a)};
        std::copy(v, v + pd.chend, out + i * std::size_t(pd.chend));
    }
    return pd;
}

PartPixels flatten_deep(OIIO::ImageInput &in, int sub, const std::string &path)
{
    OIIO::DeepData deep;
    if (!in.read_native_deep_image(sub, 0, deep)) {
        std::string err = in.geterror();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read deep part ", sub, " (truncated or corrupt?): ", err);
    }
    in.seek_subimage(sub, 0);
    const OIIO::ImageSpec &spec = in.spec();
    PartPixels pd;
    pd.chend = spec.nchannels;
    for (int c = 0; c < pd.chend; ++c) {
        pd.channels.push_back({pd.pixel_bytes, OIIO::TypeDesc::FLOAT});
        pd.pixel_bytes += sizeof(float);
    }
    const int nch = spec.nchannels;
    int z = -1, alpha = -1;
    for (int c = 0; c < nch; ++c) {
        const std::string n = spec.channel_name(c);
        if (n == "Z") {
            z = c;
        } else if (n == "A") {
            alpha = c;
        }
    }
    const std::int64_t npix = std::int64_t(spec.width) * spec.height;
    pd.bytes = std::size_t(npix) * pd.pixel_bytes;
    pd.data = raw_bytes(pd.bytes, spec.width, spec.height, nch);
    auto *out = reinterpret_cast<float *>(pd.data.get());
    parallel_for(0, spec.height, [&](int y) {
        std::vector<int> order;
        for (int x = 0; x < spec.width; ++x) {
            const std::int64_t pixel = std::int64_t(y) * spec.width + x;
            float *dst = out + std::size_t(pixel) * std::size_t(nch);
            const int n = int(deep.samples(pixel));
            order.resize(std::size_t(n));
            std::iota(order.begin(), order.end(), 0);
            if (z >= 0) {
                std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
                    return deep.deep_value(pixel, z, a) < deep.deep_value(pixel, z, b);
                });
            }
            std::fill(dst, dst + nch, 0.0f);
            float acc_alpha = 0.0f;
            for (int s : order) {
                const float transmit = 1.0f - acc_alpha;
                for (int c = 0; c < nch; ++c) {
                    if (c != z && c != alpha) {
                        dst[c] += transmit * deep.deep_value(pixel, c, s);
                    }
                }
                const float a = alpha >= 0 ? deep.deep_value(pixel, alpha, s) : 1.0f;
                acc_alpha += transmit * a;
            }
            if (alpha >= 0) {
                dst[alpha] = acc_alpha;
            }
            if (z >= 0) {
                dst[z] = n > 0 ? deep.deep_value(pixel, z, order[0])
                               : std::numeric_limits<float>::infinity();
            }
        }
    });
    return pd;
}

std::vector<SourceLevel> read_ripmap_levels(const std::string &path,
                                            int part,
                                            const OIIO::ImageSpec &spec)
{
    std::vector<SourceLevel> levels;
    try {
        Imf::MultiPartInputFile file(path.c_str());
        Imf::TiledInputPart in(file, part);
        const Imath::V2i origin = in.header().dataWindow().min;
        const std::size_t pixel_bytes = spec.pixel_bytes(/*native=*/true);
        // The levels together are up to three times level 0: within what the budget has left.
        std::size_t total = 0;
        for (int ly = 0; ly < in.numYLevels(); ++ly) {
            for (int lx = 0; lx < in.numXLevels(); ++lx) {
                total += (lx || ly) ? std::size_t(in.levelWidth(lx)) *
                                          std::size_t(in.levelHeight(ly)) * pixel_bytes
                                    : 0;
            }
        }
        const std::size_t budget = image_memory_budget(), used = image_memory_in_use();
        if (budget != 0 && total > (budget > used ? budget - used : 0)) {
            throw_runtime(path,
                          ": part ",
                          part,
                          ": its ripmap levels need ",
                          format_bytes(total),
                          ", more than the memory budget has left");
        }
        for (int ly = 0; ly < in.numYLevels(); ++ly) {
            for (int lx = 0; lx < in.numXLevels(); ++lx) {
                if (lx == 0 && ly == 0) {
                    continue;
                }
                SourceLevel level;
                level.lx = lx;
                level.ly = ly;
                level.spec = spec;
                level.spec.width = level.spec.full_width = in.levelWidth(lx);
                level.spec.height = level.spec.full_height = in.levelHeight(ly);
                auto buf = std::make_shared<std::vector<unsigned char>>(
                    std::size_t(level.spec.width) * std::size_t(level.spec.height) * pixel_bytes);
                Imf::FrameBuffer fb;
                std::size_t offset = 0;
                for (int c = 0; c < spec.nchannels; ++c) {
                    const OIIO::TypeDesc t = spec.channelformat(c);
                    fb.insert(spec.channel_name(c),
                              Imf::Slice::Make(exr_pixel_type(t),
                                               buf->data() + offset,
                                               origin,
                                               level.spec.width,
                                               level.spec.height,
                                               pixel_bytes,
                                               pixel_bytes * std::size_t(level.spec.width)));
                    offset += t.size();
                }
                in.setFrameBuffer(fb);
                in.readTiles(0, in.numXTiles(lx) - 1, 0, in.numYTiles(ly) - 1, lx, ly);
                level.pixels = std::move(buf);
                levels.push_back(std::move(level));
            }
        }
    } catch (const Iex::BaseExc &e) {
        std::string m = e.what();
        std::replace(m.begin(), m.end(), '\n', ' ');
        throw_runtime(path, ": part ", part, ": cannot read its ripmap levels: ", m);
    }
    return levels;
}

}  // namespace posthaste::io_detail
