#pragma once
// Frame: the named passes of one frame plus its metadata (frame number, Camera, and every other
// header attribute, carried through untouched). Passes are shared, immutable Images: a node that
// leaves a pass alone passes the same pointer on.

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

struct Pass {
    ImagePtr image;
    /// Channel suffixes within the pass ("R", "X", "roughness"); size == image->channels().
    std::vector<std::string> channels;
    PixelStorage storage = PixelStorage::Auto;
};

class Frame {
   public:
    int number = 0;
    int width = 0;  ///< Display window width; every pass has this size.
    int height = 0;
    Camera camera;
    /// Header attributes other than the camera ones, carried through to outputs.
    OIIO::ParamValueList attributes;

    bool has(const std::string &name) const { return passes_.count(name) != 0; }
    /// The pass `name`; throws an Error naming `who` and the missing pass.
    const Pass &pass(const std::string &name, const std::string &who = "frame") const;
    const Image &image(const std::string &name, const std::string &who = "frame") const
    {
        return *pass(name, who).image;
    }
    /// Add or replace a pass. Canonical passes get their canonical channel names when
    /// `channels` is empty; others get "0", "1", ... Throws if the size differs from the frame.
    void set(const std::string &name,
             ImagePtr image,
             std::vector<std::string> channels = {},
             PixelStorage storage = PixelStorage::Auto);
    void set(const std::string &name, Image image, std::vector<std::string> channels = {})
    {
        set(name, std::make_shared<const Image>(std::move(image)), std::move(channels));
    }
    void erase(const std::string &name) { passes_.erase(name); }
    void clear_passes() { passes_.clear(); }
    const std::map<std::string, Pass> &passes() const { return passes_; }
    std::vector<std::string> pass_names() const;

   private:
    std::map<std::string, Pass> passes_;
};

}  // namespace posthaste
