#pragma once
// Reading and writing frames: multi-layer / multi-part / multi-view OpenEXR (scanline, tiled,
// mip-mapped, deep, luminance/chroma) and PNG/TIFF/JPEG through OpenImageIO for color-only inputs,
// with channel aliases, camera attributes, data and display windows, and atomic writes. A frame
// read from an EXR remembers the file's layout (io/source_file.h), so a write puts back every
// channel no node changed exactly as it was.

#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/frame.h"
#include "io/aliases.h"
#include "io/png_write.h"

namespace posthaste {

struct FileChannel {
    std::string name;  ///< As stored in its part ("ViewLayer.Depth.Z", "right.R", "Z").
    std::string type;  ///< "half", "float", "uint", "uint8", ...
    std::string view;  ///< Its view ("" when the file has none).
    int xsampling = 1, ysampling = 1;
};

struct FilePart {
    std::string name;
    std::string view;  ///< The part's view attribute ("" when none).
    std::vector<FileChannel> channels;
    Rect data_window;     ///< Absolute, as in the file.
    Rect display_window;  ///< Absolute, as in the file.
    bool tiled = false;
    int tile_width = 0, tile_height = 0;
    int mip_levels = 1;
    std::string level_mode;                ///< "", "mipmap" or "ripmap".
    std::pair<int, int> rip_levels{1, 1};  ///< A ripmap's levels along x and y.
    std::string compression;
    std::string envmap;  ///< "latlong", "cube" or "".
    bool deep = false;
    std::int64_t deep_samples = -1;  ///< Deep parts: samples in the part (read by info).
    int deep_max_samples = -1;       ///< Deep parts: most samples in one pixel.
    /// Frame attributes of this part's header that FileInfo::attributes (another part's) lacks
    /// or gives otherwise; empty for the part those come from.
    OIIO::ParamValueList own_attributes;
};

struct FileInfo {
    std::string path;
    std::string format;  ///< OIIO format name: "openexr", "png", ...
    /// "" when read as stored; "luminance/chroma" (converted to RGB by OpenEXR's RGBA
    /// interface) or "deep, flattened" when the frame is a conversion of the file.
    std::string conversion;
    std::vector<FilePart> parts;
    Rect display_window;  ///< Absolute; every part has it.
    Rect data_window;     ///< The union of the parts' data windows: the frame's data window.
    std::vector<std::string> views;  ///< multiView (or the parts' views), in order.
    std::string view;                ///< The view the canonical passes come from.
    Camera camera;
    OIIO::ParamValueList attributes;  ///< That view's first part's attributes, camera removed.
    /// Those attributes with the cryptomatte declarations only the other parts' headers hold.
    OIIO::ParamValueList cryptomattes;
    /// How the file's channels map onto passes: the chosen view's passes under their own names,
    /// other views' as "pass@view".
    std::vector<PassSource> passes;
    /// Canonical passes whose channels a renderer wrote in a form that needs a render setting
    /// to convert (docs/CONVENTIONS.md): absent, with what to set.
    std::vector<RefusedPass> refused;
    /// "; " and the refusal's message when `pass` is refused, else "".
    std::string refusal_hint(const std::string &pass) const
    {
        for (const RefusedPass &r : refused) {
            if (r.pass == pass) {
                return "; " + r.message;
            }
        }
        return {};
    }
    int width() const { return display_window.width(); }
    int height() const { return display_window.height(); }
};

/// What to do with NaN and infinite values when reading (depth's +inf is always kept).
enum class BadPixels { Keep, Zero, Error };
/// Deep files: composite each pixel's samples front to back, or refuse them.
enum class DeepMode { Flatten, Error };

struct ReadOptions {
    std::vector<AliasRule> aliases;  ///< Graph rules, tried before the built-in ones.
    BadPixels bad_pixels = BadPixels::Keep;
    bool linearize = true;  ///< sRGB-encoded integer files (PNG, JPEG) are decoded to linear.
    std::string view;       ///< "" = the file's default view.
    DeepMode deep = DeepMode::Flatten;
    /// "" or "auto": every renderer's pass names; else one of known_conventions() (plus the
    /// canonical names).
    std::string convention = "auto";
    bool count_deep_samples = false;  ///< read_file_info: fill FilePart::deep_samples.
};

/// Read every pixel of every part and level of an image file (deep samples too), like OpenEXR's
/// exrcheck. Returns "" for a whole file, else one line saying what is wrong (never throws).
std::string verify_image_file(const std::string &path);

/// Largest data window area accepted from a file (pixels), beside kMaxImageSide per side.
inline constexpr std::int64_t kMaxFilePixels = std::int64_t(1) << 28;

/// Open a file's header and map its channels. Throws Error (exit 1) naming the file on a
/// missing, truncated or unreadable file, an absurd window, an unknown view, or a deep file
/// with DeepMode::Error.
FileInfo read_file_info(const std::string &path, const ReadOptions &options = {});

/// Read the passes `wanted` (nullptr: every pass) into a Frame whose windows are the file's
/// display window and the union of the read parts' data windows. Throws Error naming the file
/// and the missing pass (with the passes the file has) if one is absent.
/// With `non_finite`, also counts per pass the NaN and infinite values read (depth's +inf, the
/// sky, does not count) that BadPixels::Keep let through. The passes of `optional` are read
/// too where the file has them (with `wanted` only; no error for one it lacks).
Frame read_frame(const std::string &path,
                 const std::set<std::string> *wanted,
                 int frame_number,
                 const ReadOptions &options = {},
                 std::map<std::string, std::size_t> *non_finite = nullptr,
                 const std::set<std::string> *optional = nullptr);

/// How write_exr lays the file out.
enum class ExrLayout {
    Auto,       ///< The source file's layout when the frame has one, else Single.
    Single,     ///< One part with every channel, canonical channel names.
    Multipart,  ///< One part per pass, canonical channel names.
};

struct WriteOptions {
    /// "auto": the source part's compression when it is lossless (zip for a lossy one, so
    /// nothing degrades twice), piz for frames not read from an EXR.
    std::string compression = "auto";
    ExrLayout layout = ExrLayout::Auto;
    bool multipart = false;                       ///< Deprecated spelling of layout = Multipart.
    std::vector<std::string> passes;              ///< Empty: every pass of the frame.
    std::map<std::string, PixelStorage> storage;  ///< Per pass; default: the source's, else
                                                  ///< half for color/albedo, float otherwise.
    bool allow_lossy_data = false;                ///< Permit DWAA/DWAB/PXR24 on data passes.
    /// Told when half storage turned finite values (beyond 65504) into infinity, with a line
    /// that names the channels and the way out but neither the file nor the count, so that a
    /// sequence can say it once; null: "warning: FILE: ..." on stderr.
    std::function<void(const std::string &)> warn;
};

/// Validate an EXR compression name ("dwaa:45" allowed, "auto"); throws a usage Error naming
/// `where`.
void check_compression(const std::string &compression, const std::string &where);
/// Whether an EXR compression name ("dwaa:45" allowed) changes values: dwaa, dwab, pxr24, b44,
/// b44a.
bool is_lossy_compression(const std::string &compression);

/// Write an EXR atomically (temporary file, then rename). Camera and header attributes kept;
/// the data and display windows are the frame's.
void write_exr(const Frame &frame, const std::string &path, const WriteOptions &options);

/// Write an 8-bit display-referred preview (PNG, JPEG, TIFF...) of an RGB(A) image whose values
/// are already display-encoded in [0,1]; atomic.
void write_preview(const Image &display_rgba, const std::string &path, bool with_alpha);

class ColorProcessor;

struct PreviewOptions {
    bool alpha = false;  ///< Write alpha as a fourth channel.
    int png_level = 1;   ///< zlib level of a PNG, 0-9.
    /// PNG row filter (the write node's png_filter choice, in the enum's order).
    PngFilter png_filter = PngFilter::none;
    bool dither = true;  ///< 8x8 ordered dither before quantising to 8 bits.
};

/// Write an 8-bit display-referred preview of a linear, premultiplied RGB(A) pass `color`
/// (covering the absolute rectangle `data`) over the display window `display` (transparent
/// black outside the data): each row is placed, transformed by `to_display` (unpremultiplied
/// around the transform) and quantised, rows in parallel, with no full-size float copy; atomic.
/// The dither is a fixed 8x8 Bayer pattern in display-window coordinates: deterministic, and it
/// breaks the bands that 8 bits leave in fog and sky gradients.
void write_display_preview(const Image &color,
                           const Rect &data,
                           const Rect &display,
                           const ColorProcessor &to_display,
                           const std::string &path,
                           const PreviewOptions &options);

/// Run `write(temporary_path)` and rename the result onto `path`; the temporary is removed if
/// `write` throws. The directory of `path` is created if missing.
void atomic_write(const std::string &path, const std::function<void(const std::string &)> &write);

/// Write `size` bytes to `path` atomically (atomic_write); a one-line error naming the path (and
/// the free space when the disk is full) otherwise.
void write_file_bytes(const std::string &path, const void *data, std::size_t size);

/// Write `text` to `path` atomically (atomic_write); a one-line error naming the path (and the
/// free space when the disk is full) otherwise.
void write_text_file(const std::string &path, const std::string &text);

/// True if `path` has an EXR extension.
bool is_exr_path(const std::string &path);

}  // namespace posthaste
