#pragma once
// Internal to src/io: header attribute tables, the camera's attributes, and pixel conversions
// between a file's native types and float passes, shared by the reader and the writer.

#include <OpenEXR/ImfPixelType.h>
#include <OpenImageIO/imageio.h>

#include <cstddef>
#include <cstdint>
#include <istream>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "core/camera.h"
#include "io/source_file.h"

namespace posthaste::io_detail {

/// Attributes that describe the file's structure rather than the picture: not carried over.
bool is_structural_attribute(const std::string &name);
/// The camera's header attributes (read into Camera, written from it).
bool is_camera_attribute(const std::string &name);
/// An attribute a read puts into Frame::attributes (neither structural nor the camera's).
inline bool is_frame_attribute(const std::string &name)
{
    return !is_structural_attribute(name) && !is_camera_attribute(name) && name != "multiView";
}
/// The frame attributes of a part's header (`spec`) that `shown` (the frame's, from another
/// part) lacks or gives another value: what `info` lists under that part.
OIIO::ParamValueList own_attributes(const OIIO::ImageSpec &spec, const OIIO::ParamValueList &shown);
/// "half", "float", "uint", or OIIO's name for other types.
std::string type_name(OIIO::TypeDesc t);
/// 8/16-bit integer types (normalised on read).
bool is_integer_type(OIIO::TypeDesc t);
/// Parse the camera attributes of `spec` into `cam` (absent ones stay unset).
void read_camera(const OIIO::ImageSpec &spec, Camera &cam);
/// Write every set camera value into `spec`; with `only_changed`, a value that `before` already
/// has bit for bit is left as the spec has it (its attribute type and bits kept).
void write_camera(const Camera &cam, OIIO::ImageSpec &spec, const Camera *before = nullptr);
/// Open an image for reading; throws Error (exit 1) naming the file.
/// Walk an OpenEXR header (the stream is just past the magic number) without allocating what it
/// claims: "" if every attribute's size fits in the file, else what is wrong. OpenEXR 3.1
/// allocates an attribute's claimed size before reading it, so a 100-byte file could ask for
/// 2 GB.
struct ExrPartLayout {
    int x_min = 0, y_min = 0;    ///< data window, inclusive as in the file; OpenEXR's default
    int x_max = 63, y_max = 63;  ///< (0,0)-(63,63) when the header has none
    int bytes_per_pixel = 0;     ///< all channels
    int compression = 0;         ///< OpenEXR's compression id
    int tile_width = 0;          ///< 0: scan lines
    int tile_height = 0;
    int line_order = 0;  ///< OpenEXR's: 0 increasing y, 1 decreasing y, 2 random y
    std::vector<HeaderAttribute> attributes;  ///< every attribute but the channel list
};
std::string exr_header_problem(std::istream &in,
                               std::uint64_t file_size,
                               std::vector<ExrPartLayout> *parts = nullptr);
/// Chunks (scan-line blocks or level-0 tiles) of a part: its offset table has that many entries.
std::int64_t exr_chunk_count(const ExrPartLayout &part);
/// What OpenEXR allocates for a part's block buffers when it opens the file (a low estimate).
std::size_t exr_open_bytes(const ExrPartLayout &part);

/// Throws a one-line error naming the file when exr_header_problem finds something; else the
/// parts' layouts as the walk read them (also what OpenImageIO does not report: the line order).
std::vector<ExrPartLayout> check_exr_header(const std::string &path);
/// OpenEXR's id of a compression named as OpenImageIO names it ("zip", "dwaa:45", "deflate"),
/// or -1.
int exr_compression_id(std::string_view name);

/// An EXR's header is walked first (check_exr_header); its layouts go to `layouts` if given
/// (empty for other formats).
std::unique_ptr<OIIO::ImageInput> open_input(const std::string &path,
                                             std::vector<ExrPartLayout> *layouts = nullptr);
/// Convert `count` pixels of `channels` floats (pixel i at src + i * src_stride; 0: channels)
/// to halves at dst + i * dst_stride. Rounds to nearest even (F16C where the CPU has it).
/// Returns how many finite values became infinite (65520 and beyond in magnitude).
std::size_t floats_to_halves(const float *src,
                             int channels,
                             int count,
                             unsigned char *dst,
                             std::size_t dst_stride,
                             int src_stride = 0);
/// Copy `count` pixels of `channels` floats (pixel i at src + i * src_stride; 0: channels) to
/// dst + i * dst_stride.
void scatter_floats(const float *src,
                    int channels,
                    int count,
                    unsigned char *dst,
                    std::size_t dst_stride,
                    int src_stride = 0);
/// Convert `count` values of one native channel to float, `src` stepping `stride` bytes.
void convert_channel(const unsigned char *src,
                     std::size_t stride,
                     OIIO::TypeDesc type,
                     float *dst,
                     std::size_t dst_stride,
                     int count);
/// Rows of a part read or written at once: whole blocks of its codec and whole rows of its
/// tiles (a multiple of 32 rows), about 4 MiB and at least 8 blocks, for OpenEXR's threads to
/// work on side by side, at most 32 MiB: small enough to stay in cache between the library's
/// copy and posthaste's conversion, and never the whole frame a second time.
int band_rows(const OIIO::ImageSpec &spec, std::size_t row_bytes);
/// OpenEXR's pixel type for a channel's type: uint, float (also for double) or half.
Imf::PixelType exr_pixel_type(OIIO::TypeDesc t);
/// Pixel types the reader converts.
bool supported_native(OIIO::TypeDesc t);

}  // namespace posthaste::io_detail
