#pragma once
// Reading and writing frames: multi-layer / multi-part OpenEXR (and PNG/TIFF/JPEG through
// OpenImageIO for color-only inputs), with channel aliases, camera attributes and atomic writes.

#include <functional>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/frame.h"
#include "io/aliases.h"

namespace posthaste {

struct FileChannel {
    std::string name;  ///< Full name as stored ("ViewLayer.Depth.Z"), part-prefixed if needed.
    std::string type;  ///< "half", "float", "uint", "uint8", ...
};

struct FilePart {
    std::string name;
    std::vector<FileChannel> channels;
    Rect data_window;     ///< In pixel coordinates of the display window's origin.
    Rect display_window;  ///< Absolute, as in the file.
    bool tiled = false;
    std::string compression;
};

struct FileInfo {
    std::string path;
    std::string format;  ///< OIIO format name: "openexr", "png", ...
    std::vector<FilePart> parts;
    int width = 0, height = 0;  ///< Display window size.
    Camera camera;
    OIIO::ParamValueList attributes;  ///< Part 0's attributes, camera and structural ones removed.
    std::vector<PassSource> passes;   ///< How the file's channels map onto passes.
};

/// What to do with NaN and infinite values when reading (depth's +inf is always kept).
enum class BadPixels { Keep, Zero, Error };

struct ReadOptions {
    std::vector<AliasRule> aliases;  ///< Graph rules, tried before the built-in ones.
    BadPixels bad_pixels = BadPixels::Keep;
    bool linearize = true;  ///< sRGB-encoded integer files (PNG, JPEG) are decoded to linear.
};

/// Open a file's header and map its channels. Throws Error (exit 1) naming the file on a
/// missing, truncated or unreadable file.
FileInfo read_file_info(const std::string &path, const ReadOptions &options = {});

/// Read the passes `wanted` (nullptr: every pass) into a Frame. Throws Error naming the file and
/// the missing pass (with the passes the file has) if one is absent.
Frame read_frame(const std::string &path,
                 const std::set<std::string> *wanted,
                 int frame_number,
                 const ReadOptions &options = {});

struct WriteOptions {
    std::string compression = "piz";
    bool multipart = false;           ///< One part per pass instead of one part with every channel.
    std::vector<std::string> passes;  ///< Empty: every pass of the frame.
    std::map<std::string, PixelStorage> storage;  ///< Per pass; default half for color/albedo.
    bool allow_lossy_data = false;                ///< Permit DWAA/DWAB/PXR24 on data passes.
};

/// Validate an EXR compression name ("dwaa:45" allowed); throws a usage Error naming `where`.
void check_compression(const std::string &compression, const std::string &where);

/// Write an EXR atomically (temporary file, then rename). Camera and header attributes kept.
void write_exr(const Frame &frame, const std::string &path, const WriteOptions &options);

/// Write an 8-bit display-referred preview (PNG, JPEG, TIFF...) of an RGB(A) image whose values
/// are already display-encoded in [0,1]; atomic.
void write_preview(const Image &display_rgba, const std::string &path, bool with_alpha);

/// Run `write(temporary_path)` and rename the result onto `path`; the temporary is removed if
/// `write` throws. The directory of `path` is created if missing.
void atomic_write(const std::string &path, const std::function<void(const std::string &)> &write);

/// True if `path` has an EXR extension.
bool is_exr_path(const std::string &path);

}  // namespace posthaste
