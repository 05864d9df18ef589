#include "io/image_file.h"

#include <Imath/half.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#if defined(__x86_64__)
#include <immintrin.h>
#endif
#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include "core/error.h"
#include "core/parallel.h"
#include "core/passes.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;

// Attributes that describe the file's structure rather than the picture: not carried over.
bool is_structural_attribute(const std::string &name)
{
    static const std::set<std::string> kNames = {"compression",
                                                 "channelformats",
                                                 "oiio:subimages",
                                                 "oiio:subimagename",
                                                 "name",
                                                 "type",
                                                 "view",
                                                 "openexr:chunkCount",
                                                 "openexr:lineOrder",
                                                 "tiles",
                                                 "textureformat",
                                                 "oiio:ColorSpace",
                                                 "oiio:BitsPerSample",
                                                 "oiio:UnassociatedAlpha",
                                                 "openexr:roundingmode",
                                                 "openexr:levelmode",
                                                 "openexr:dwaCompressionLevel",
                                                 "Compression",
                                                 "PixelAspectRatio",
                                                 "smpte:TimeCode",
                                                 "oiio:Movie",
                                                 "oiio:updirection",
                                                 "oiio:sampleborder",
                                                 "png:compressionLevel",
                                                 "ImageDescription",
                                                 "Software",
                                                 "DateTime"};
    return kNames.count(name) != 0 || name.rfind("oiio:", 0) == 0 || name.rfind("tiff:", 0) == 0 ||
           name.rfind("png:", 0) == 0 || name.rfind("jpeg:", 0) == 0 || name.rfind("Exif:", 0) == 0;
}

bool is_camera_attribute(const std::string &name)
{
    static const std::set<std::string> kNames = {attr::kWorldToCamera,
                                                 attr::kWorldToNDC,
                                                 attr::kPrevWorldToCamera,
                                                 attr::kPrevWorldToNDC,
                                                 attr::kAperture,
                                                 attr::kFocus,
                                                 attr::kFocalLength,
                                                 attr::kSensorWidth,
                                                 attr::kSensorHeight,
                                                 attr::kShutter,
                                                 attr::kNearClip,
                                                 attr::kFarClip,
                                                 attr::kFrameNumber,
                                                 "FNumber"};
    return kNames.count(name) != 0;
}

std::string type_name(OIIO::TypeDesc t)
{
    if (t == OIIO::TypeDesc::HALF) {
        return "half";
    }
    if (t == OIIO::TypeDesc::FLOAT) {
        return "float";
    }
    if (t == OIIO::TypeDesc::UINT) {
        return "uint";
    }
    return t.c_str();
}

bool is_integer_type(OIIO::TypeDesc t)
{
    return t.basetype == OIIO::TypeDesc::UINT8 || t.basetype == OIIO::TypeDesc::UINT16 ||
           t.basetype == OIIO::TypeDesc::INT8 || t.basetype == OIIO::TypeDesc::INT16;
}

// The camera's header attributes, each once: read and write walk the same tables.
struct MatrixAttribute {
    const char *name;
    std::optional<glm::mat4> Camera::*member;
};
struct ScalarAttribute {
    const char *name;
    std::optional<float> Camera::*member;
};
constexpr MatrixAttribute kMatrixAttributes[] = {
    {attr::kWorldToCamera, &Camera::world_to_camera},
    {attr::kWorldToNDC, &Camera::world_to_ndc},
    {attr::kPrevWorldToCamera, &Camera::prev_world_to_camera},
    {attr::kPrevWorldToNDC, &Camera::prev_world_to_ndc},
};
constexpr ScalarAttribute kScalarAttributes[] = {
    {attr::kAperture, &Camera::fstop},
    {attr::kFocus, &Camera::focus_distance},
    {attr::kFocalLength, &Camera::focal_length_mm},
    {attr::kSensorWidth, &Camera::sensor_width_mm},
    {attr::kSensorHeight, &Camera::sensor_height_mm},
    {attr::kShutter, &Camera::shutter},
    {attr::kNearClip, &Camera::near_clip},
    {attr::kFarClip, &Camera::far_clip},
};

void read_camera(const OIIO::ImageSpec &spec, Camera &cam)
{
    for (const MatrixAttribute &a : kMatrixAttributes) {
        if (const OIIO::ParamValue *p = spec.find_attribute(a.name, OIIO::TypeMatrix44)) {
            glm::mat4 m;
            std::memcpy(&m, p->data(), sizeof(m));  // Imath and GLM share the layout
            cam.*a.member = m;
        }
    }
    auto scalar = [&](const char *name, std::optional<float> &out) {
        const OIIO::ParamValue *p = spec.find_attribute(name);
        if (p && (p->type() == OIIO::TypeFloat || p->type() == OIIO::TypeInt ||
                  p->type() == OIIO::TypeDesc::DOUBLE)) {
            out = p->get_float();
        }
    };
    for (const ScalarAttribute &a : kScalarAttributes) {
        scalar(a.name, cam.*a.member);
    }
    if (!cam.fstop) {
        scalar("FNumber", cam.fstop);  // OIIO reads EXR's standard "aperture" as Exif FNumber
    }
}

void write_camera(const Camera &cam, OIIO::ImageSpec &spec)
{
    for (const MatrixAttribute &a : kMatrixAttributes) {
        if (const auto &m = cam.*a.member) {
            spec.attribute(a.name, OIIO::TypeMatrix44, &*m);
        }
    }
    for (const ScalarAttribute &a : kScalarAttributes) {
        if (const auto &v = cam.*a.member) {
            spec.attribute(a.name, *v);
        }
    }
}

std::unique_ptr<OIIO::ImageInput> open_input(const std::string &path)
{
    std::error_code ec;
    if (!fs::exists(path, ec)) {
        throw_runtime(path, ": no such file");
    }
    if (fs::is_directory(path, ec)) {
        throw_runtime(path, ": is a directory, not an image");
    }
    if (fs::file_size(path, ec) == 0) {
        throw_runtime(path, ": empty file");
    }
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        std::string err = OIIO::geterror();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read image: ", err.empty() ? "unknown format" : err);
    }
    return in;
}

/// Convert `count` pixels of `channels` floats to halves; pixel i's halves go to
/// dst + i * dst_stride. Rounds to nearest even, like Imath::half.
void floats_to_halves_portable(
    const float *src, int channels, int count, unsigned char *dst, std::size_t dst_stride)
{
    for (int x = 0; x < count; ++x, dst += dst_stride, src += channels) {
        for (int c = 0; c < channels; ++c) {
            const Imath::half h(src[c]);
            std::memcpy(dst + std::size_t(c) * 2, &h, 2);
        }
    }
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("f16c"))) void floats_to_halves_f16c(
    const float *src, int channels, int count, unsigned char *dst, std::size_t dst_stride)
{
    for (int x = 0; x < count; ++x, dst += dst_stride, src += channels) {
        if (channels == 4) {
            const __m128i h = _mm_cvtps_ph(_mm_loadu_ps(src), _MM_FROUND_TO_NEAREST_INT);
            _mm_storel_epi64(reinterpret_cast<__m128i *>(dst), h);
            continue;
        }
        for (int c = 0; c < channels; ++c) {
            const unsigned short h = _cvtss_sh(src[c], _MM_FROUND_TO_NEAREST_INT);
            std::memcpy(dst + std::size_t(c) * 2, &h, 2);
        }
    }
}
#endif

/// floats_to_halves_portable, with the CPU's F16C instructions where it has them (the software
/// conversion was a quarter of a 1080p all-pass write).
void floats_to_halves(
    const float *src, int channels, int count, unsigned char *dst, std::size_t dst_stride)
{
#if defined(__x86_64__) && defined(__GNUC__)
    static const bool has_f16c = __builtin_cpu_supports("f16c");
    if (has_f16c) {
        floats_to_halves_f16c(src, channels, count, dst, dst_stride);
        return;
    }
#endif
    floats_to_halves_portable(src, channels, count, dst, dst_stride);
}

/// Copy `count` pixels of `channels` floats to dst + i * dst_stride. The per-pixel copy has a
/// size known at compile time so it inlines (a libc memmove per pixel dominated the write).
template <int N>
void scatter_floats_n(const float *src, int count, unsigned char *dst, std::size_t dst_stride)
{
    for (int x = 0; x < count; ++x, dst += dst_stride, src += N) {
        std::memcpy(dst, src, N * sizeof(float));
    }
}

void scatter_floats(
    const float *src, int channels, int count, unsigned char *dst, std::size_t dst_stride)
{
    switch (channels) {
        case 1:
            return scatter_floats_n<1>(src, count, dst, dst_stride);
        case 2:
            return scatter_floats_n<2>(src, count, dst, dst_stride);
        case 3:
            return scatter_floats_n<3>(src, count, dst, dst_stride);
        case 4:
            return scatter_floats_n<4>(src, count, dst, dst_stride);
        default:
            for (int x = 0; x < count; ++x, dst += dst_stride, src += channels) {
                std::memcpy(dst, src, std::size_t(channels) * sizeof(float));
            }
    }
}

float srgb_to_linear(float v)
{
    return v <= 0.04045f ? v / 12.92f : std::pow((v + 0.055f) / 1.055f, 2.4f);
}

}  // namespace

bool is_exr_path(const std::string &path)
{
    std::string ext = fs::path(path).extension().string();
    std::transform(
        ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".exr" || ext == ".sxr" || ext == ".mxr";
}

namespace {

FileInfo info_from_input(OIIO::ImageInput &in, const std::string &path, const ReadOptions &options)
{
    FileInfo info;
    info.path = path;
    info.format = in.format_name();
    std::vector<PartChannels> parts;
    for (int sub = 0; in.seek_subimage(sub, 0); ++sub) {
        const OIIO::ImageSpec &spec = in.spec();
        if (spec.deep) {
            throw_runtime(path, ": deep images are not supported (part ", sub, ")");
        }
        if (spec.nchannels <= 0 || spec.width <= 0 || spec.height <= 0 || spec.full_width <= 0 ||
            spec.full_height <= 0 || spec.full_width > kMaxImageSide ||
            spec.full_height > kMaxImageSide || spec.width > kMaxImageSide ||
            spec.height > kMaxImageSide) {
            throw_runtime(path,
                          ": part ",
                          sub,
                          " has an unsupported size: data window ",
                          spec.width,
                          "x",
                          spec.height,
                          ", display window ",
                          spec.full_width,
                          "x",
                          spec.full_height,
                          " (limit ",
                          kMaxImageSide,
                          ")");
        }
        FilePart part;
        part.name = spec.get_string_attribute("name");
        part.tiled = spec.tile_width > 0;
        part.compression = spec.get_string_attribute("compression");
        part.display_window = {spec.full_x,
                               spec.full_y,
                               spec.full_x + spec.full_width,
                               spec.full_y + spec.full_height};
        part.data_window = {spec.x - spec.full_x,
                            spec.y - spec.full_y,
                            spec.x - spec.full_x + spec.width,
                            spec.y - spec.full_y + spec.height};
        PartChannels pc;
        pc.part_name = part.name;
        for (int c = 0; c < spec.nchannels; ++c) {
            std::string name = spec.channel_name(c);
            // Parts after the first may store bare channel names; their layer is the part name.
            if (sub > 0 && !part.name.empty() && name.find('.') == std::string::npos) {
                name = part.name + "." + name;
            }
            part.channels.push_back({name, type_name(spec.channelformat(c))});
            pc.names.push_back(name);
        }
        if (sub == 0) {
            info.width = spec.full_width;
            info.height = spec.full_height;
            read_camera(spec, info.camera);
            for (const OIIO::ParamValue &p : spec.extra_attribs) {
                const std::string n = p.name().string();
                if (!is_structural_attribute(n) && !is_camera_attribute(n)) {
                    info.attributes.push_back(p);
                }
            }
        } else if (spec.full_width != info.width || spec.full_height != info.height) {
            throw_runtime(path,
                          ": part ",
                          sub,
                          " has display window ",
                          spec.full_width,
                          "x",
                          spec.full_height,
                          " but part 0 has ",
                          info.width,
                          "x",
                          info.height);
        }
        info.parts.push_back(std::move(part));
        parts.push_back(std::move(pc));
    }
    if (info.parts.empty()) {
        throw_runtime(path, ": no image in file");
    }
    info.passes = map_channels(parts, options.aliases);
    return info;
}

/// One channel of a part's native pixel buffer.
struct NativeChannel {
    std::size_t offset = 0;  ///< Byte offset within a pixel.
    OIIO::TypeDesc type;
};

/// A part's needed channel span, read at native pixel types (converted here, in parallel,
/// rather than by OIIO on one thread).
struct PartPixels {
    int chbegin = 0, chend = 0;
    std::size_t pixel_bytes = 0;
    std::vector<NativeChannel> channels;  ///< By channel - chbegin.
    std::unique_ptr<unsigned char[]> data;
};

/// Convert `count` values of one native channel to float, `src` stepping `stride` bytes.
void convert_channel(const unsigned char *src,
                     std::size_t stride,
                     OIIO::TypeDesc type,
                     float *dst,
                     std::size_t dst_stride,
                     int count)
{
    switch (type.basetype) {
        case OIIO::TypeDesc::HALF:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                Imath::half h;
                std::memcpy(&h, src, sizeof(h));
                *dst = float(h);
            }
            break;
        case OIIO::TypeDesc::FLOAT:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::memcpy(dst, src, sizeof(float));
            }
            break;
        case OIIO::TypeDesc::DOUBLE:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                double d;
                std::memcpy(&d, src, sizeof(d));
                *dst = float(d);
            }
            break;
        case OIIO::TypeDesc::UINT:  // ids: integers, not normalised
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::uint32_t u;
                std::memcpy(&u, src, sizeof(u));
                *dst = float(u);
            }
            break;
        case OIIO::TypeDesc::UINT8:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                *dst = float(*src) * (1.0f / 255.0f);
            }
            break;
        case OIIO::TypeDesc::UINT16:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::uint16_t u;
                std::memcpy(&u, src, sizeof(u));
                *dst = float(u) * (1.0f / 65535.0f);
            }
            break;
        case OIIO::TypeDesc::INT8:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                *dst = std::max(-1.0f, float(std::int8_t(*src)) * (1.0f / 127.0f));
            }
            break;
        case OIIO::TypeDesc::INT16:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::int16_t v;
                std::memcpy(&v, src, sizeof(v));
                *dst = std::max(-1.0f, float(v) * (1.0f / 32767.0f));
            }
            break;
        default:
            for (int i = 0; i < count; ++i, dst += dst_stride) {
                *dst = 0.0f;  // types refused when the part is read
            }
            break;
    }
}

bool supported_native(OIIO::TypeDesc t)
{
    switch (t.basetype) {
        case OIIO::TypeDesc::HALF:
        case OIIO::TypeDesc::FLOAT:
        case OIIO::TypeDesc::DOUBLE:
        case OIIO::TypeDesc::UINT:
        case OIIO::TypeDesc::UINT8:
        case OIIO::TypeDesc::UINT16:
        case OIIO::TypeDesc::INT8:
        case OIIO::TypeDesc::INT16:
            return t.aggregate == OIIO::TypeDesc::SCALAR;
        default:
            return false;
    }
}

}  // namespace

FileInfo read_file_info(const std::string &path, const ReadOptions &options)
{
    auto in = open_input(path);
    return info_from_input(*in, path, options);
}

Frame read_frame(const std::string &path,
                 const std::set<std::string> *wanted,
                 int frame_number,
                 const ReadOptions &options)
{
    auto in = open_input(path);
    const FileInfo info = info_from_input(*in, path, options);
    std::vector<const PassSource *> selected;
    if (wanted) {
        for (const std::string &name : *wanted) {
            auto it = std::find_if(info.passes.begin(),
                                   info.passes.end(),
                                   [&](const PassSource &p) { return p.pass == name; });
            if (it == info.passes.end()) {
                std::string have;
                for (const PassSource &p : info.passes) {
                    have += (have.empty() ? "" : ", ") + p.pass;
                }
                throw_runtime(path, ": no pass \"", name, "\" in file (have: ", have, ")");
            }
            selected.push_back(&*it);
        }
    } else {
        for (const PassSource &p : info.passes) {
            selected.push_back(&p);
        }
    }

    Frame frame;
    frame.number = frame_number;
    frame.width = info.width;
    frame.height = info.height;
    frame.camera = info.camera;
    frame.attributes = info.attributes;

    // Read, per part, the span of channels that covers every selected channel, natively.
    std::vector<PartPixels> data(info.parts.size());
    std::vector<std::set<int>> needed(info.parts.size());
    for (const PassSource *ps : selected) {
        for (const ChannelSource &cs : ps->sources) {
            if (cs.part >= 0) {
                needed[std::size_t(cs.part)].insert(cs.channel);
            }
        }
    }
    bool srgb_encoded = false;
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        if (needed[p].empty()) {
            continue;
        }
        if (!in->seek_subimage(int(p), 0)) {
            throw_runtime(path, ": cannot seek to part ", p, ": ", in->geterror());
        }
        const OIIO::ImageSpec spec = in->spec();
        PartPixels &pd = data[p];
        pd.chbegin = *needed[p].begin();
        pd.chend = *needed[p].rbegin() + 1;
        for (int c = pd.chbegin; c < pd.chend; ++c) {
            const OIIO::TypeDesc t = spec.channelformat(c);
            if (!supported_native(t)) {
                throw_runtime(path,
                              ": channel \"",
                              spec.channel_name(c),
                              "\" has pixel type ",
                              t.c_str(),
                              ", which is not supported");
            }
            pd.channels.push_back({pd.pixel_bytes, t});
            pd.pixel_bytes += t.size();
        }
        const std::size_t npix = std::size_t(spec.width) * std::size_t(spec.height);
        pd.data = std::make_unique_for_overwrite<unsigned char[]>(npix * pd.pixel_bytes);
        if (!in->read_image(int(p), 0, pd.chbegin, pd.chend, OIIO::TypeUnknown, pd.data.get())) {
            std::string err = in->geterror();
            std::replace(err.begin(), err.end(), '\n', ' ');
            throw_runtime(
                path, ": cannot read pixels of part ", p, " (truncated or corrupt?): ", err);
        }
        if (p == 0 && is_integer_type(spec.format) && options.linearize) {
            const std::string cs = spec.get_string_attribute("oiio:ColorSpace", "sRGB");
            srgb_encoded = cs.empty() || OIIO::Strutil::iequals(cs, "sRGB");
        }
    }

    const int width = info.width, height = info.height;
    for (const PassSource *ps : selected) {
        const int nch = int(ps->sources.size());
        Image img = Image::uninitialized(width, height, nch);
        const bool is_depth = ps->pass == pass::kDepth;
        const bool linearize = srgb_encoded && ps->pass == pass::kColor;
        // First bad value per row (x, channel), for BadPixels::Error; -1 when none.
        std::vector<std::pair<int, int>> bad(std::size_t(height), {-1, -1});
        parallel_for(0, height, [&](int y) {
            float *row = img.pixel(0, y);
            for (int k = 0; k < nch; ++k) {
                const ChannelSource &cs = ps->sources[std::size_t(k)];
                float *out = row + k;
                const std::size_t step = std::size_t(nch);
                if (cs.part < 0) {
                    for (int x = 0; x < width; ++x) {
                        out[std::size_t(x) * step] = cs.offset;
                    }
                    continue;
                }
                const FilePart &part = info.parts[std::size_t(cs.part)];
                const PartPixels &pd = data[std::size_t(cs.part)];
                const Rect &dw = part.data_window;
                const float outside = (ps->pass == pass::kColor && k == 3) ? 0.0f
                                      : is_depth ? std::numeric_limits<float>::infinity()
                                                 : 0.0f;
                const int x0 = std::clamp(dw.x0, 0, width), x1 = std::clamp(dw.x1, 0, width);
                if (y < dw.y0 || y >= dw.y1 || x0 >= x1) {
                    for (int x = 0; x < width; ++x) {
                        out[std::size_t(x) * step] = outside;
                    }
                    continue;
                }
                for (int x = 0; x < x0; ++x) {
                    out[std::size_t(x) * step] = outside;
                }
                for (int x = x1; x < width; ++x) {
                    out[std::size_t(x) * step] = outside;
                }
                const NativeChannel &nc = pd.channels[std::size_t(cs.channel - pd.chbegin)];
                const std::size_t first =
                    std::size_t(y - dw.y0) * std::size_t(dw.width()) + std::size_t(x0 - dw.x0);
                convert_channel(pd.data.get() + first * pd.pixel_bytes + nc.offset,
                                pd.pixel_bytes,
                                nc.type,
                                out + std::size_t(x0) * step,
                                step,
                                x1 - x0);
                const bool affine = cs.scale != 1.0f || cs.offset != 0.0f;
                const bool lin = linearize && k < 3;
                const bool clip_inf = ps->infinite_above > 0.0f;
                const bool check_bad = options.bad_pixels != BadPixels::Keep;
                if (!(affine || lin || clip_inf || check_bad)) {
                    continue;
                }
                for (int x = x0; x < x1; ++x) {
                    float &v = out[std::size_t(x) * step];
                    if (lin) {
                        v = srgb_to_linear(v);
                    }
                    if (affine) {
                        v = cs.scale * v + cs.offset;
                    }
                    if (clip_inf && v >= ps->infinite_above) {
                        v = std::numeric_limits<float>::infinity();
                    }
                    if (check_bad && !std::isfinite(v) && !(is_depth && v > 0.0f)) {
                        if (options.bad_pixels == BadPixels::Zero) {
                            v = 0.0f;
                        } else if (bad[std::size_t(y)].first < 0 ||
                                   std::make_pair(x, k) < bad[std::size_t(y)]) {
                            bad[std::size_t(y)] = {x, k};
                        }
                    }
                }
            }
        });
        for (int y = 0; y < height; ++y) {
            if (bad[std::size_t(y)].first >= 0) {
                const auto [x, k] = bad[std::size_t(y)];
                throw_runtime(path,
                              ": pass \"",
                              ps->pass,
                              "\" channel \"",
                              ps->sources[std::size_t(k)].name,
                              "\" has a NaN or infinite value at (",
                              x,
                              ", ",
                              y,
                              ")");
            }
        }
        frame.set(ps->pass, std::make_shared<const Image>(std::move(img)), ps->channel_suffixes);
    }
    return frame;
}

void check_compression(const std::string &compression, const std::string &where)
{
    static const std::vector<std::string> kNames = {
        "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};
    std::string base = compression.substr(0, compression.find(':'));
    if (std::find(kNames.begin(), kNames.end(), base) == kNames.end()) {
        throw_usage(where,
                    ": unknown EXR compression \"",
                    compression,
                    "\" (expected none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab)");
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

void atomic_write(const std::string &path, const std::function<void(const std::string &)> &write)
{
    const fs::path target(path);
    std::error_code ec;
    if (target.has_parent_path()) {
        fs::create_directories(target.parent_path(), ec);
        if (ec) {
            throw_runtime(path,
                          ": cannot create directory ",
                          target.parent_path().string(),
                          ": ",
                          ec.message());
        }
    }
    // Keep the extension last: OIIO picks the writer from it.
    thread_local std::mt19937 rng(std::random_device{}());
    const std::string tmp =
        (target.parent_path() / ("." + target.stem().string() + ".tmp" +
                                 std::to_string(::getpid()) + "-" + std::to_string(rng() % 100000)))
            .string() +
        target.extension().string();
    try {
        write(tmp);
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    fs::rename(tmp, target, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw_runtime(path, ": cannot rename temporary file into place: ", ec.message());
    }
}

void write_exr(const Frame &frame, const std::string &path, const WriteOptions &options)
{
    check_compression(options.compression, path);
    std::vector<std::string> names = options.passes;
    if (names.empty()) {
        names = frame.pass_names();
        // Canonical passes first, in table order, then the rest alphabetically.
        std::stable_sort(
            names.begin(), names.end(), [](const std::string &a, const std::string &b) {
                auto rank = [](const std::string &n) {
                    int i = 0;
                    for (const pass::CanonicalPass &cp : pass::canonical_passes()) {
                        if (cp.name == n) {
                            return i;
                        }
                        ++i;
                    }
                    return 1000;
                };
                return rank(a) < rank(b);
            });
    }
    if (names.empty()) {
        throw_runtime(path, ": nothing to write: the frame has no passes");
    }
    const std::string base = options.compression.substr(0, options.compression.find(':'));
    const bool lossy_for_data = base == "dwaa" || base == "dwab" || base == "pxr24";

    struct Layer {
        const Pass *pass;
        std::vector<std::string> channel_names;
        OIIO::TypeDesc type;
    };
    std::vector<Layer> layers;
    for (const std::string &name : names) {
        const Pass &p = frame.pass(name, path);
        Layer l{&p, pass::exr_channel_names(name, p.channels), OIIO::TypeDesc::FLOAT};
        const pass::CanonicalPass *cp = pass::find_canonical(name);
        PixelStorage storage = p.storage;
        if (auto it = options.storage.find(name); it != options.storage.end()) {
            storage = it->second;
        }
        if (storage == PixelStorage::Auto) {
            storage = (cp && cp->half_by_default) ? PixelStorage::Half : PixelStorage::Float;
        }
        l.type = storage == PixelStorage::Half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT;
        const bool data_pass = !(name == pass::kColor || name == pass::kAlbedo);
        if (lossy_for_data && data_pass && !options.allow_lossy_data) {
            throw_usage(path,
                        ": compression \"",
                        options.compression,
                        "\" is lossy on data pass \"",
                        name,
                        "\"; choose a lossless compression or allow lossy data passes");
        }
        layers.push_back(std::move(l));
    }

    auto base_spec = [&](int nchannels) {
        OIIO::ImageSpec spec(frame.width, frame.height, nchannels, OIIO::TypeDesc::FLOAT);
        for (const OIIO::ParamValue &p : frame.attributes) {
            spec.extra_attribs.push_back(p);
        }
        write_camera(frame.camera, spec);
        spec.attribute(attr::kFrameNumber, frame.number);
        spec.attribute("compression", options.compression);
        return spec;
    };

    atomic_write(path, [&](const std::string &tmp) {
        auto out = OIIO::ImageOutput::create("exr");
        if (!out) {
            throw_runtime(path, ": no EXR writer: ", OIIO::geterror());
        }
        std::vector<OIIO::ImageSpec> specs;
        std::vector<std::vector<const Layer *>> part_layers;
        if (options.multipart) {
            for (const Layer &l : layers) {
                specs.push_back(base_spec(int(l.channel_names.size())));
                specs.back().channelnames = l.channel_names;
                specs.back().channelformats.assign(l.channel_names.size(), l.type);
                const auto cp = pass::find_canonical(names[std::size_t(&l - layers.data())]);
                specs.back().attribute("name",
                                       cp && cp->name == pass::kColor
                                           ? std::string("rgba")
                                           : names[std::size_t(&l - layers.data())]);
                part_layers.push_back({&l});
            }
        } else {
            int total = 0;
            for (const Layer &l : layers) {
                total += int(l.channel_names.size());
            }
            specs.push_back(base_spec(total));
            specs.back().channelnames.clear();
            specs.back().channelformats.clear();
            part_layers.emplace_back();
            for (const Layer &l : layers) {
                for (const std::string &c : l.channel_names) {
                    specs.back().channelnames.push_back(c);
                    specs.back().channelformats.push_back(l.type);
                }
                part_layers.back().push_back(&l);
            }
            if (total > kMaxChannels * 4) {
                throw_runtime(path, ": too many channels (", total, ")");
            }
        }
        if (!out->open(tmp, int(specs.size()), specs.data())) {
            throw_runtime(path, ": cannot open for writing: ", out->geterror());
        }
        for (std::size_t part = 0; part < specs.size(); ++part) {
            if (part > 0 && !out->open(tmp, specs[part], OIIO::ImageOutput::AppendSubimage)) {
                throw_runtime(path, ": cannot append part ", part, ": ", out->geterror());
            }
            // Native per-channel layout (half or float), converted here in parallel so OIIO
            // only compresses.
            std::size_t pixel_bytes = 0;
            for (const Layer *l : part_layers[part]) {
                pixel_bytes += l->channel_names.size() * l->type.size();
            }
            const std::size_t row_bytes = pixel_bytes * std::size_t(frame.width);
            auto buf = std::make_unique_for_overwrite<unsigned char[]>(row_bytes *
                                                                       std::size_t(frame.height));
            std::size_t offset = 0;
            for (const Layer *l : part_layers[part]) {
                const Image &img = *l->pass->image;
                const int lc = img.channels();
                const bool half = l->type == OIIO::TypeDesc::HALF;
                parallel_for(0, frame.height, [&](int y) {
                    const float *src = img.pixel(0, y);
                    unsigned char *dst = buf.get() + std::size_t(y) * row_bytes + offset;
                    if (half) {
                        floats_to_halves(src, lc, frame.width, dst, pixel_bytes);
                        return;
                    }
                    scatter_floats(src, lc, frame.width, dst, pixel_bytes);
                });
                offset += std::size_t(lc) * l->type.size();
            }
            if (!out->write_image(OIIO::TypeUnknown, buf.get())) {
                throw_runtime(path, ": cannot write pixels: ", out->geterror());
            }
        }
        if (!out->close()) {
            throw_runtime(path, ": cannot finish writing: ", out->geterror());
        }
    });
}

void write_preview(const Image &display_rgba, const std::string &path, bool with_alpha)
{
    const int nch = with_alpha && display_rgba.channels() >= 4 ? 4 : 3;
    std::vector<std::uint8_t> buf(display_rgba.pixel_count() * std::size_t(nch));
    for (int y = 0; y < display_rgba.height(); ++y) {
        for (int x = 0; x < display_rgba.width(); ++x) {
            const float *p = display_rgba.pixel(x, y);
            for (int c = 0; c < nch; ++c) {
                float v = c < display_rgba.channels() ? p[c] : 1.0f;
                v = std::isfinite(v) ? std::clamp(v, 0.0f, 1.0f) : 0.0f;
                buf[(std::size_t(y) * std::size_t(display_rgba.width()) + std::size_t(x)) *
                        std::size_t(nch) +
                    std::size_t(c)] = std::uint8_t(std::lround(v * 255.0f));
            }
        }
    }
    atomic_write(path, [&](const std::string &tmp) {
        auto out = OIIO::ImageOutput::create(path);
        if (!out) {
            throw_runtime(path, ": no writer for this file type: ", OIIO::geterror());
        }
        OIIO::ImageSpec spec(
            display_rgba.width(), display_rgba.height(), nch, OIIO::TypeDesc::UINT8);
        spec.attribute("oiio:ColorSpace", "sRGB");
        if (!out->open(tmp, spec) || !out->write_image(OIIO::TypeDesc::UINT8, buf.data()) ||
            !out->close()) {
            throw_runtime(path, ": cannot write preview: ", out->geterror());
        }
    });
}

}  // namespace posthaste
