#pragma once
// OpenColorIO 2.1: the active config ($OCIO, else the config shipped in samples/ocio/, built in)
// and processors applied to RGBA images in place.

#include <memory>
#include <string>
#include <vector>

#include "core/image.h"

namespace posthaste {

/// Where the active config came from ("$OCIO=/path" or "built-in samples/ocio/config.ocio").
std::string color_config_source();
/// Color space names of the active config.
std::vector<std::string> color_space_names();
/// Display names and the views of one display.
std::vector<std::string> color_display_names();
std::vector<std::string> color_view_names(const std::string &display);

/// A CPU color processor over the RGB channels of an image (alpha untouched). Immutable and
/// thread-safe once made.
class ColorProcessor {
   public:
    /// From one color space to another. Throws a usage Error naming `where` and listing the
    /// config's spaces when a name is unknown.
    static ColorProcessor between(const std::string &from,
                                  const std::string &to,
                                  const std::string &where);
    /// From a color space to a display and view.
    /// `for_8bit`: the result feeds 8-bit output, so OpenColorIO may approximate (look-up
    /// tables; within one 8-bit code).
    static ColorProcessor display_view(const std::string &from,
                                       const std::string &display,
                                       const std::string &view,
                                       const std::string &where,
                                       bool for_8bit = false);

    /// Apply to the first three channels of every pixel. With `unpremultiply`, color is divided
    /// by alpha (channel 3) where alpha > 0 before, and multiplied after.
    void apply(Image &image, bool unpremultiply) const;
    /// The same on one row of `width` pixels of `nch` interleaved floats.
    void apply_row(float *row, int width, int nch, bool unpremultiply) const;
    /// Apply to one RGB triple (tests, single values).
    void apply_rgb(float rgb[3]) const;
    bool is_noop() const;

   private:
    struct Impl;
    std::shared_ptr<const Impl> impl_;
};

}  // namespace posthaste
