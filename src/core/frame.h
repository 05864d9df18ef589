#pragma once
// Frame: the named passes of one frame plus its metadata (frame number, windows, Camera, and every
// other header attribute, carried through untouched). Passes are shared, immutable Images: a node
// that leaves a pass alone passes the same pointer on.
//
// Windows (as OpenEXR's and Nuke's bbox): the display window is the delivered format, the data
// window is where pixels exist; both are in the file's integer coordinates, negative origins
// allowed, and the data window may lie inside, outside or across the display window. Every pass
// image covers the data window exactly: pixel (0, 0) of a pass is the data window's (x0, y0).

#include <OpenImageIO/paramlist.h>

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "core/camera.h"
#include "core/image.h"

namespace posthaste {

/// How a pass is stored when written to EXR.
enum class PixelStorage { Auto, Half, Float };

/// Where one channel of a pass came from in its source file: value = scale * file + offset.
/// part -1: a constant (offset), such as the alpha of a file without one; kRenamedPart: from the
/// file, but its pass was renamed, so a write puts it out fresh under the new name.
constexpr int kRenamedPart = -2;
struct ChannelOrigin {
    int part = -1;
    int channel = -1;
    float scale = 1.0f;
    float offset = 0.0f;
};

/// The layout of the file a frame was read from (parts, their headers and windows, views, raw
/// samples that a float pass cannot hold exactly). Defined in io/source_file.h; the core only
/// carries it so that a write can put untouched channels back as they were.
struct SourceFile;

struct Pass {
    ImagePtr image;
    /// Channel suffixes within the pass ("R", "X", "roughness"); size == image->channels().
    std::vector<std::string> channels;
    PixelStorage storage = PixelStorage::Auto;
    /// Per channel, where it came from in the frame's source file; empty for a pass no file gave.
    std::vector<ChannelOrigin> origin;
    /// The image as the reader made it: the pass is untouched while `image` is still that one.
    std::weak_ptr<const Image> as_read;

    /// True when the pass came from the source file and no node replaced its pixels.
    bool untouched() const
    {
        return !origin.empty() && image && !as_read.owner_before(image) &&
               !image.owner_before(as_read);
    }
};

/// The channel names a pass of `count` channels gets when none are given: a canonical pass's
/// own (their first `count`; a colour of one or two channels is "Y" and "A"), else "Y" for one
/// channel and "R", "G", "B" ("A") for three and four, else "0", "1", ...
std::vector<std::string> default_channel_names(const std::string &name, int count);

class Frame {
   public:
    int number = 0;
    /// The delivered format, absolute file coordinates (OpenEXR displayWindow, exclusive max).
    Rect display_window;
    /// Where pixels exist, absolute file coordinates; every pass is this size.
    Rect data_window;
    /// The camera of the display window (NDC [0,1]^2 spans it, as stored in the file).
    Camera camera;
    /// The other views' cameras, by view (a multi-part stereo file's: each view's first part's
    /// header). Nodes that move pixels move them as `camera`; a write gives each view's parts
    /// its own.
    std::map<std::string, Camera> view_cameras;
    /// Header attributes other than the camera ones, carried through to outputs.
    OIIO::ParamValueList attributes;
    /// The file the passes came from, or null (rendered or computed frames).
    std::shared_ptr<const SourceFile> source;

    /// Size of every pass (the data window's).
    int width() const { return data_window.width(); }
    int height() const { return data_window.height(); }
    /// Display window and data window both (0, 0, w, h): a frame without overscan.
    void set_size(int w, int h) { display_window = data_window = {0, 0, w, h}; }
    /// The camera as the pass images see it: NDC [0,1]^2 spans the data window, and the sensor
    /// spans it too, so code that maps pixels with (x + 0.5) / width() stays right when the data
    /// window differs from the display window. Equal to `camera` when the windows agree.
    Camera pixel_camera() const { return camera.for_window(display_window, data_window); }

    bool has(const std::string &name) const { return passes_.count(name) != 0; }
    /// The pass `name`; throws an Error naming `who` and the missing pass.
    const Pass &pass(const std::string &name, const std::string &who = "frame") const;
    const Image &image(const std::string &name, const std::string &who = "frame") const
    {
        return *pass(name, who).image;
    }
    /// Add or replace a pass. Without `channels` a pass gets default_channel_names. Throws if the
    /// size differs from the data window (the first pass of a frame without windows sets both
    /// windows to its size). Replacing a pass with the same channel count keeps its file origin, so
    /// a write puts the new pixels back where the old ones came from.
    void set(const std::string &name,
             ImagePtr image,
             std::vector<std::string> channels = {},
             PixelStorage storage = PixelStorage::Auto);
    void set(const std::string &name, Image image, std::vector<std::string> channels = {})
    {
        set(name, std::make_shared<const Image>(std::move(image)), std::move(channels));
    }
    /// Add a pass exactly as given (the reader's entry point: origin and as_read set).
    void set_pass(const std::string &name, Pass pass);
    void erase(const std::string &name) { passes_.erase(name); }
    void clear_passes() { passes_.clear(); }
    const std::map<std::string, Pass> &passes() const { return passes_; }
    std::vector<std::string> pass_names() const;

   private:
    void check_size(const std::string &name, const Image &image);
    std::map<std::string, Pass> passes_;
};

}  // namespace posthaste
