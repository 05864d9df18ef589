// Files OpenImageIO does not hand over as flat native pixels: luminance/chroma EXRs through
// OpenEXR's RGBA interface, deep parts flattened front to back, ripmap levels through OpenEXR
// (io/read_detail.h).

#include <IexBaseExc.h>
#include <ImfBoxAttribute.h>
#include <ImfChromaticitiesAttribute.h>
#include <ImfDoubleAttribute.h>
#include <ImfFloatAttribute.h>
#include <ImfFloatVectorAttribute.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIntAttribute.h>
#include <ImfKeyCodeAttribute.h>
#include <ImfMatrixAttribute.h>
#include <ImfMultiPartInputFile.h>
#include <ImfRationalAttribute.h>
#include <ImfRgbaFile.h>
#include <ImfStringAttribute.h>
#include <ImfStringVectorAttribute.h>
#include <ImfTiledInputPart.h>
#include <ImfTimeCodeAttribute.h>
#include <ImfVecAttribute.h>
#include <OpenImageIO/deepdata.h>

#include <algorithm>
#include <cmath>
#include <fstream>
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

namespace {

/// An OpenEXR attribute as OpenImageIO's EXR reader would hand it over (its type; the name as
/// the file has it, which the writer maps back): false for types with no such form (previews,
/// opaque types, the header's own enums).
bool to_param(const std::string &name, const Imf::Attribute &a, OIIO::ParamValueList &out)
{
    using OIIO::TypeDesc;
    auto add = [&](TypeDesc t, const void *data) {
        out.push_back(OIIO::ParamValue(name, t, 1, data));
    };
    if (const auto *v = dynamic_cast<const Imf::IntAttribute *>(&a)) {
        add(OIIO::TypeInt, &v->value());
    } else if (const auto *v = dynamic_cast<const Imf::FloatAttribute *>(&a)) {
        add(OIIO::TypeFloat, &v->value());
    } else if (const auto *v = dynamic_cast<const Imf::DoubleAttribute *>(&a)) {
        add(TypeDesc::DOUBLE, &v->value());
    } else if (const auto *v = dynamic_cast<const Imf::StringAttribute *>(&a)) {
        out.push_back(OIIO::ParamValue(name, v->value()));
    } else if (const auto *v = dynamic_cast<const Imf::V2iAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::INT, TypeDesc::VEC2), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::V2fAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::FLOAT, TypeDesc::VEC2), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::V2dAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::DOUBLE, TypeDesc::VEC2), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::V3iAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::INT, TypeDesc::VEC3), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::V3fAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::FLOAT, TypeDesc::VEC3), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::V3dAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::DOUBLE, TypeDesc::VEC3), &v->value().x);
    } else if (const auto *v = dynamic_cast<const Imf::M33fAttribute *>(&a)) {
        add(OIIO::TypeMatrix33, &v->value()[0][0]);
    } else if (const auto *v = dynamic_cast<const Imf::M33dAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::DOUBLE, TypeDesc::MATRIX33), &v->value()[0][0]);
    } else if (const auto *v = dynamic_cast<const Imf::M44fAttribute *>(&a)) {
        add(OIIO::TypeMatrix44, &v->value()[0][0]);
    } else if (const auto *v = dynamic_cast<const Imf::M44dAttribute *>(&a)) {
        add(TypeDesc(TypeDesc::DOUBLE, TypeDesc::MATRIX44), &v->value()[0][0]);
    } else if (const auto *v = dynamic_cast<const Imf::Box2iAttribute *>(&a)) {
        const int b[4] = {v->value().min.x, v->value().min.y, v->value().max.x, v->value().max.y};
        add(TypeDesc(TypeDesc::INT, TypeDesc::VEC2, 2), b);
    } else if (const auto *v = dynamic_cast<const Imf::Box2fAttribute *>(&a)) {
        const float b[4] = {v->value().min.x, v->value().min.y, v->value().max.x, v->value().max.y};
        add(TypeDesc(TypeDesc::FLOAT, TypeDesc::VEC2, 2), b);
    } else if (const auto *v = dynamic_cast<const Imf::FloatVectorAttribute *>(&a)) {
        if (v->value().empty()) {
            return false;
        }
        out.push_back(OIIO::ParamValue(
            name, TypeDesc(TypeDesc::FLOAT, int(v->value().size())), 1, v->value().data()));
    } else if (const auto *v = dynamic_cast<const Imf::StringVectorAttribute *>(&a)) {
        std::vector<OIIO::ustring> strings;
        for (const std::string &x : v->value()) {
            strings.emplace_back(x);
        }
        if (strings.empty()) {
            return false;
        }
        out.push_back(OIIO::ParamValue(
            name, TypeDesc(TypeDesc::STRING, int(strings.size())), 1, strings.data()));
    } else if (const auto *v = dynamic_cast<const Imf::RationalAttribute *>(&a)) {
        const int r[2] = {v->value().n, int(v->value().d)};
        add(OIIO::TypeRational, r);
    } else if (const auto *v = dynamic_cast<const Imf::TimeCodeAttribute *>(&a)) {
        const unsigned t[2] = {v->value().timeAndFlags(), v->value().userData()};
        add(OIIO::TypeTimeCode, t);
    } else if (const auto *v = dynamic_cast<const Imf::KeyCodeAttribute *>(&a)) {
        const Imf::KeyCode &k = v->value();
        const int c[7] = {k.filmMfcCode(),
                          k.filmType(),
                          k.prefix(),
                          k.count(),
                          k.perfOffset(),
                          k.perfsPerFrame(),
                          k.perfsPerCount()};
        add(OIIO::TypeKeyCode, c);
    } else if (const auto *v = dynamic_cast<const Imf::ChromaticitiesAttribute *>(&a)) {
        const Imf::Chromaticities &c = v->value();
        const float f[8] = {
            c.red.x, c.red.y, c.green.x, c.green.y, c.blue.x, c.blue.y, c.white.x, c.white.y};
        add(TypeDesc(TypeDesc::FLOAT, 8), f);
    } else {
        return false;
    }
    return true;
}

}  // namespace

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
        // The header's attributes as the other reads take them (OpenImageIO refuses these
        // files): the camera's into the camera, the rest into the frame's attributes (every one
        // was dropped here, the camera's scalars too).
        const Imf::Header &h = f.header();
        OIIO::ImageSpec spec;
        for (auto it = h.begin(); it != h.end(); ++it) {
            const std::string name = it.name();
            if (name == "dataWindow" || name == "displayWindow" || name == "channels") {
                continue;
            }
            to_param(name, it.attribute(), spec.extra_attribs);
        }
        read_camera(spec, info.camera);
        for (const OIIO::ParamValue &p : spec.extra_attribs) {
            if (is_frame_attribute(p.name().string()) && p.name() != "pixelAspectRatio" &&
                p.name() != "screenWindowCenter" && p.name() != "screenWindowWidth") {
                info.attributes.push_back(p);
            }
        }
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

bool float_reproduces(OIIO::TypeDesc type, const ChannelSource &cs, const PassSource &ps, bool lin)
{
    const bool exact_type =
        type.basetype == OIIO::TypeDesc::HALF || type.basetype == OIIO::TypeDesc::FLOAT;
    const bool exact_map = (cs.scale == 1.0f || cs.scale == -1.0f) && cs.offset == 0.0f;
    return exact_type && exact_map && !(ps.infinite_above > 0.0f) && !lin;
}

void check_image_ends(const std::string &path, const std::string &format)
{
    // JPEG's end-of-image marker; PNG's IEND chunk (no data, its CRC).
    static const std::string jpeg_end = "\xFF\xD9";
    static const std::string png_end("\0\0\0\0IEND\xAE\x42\x60\x82", 12);
    const bool jpeg = format == "jpeg";
    if (!jpeg && format != "png") {
        return;
    }
    const std::string &want = jpeg ? jpeg_end : png_end;
    std::ifstream f(path, std::ios::binary | std::ios::ate);
    std::string end(want.size(), '\0');
    if (f && f.tellg() >= std::streamoff(want.size())) {
        f.seekg(-std::streamoff(want.size()), std::ios::end);
        f.read(end.data(), std::streamsize(end.size()));
    }
    if (!f || end != want) {
        throw_runtime(path,
                      jpeg ? ": the JPEG is cut short (no end-of-image marker)"
                           : ": the PNG is cut short (no IEND chunk at its end)");
    }
}

}  // namespace posthaste::io_detail
