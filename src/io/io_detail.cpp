#include "io/io_detail.h"

#include <OpenImageIO/strutil.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <numeric>
#include <set>
#include <string_view>

#include "core/error.h"
#include "core/memory.h"

namespace posthaste::io_detail {
namespace fs = std::filesystem;

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
                                                 "oiio:Movie",
                                                 "oiio:updirection",
                                                 "oiio:sampleborder",
                                                 "png:compressionLevel"};
    return kNames.count(name) != 0 || name.rfind("oiio:", 0) == 0 || name.rfind("tiff:", 0) == 0 ||
           name.rfind("png:", 0) == 0 || name.rfind("jpeg:", 0) == 0;
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

namespace {

// The camera's matrix attributes, each once: read and write walk the same table (the scalars'
// is core/camera.h's kCameraScalarAttributes).
struct MatrixAttribute {
    const char *name;
    std::optional<glm::mat4> Camera::*member;
};
constexpr MatrixAttribute kMatrixAttributes[] = {
    {attr::kWorldToCamera, &Camera::world_to_camera},
    {attr::kWorldToNDC, &Camera::world_to_ndc},
    {attr::kPrevWorldToCamera, &Camera::prev_world_to_camera},
    {attr::kPrevWorldToNDC, &Camera::prev_world_to_ndc},
};

}  // namespace

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
    for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
        scalar(a.name, cam.*a.member);
    }
    if (!cam.fstop) {
        scalar("FNumber", cam.fstop);  // OIIO reads EXR's standard "aperture" as Exif FNumber
    }
}

void write_camera(const Camera &cam, OIIO::ImageSpec &spec, const Camera *before)
{
    for (const MatrixAttribute &a : kMatrixAttributes) {
        if (const auto &m = cam.*a.member) {
            if (!before || before->*a.member != m) {
                spec.attribute(a.name, OIIO::TypeMatrix44, &*m);
            }
        } else if (before && before->*a.member) {
            spec.erase_attribute(a.name);
        }
    }
    for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
        if (const auto &v = cam.*a.member) {
            if (!before || before->*a.member != v) {
                spec.attribute(a.name, *v);
            }
        } else if (before && before->*a.member) {
            spec.erase_attribute(a.name);
            if (a.member == &Camera::fstop) {
                spec.erase_attribute("FNumber");  // OpenImageIO's name for EXR's aperture
            }
        }
    }
}

namespace {

/// The bytes OpenEXR 3.1 reads for a value of a fixed-size attribute type, or -1 (variable:
/// chlist, preview, string, stringvector, floatvector, unknown types).
int fixed_attribute_size(const std::string &type)
{
    static const std::map<std::string, int> kSizes = {{"box2i", 16},
                                                      {"box2f", 16},
                                                      {"chromaticities", 32},
                                                      {"compression", 1},
                                                      {"deepImageState", 1},
                                                      {"double", 8},
                                                      {"envmap", 1},
                                                      {"float", 4},
                                                      {"int", 4},
                                                      {"keycode", 28},
                                                      {"lineOrder", 1},
                                                      {"m33d", 72},
                                                      {"m33f", 36},
                                                      {"m44d", 128},
                                                      {"m44f", 64},
                                                      {"rational", 8},
                                                      {"tiledesc", 9},
                                                      {"timecode", 8},
                                                      {"v2i", 8},
                                                      {"v2f", 8},
                                                      {"v2d", 16},
                                                      {"v3i", 12},
                                                      {"v3f", 12},
                                                      {"v3d", 24}};
    const auto it = kSizes.find(type);
    return it == kSizes.end() ? -1 : it->second;
}

}  // namespace

std::string exr_header_problem(std::istream &in,
                               std::uint64_t file_size,
                               std::vector<ExrPartLayout> *parts)
{
    // Layout: magic (4), version and flags (4), then one header (single part) or several
    // headers ended by an empty one (multi-part); a header is attributes ended by a 0 byte, an
    // attribute is name\0 type\0 int32 size, then size bytes.
    unsigned char version[4] = {};
    if (!in.read(reinterpret_cast<char *>(version), 4)) {
        return "truncated before the header";
    }
    // Flags live in bits 8-15 of the version field: 0x10 there is "multi-part". OpenEXR reads
    // names up to 255 characters whatever the long-names flag says, and so does this walk.
    const bool multipart = (version[1] & 0x10) != 0;
    const std::size_t max_name = 255;
    std::uint64_t pos = 8;
    auto read_name = [&](std::string &name) -> bool {
        name.clear();
        for (;;) {
            const int c = in.get();
            if (c == std::char_traits<char>::eof()) {
                return false;
            }
            ++pos;
            if (c == 0) {
                return true;
            }
            if (name.size() >= max_name) {
                return false;
            }
            name.push_back(char(c));
        }
    };
    auto le32 = [](const unsigned char *b) {
        return std::int32_t(std::uint32_t(b[0]) | std::uint32_t(b[1]) << 8 |
                            std::uint32_t(b[2]) << 16 | std::uint32_t(b[3]) << 24);
    };
    std::vector<ExrPartLayout> found;
    for (int header = 0;; ++header) {
        std::string name;
        std::string type;
        ExrPartLayout part;
        int attributes = 0;
        for (;; ++attributes) {
            if (!read_name(name)) {
                return "header " + std::to_string(header) +
                       " is truncated or has an over-long name";
            }
            if (name.empty()) {
                break;
            }
            if (!read_name(type)) {
                return "attribute \"" + name + "\" has no readable type name";
            }
            unsigned char b[4];
            if (!in.read(reinterpret_cast<char *>(b), 4)) {
                return "attribute \"" + name + "\" is truncated";
            }
            pos += 4;
            const std::int32_t size = le32(b);
            if (size < 0 || std::uint64_t(size) > file_size - pos) {
                return "attribute \"" + name + "\" claims " + std::to_string(size) +
                       " bytes, more than the file's remaining " + std::to_string(file_size - pos);
            }
            // Advance exactly as OpenEXR 3.1 does, or the walk and OpenEXR would read different
            // attributes from the same bytes: a known fixed-size type reads its own size whatever
            // the size field says, a channel list reads entries up to an empty name, a preview
            // reads its width x height pixels; everything else (strings, vectors, unknown
            // types) reads `size` bytes.
            const int fixed = fixed_attribute_size(type);
            if (type == "chlist") {
                for (;;) {
                    std::string channel;
                    if (!read_name(channel)) {
                        return "attribute \"" + name + "\" has a truncated channel list";
                    }
                    if (channel.empty()) {
                        break;
                    }
                    unsigned char c[16];
                    if (!in.read(reinterpret_cast<char *>(c), 16)) {
                        return "attribute \"" + name + "\" has a truncated channel list";
                    }
                    pos += 16;
                    // OpenImageIO 2.4 aborts the process on a pixel type it does not know.
                    const std::int32_t pixel_type = le32(c);
                    if (pixel_type < 0 || pixel_type > 2) {
                        return "channel \"" + channel + "\" has pixel type " +
                               std::to_string(pixel_type) + " (0 uint, 1 half and 2 float exist)";
                    }
                    part.bytes_per_pixel += pixel_type == 1 ? 2 : 4;
                }
            } else if (type == "preview") {
                unsigned char wh[8];
                if (!in.read(reinterpret_cast<char *>(wh), 8)) {
                    return "attribute \"" + name + "\" is truncated";
                }
                pos += 8;
                const std::uint64_t w = std::uint32_t(le32(wh)), h = std::uint32_t(le32(wh + 4));
                if (w * h * 4 > file_size - pos) {
                    return "preview attribute \"" + name + "\" claims " + std::to_string(w) + "x" +
                           std::to_string(h) + " pixels, more than the file holds";
                }
                std::vector<char> value(std::size_t(8 + w * h * 4));
                std::copy(wh, wh + 8, value.begin());
                if (!in.read(value.data() + 8, std::streamsize(w * h * 4))) {
                    return "attribute \"" + name + "\" is truncated";
                }
                pos += w * h * 4;
                part.attributes.push_back({name, type, std::move(value)});
            } else if (fixed >= 0) {
                unsigned char v[128] = {};
                if (std::uint64_t(fixed) > file_size - pos ||
                    !in.read(reinterpret_cast<char *>(v), fixed)) {
                    return "attribute \"" + name + "\" is truncated";
                }
                pos += std::uint64_t(fixed);
                if (name == "dataWindow" && type == "box2i") {
                    part.x_min = le32(&v[0]);
                    part.y_min = le32(&v[4]);
                    part.x_max = le32(&v[8]);
                    part.y_max = le32(&v[12]);
                } else if (name == "compression" && type == "compression") {
                    part.compression = v[0];
                } else if (name == "tiles" && type == "tiledesc") {
                    part.tile_width = le32(&v[0]);
                    part.tile_height = le32(&v[4]);
                } else if (name == "lineOrder" && type == "lineOrder") {
                    part.line_order = v[0];
                }
                part.attributes.push_back({name, type, std::vector<char>(v, v + fixed)});
            } else {
                std::vector<char> value(static_cast<std::size_t>(size));
                if (!in.read(value.data(), size)) {
                    return "attribute \"" + name + "\" is truncated";
                }
                pos += std::uint64_t(size);
                part.attributes.push_back({name, type, std::move(value)});
            }
        }
        if (attributes > 0) {
            found.push_back(part);
        }
        // A single-part file has one header; in a multi-part file an empty header ends the list.
        if (!multipart || (attributes == 0 && header > 0)) {
            break;
        }
    }
    // The chunk offset tables follow the headers, 8 bytes a chunk: a window whose table cannot
    // fit in the file is damaged (and OpenEXR would allocate the table before finding out).
    std::uint64_t offsets = 0;
    for (const ExrPartLayout &p : found) {
        offsets += std::uint64_t(exr_chunk_count(p)) * 8;
    }
    if (offsets > file_size - pos) {
        return "its data window" + std::string(found.size() > 1 ? "s need " : " needs ") +
               std::to_string(offsets / 8) + " chunk offsets (" + std::to_string(offsets) +
               " bytes), more than the " + std::to_string(file_size - pos) +
               " bytes after the header";
    }
    if (parts) {
        *parts = std::move(found);
    }
    return {};
}

namespace {

/// Scan lines per chunk of a compression: none, rle, zips 1; zip, pxr24 16; piz, b44(a), dwaa 32;
/// dwab 256 (and 256 for anything newer).
int lines_per_chunk(int compression)
{
    static constexpr int kLines[] = {1, 1, 1, 16, 32, 16, 32, 32, 32, 256};
    return compression >= 0 && compression < 10 ? kLines[compression] : 256;
}

}  // namespace

std::int64_t exr_chunk_count(const ExrPartLayout &part)
{
    const std::int64_t width = std::int64_t(part.x_max) - part.x_min + 1;
    const std::int64_t height = std::int64_t(part.y_max) - part.y_min + 1;
    if (width <= 0 || height <= 0) {
        return 0;
    }
    if (part.tile_width > 0 && part.tile_height > 0) {
        // Level 0 only: mip levels add more, so this is a lower bound.
        return ((width + part.tile_width - 1) / part.tile_width) *
               ((height + part.tile_height - 1) / part.tile_height);
    }
    const int lines = lines_per_chunk(part.compression);
    return (height + lines - 1) / lines;
}

std::size_t exr_open_bytes(const ExrPartLayout &part)
{
    const std::int64_t width = std::int64_t(part.x_max) - part.x_min + 1;
    if (part.bytes_per_pixel <= 0 || width <= 0) {
        return 0;
    }
    const std::int64_t block_pixels = part.tile_width > 0 && part.tile_height > 0
                                          ? std::int64_t(part.tile_width) * part.tile_height
                                          : width * lines_per_chunk(part.compression);
    // A block's pixels, once raw and once in the compressor's buffer, for each of the block
    // buffers OpenEXR keeps (at least two), plus the table of chunk offsets (deep parts keep
    // more per chunk): a low estimate on purpose.
    return std::size_t(block_pixels) * std::size_t(part.bytes_per_pixel) * 4 +
           std::size_t(exr_chunk_count(part)) * 16;
}

std::vector<ExrPartLayout> check_exr_header(const std::string &path)
{
    std::error_code ec;
    const std::uint64_t size = fs::file_size(path, ec);
    std::ifstream f(path, std::ios::binary);
    if (ec || !f) {
        throw_runtime(path, ": cannot open file");
    }
    // Bytes 0-3 are the magic number, checked by the caller.
    f.seekg(4);
    std::vector<ExrPartLayout> parts;
    const std::string problem = exr_header_problem(f, size, &parts);
    if (!problem.empty()) {
        throw_runtime(path, ": cannot read image: damaged OpenEXR header: ", problem);
    }
    // OpenEXR allocates its block buffers when the file is opened, before any window check of
    // ours: a header claiming a 2-billion-pixel-wide part must not get that far. These buffers
    // live only while the file is read, so up to 16 MiB always opens; past that, what the
    // budget has left decides.
    const std::size_t budget = image_memory_budget();
    const std::size_t in_use = image_memory_in_use();
    const std::size_t allowed =
        std::max(std::size_t(16) << 20, budget > in_use ? budget - in_use : std::size_t(0));
    for (std::size_t i = 0; i < parts.size(); ++i) {
        const std::size_t need = exr_open_bytes(parts[i]);
        if (budget != 0 && need > allowed) {
            throw_runtime(path,
                          ": part ",
                          i,
                          ": opening it would take ",
                          format_bytes(need),
                          " of line or tile buffers and offset tables (data window ",
                          std::int64_t(parts[i].x_max) - parts[i].x_min + 1,
                          "x",
                          std::int64_t(parts[i].y_max) - parts[i].y_min + 1,
                          "), over --max-memory ",
                          format_bytes(budget));
        }
    }
    return parts;
}

int exr_compression_id(std::string_view name)
{
    // OpenEXR's compressions in the order of their ids; "deflate" is OpenImageIO's name for zip.
    static constexpr std::string_view kCodecs[] = {
        "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab"};
    const std::string_view base = name.substr(0, name.find(':'));
    if (OIIO::Strutil::iequals(base, "deflate")) {
        return 3;
    }
    for (int id = 0; id < int(std::size(kCodecs)); ++id) {
        if (OIIO::Strutil::iequals(base, kCodecs[id])) {
            return id;
        }
    }
    return -1;
}

int band_rows(const OIIO::ImageSpec &spec, std::size_t row_bytes)
{
    // Scan lines per block of the part's codec (1 for formats other than EXR).
    const int id = exr_compression_id(spec.get_string_attribute("compression"));
    int block = id >= 0 ? lines_per_chunk(id) : 1;
    if (spec.tile_width > 0) {
        block = std::max(1, spec.tile_height);  // a row of tiles: many blocks side by side
    }
    const int step = std::lcm(32, block);
    const std::size_t step_bytes = std::max<std::size_t>(row_bytes * std::size_t(step), 1);
    // About 4 MiB, and at least 8 blocks for OpenEXR's threads to share (a band of 3 blocks on
    // 2 threads leaves one idle a third of the time), but at most 32 MiB.
    std::size_t steps = std::max<std::size_t>((std::size_t(4) << 20) / step_bytes, 1);
    if (spec.tile_width <= 0) {
        steps = std::max<std::size_t>(steps, std::size_t((8 * block + step - 1) / step));
    }
    steps = std::clamp<std::size_t>(
        steps, 1, std::max<std::size_t>((std::size_t(32) << 20) / step_bytes, 1));
    return step * int(std::min<std::size_t>(steps, 64));
}

std::unique_ptr<OIIO::ImageInput> open_input(const std::string &path,
                                             std::vector<ExrPartLayout> *layouts)
{
    std::error_code ec;
    if (!fs::exists(path, ec)) {
        throw_runtime(path, ": no such file");
    }
    if (fs::is_directory(path, ec)) {
        throw_runtime(path, ": is a directory, not an image");
    }
    if (!fs::is_regular_file(path, ec)) {
        // A FIFO or a device would block the read, or never end.
        throw_runtime(path, ": not a regular file (a pipe, socket or device), not an image");
    }
    if (fs::file_size(path, ec) == 0) {
        throw_runtime(path, ": empty file");
    }
    // A file that starts with OpenEXR's magic number is opened by the EXR reader alone: a
    // damaged one gets the EXR reader's error instead of every other format being tried (one of
    // them, LibRaw, clears megabytes per attempt).
    unsigned char magic[4] = {};
    {
        std::ifstream f(path, std::ios::binary);
        f.read(reinterpret_cast<char *>(magic), 4);
    }
    if (magic[0] == 0x76 && magic[1] == 0x2f && magic[2] == 0x31 && magic[3] == 0x01) {
        std::vector<ExrPartLayout> walked = check_exr_header(path);
        if (layouts) {
            *layouts = std::move(walked);
        }
        auto exr = OIIO::ImageInput::create("openexr");
        OIIO::ImageSpec spec;
        if (exr && exr->open(path, spec)) {
            return exr;
        }
        std::string err = exr ? exr->geterror() : OIIO::geterror();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read image: ", err.empty() ? "damaged OpenEXR file" : err);
    }
    auto in = OIIO::ImageInput::open(path);
    if (!in) {
        std::string err = OIIO::geterror();
        std::replace(err.begin(), err.end(), '\n', ' ');
        throw_runtime(path, ": cannot read image: ", err.empty() ? "unknown format" : err);
    }
    return in;
}

OIIO::ParamValueList own_attributes(const OIIO::ImageSpec &spec, const OIIO::ParamValueList &shown)
{
    OIIO::ParamValueList own;
    for (const OIIO::ParamValue &p : spec.extra_attribs) {
        if (!is_frame_attribute(p.name().string())) {
            continue;
        }
        const auto same = std::find_if(shown.begin(), shown.end(), [&](const OIIO::ParamValue &q) {
            return q.name() == p.name() && q.type() == p.type() &&
                   q.get_string(1 << 20) == p.get_string(1 << 20);
        });
        if (same == shown.end()) {
            own.push_back(p);
        }
    }
    return own;
}

}  // namespace posthaste::io_detail
