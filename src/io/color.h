#pragma once
// OpenColorIO 2.1: the active config ($OCIO, else the config shipped in samples/ocio/, built in)
// and processors applied to RGBA images in place.

#include <array>
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

/// CIE 1931 xy of the light at `kelvin` (1667-25000) on the Planckian locus (Kim et al. 2002's
/// cubic fit), moved `tint` thousandths of a CIE 1960 uv unit (Duv x 1000) off the locus,
/// positive toward green.
void planckian_xy(double kelvin, double tint, double &x, double &y);

/// A row-major 3x3 matrix on linear Rec.709 that adapts colors seen under the light
/// (kelvin, tint) to how they would look under (target_kelvin, target_tint): Bradford chromatic
/// adaptation between the two whites. Identity when the two lights are the same.
std::array<double, 9> white_balance_matrix(double kelvin,
                                           double tint,
                                           double target_kelvin,
                                           double target_tint);

/// A CPU color processor over the RGB channels of an image (alpha untouched). Immutable and
/// thread-safe once made.
class ColorProcessor {
   public:
    /// From one color space to another. Throws a usage Error naming `where` and listing the
    /// config's spaces when a name is unknown.
    /// `from_param`, `to_param`: the node parameters that named them, for the messages.
    static ColorProcessor between(const std::string &from,
                                  const std::string &to,
                                  const std::string &where,
                                  const std::string &from_param = "",
                                  const std::string &to_param = "");
    /// From a color space to a display and view.
    /// `for_8bit`: the result feeds 8-bit output, so OpenColorIO may approximate (look-up
    /// tables; within one 8-bit code).
    static ColorProcessor display_view(const std::string &from,
                                       const std::string &display,
                                       const std::string &view,
                                       const std::string &where,
                                       bool for_8bit = false,
                                       const std::string &from_param = "");

    /// A grade as one OpenColorIO group, in this order: `matrix` (white balance and exposure,
    /// row-major 3x3 on linear RGB), the ASC CDL (slope, offset, power, saturation; OCIO's
    /// CDLTransform, no clamping), then x * (gain - lift) + lift per channel, then x^(1/gamma)
    /// with negatives passed through, then a LUT file through OCIO's FileTransform ("" for
    /// none). Throws a usage Error naming `where` for a LUT OpenColorIO cannot read.
    struct Grade {
        double matrix[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
        double slope[3] = {1, 1, 1}, offset[3] = {0, 0, 0}, power[3] = {1, 1, 1};
        double saturation = 1.0;
        double lift[3] = {0, 0, 0}, gamma[3] = {1, 1, 1}, gain[3] = {1, 1, 1};
        std::string lut;
        std::string interpolation = "best";  ///< nearest, linear, tetrahedral, best
    };
    static ColorProcessor grade(const Grade &grade, const std::string &where);

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
