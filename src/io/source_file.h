#pragma once
// SourceFile: what a frame keeps of the EXR file it was read from, so that a write puts every
// channel no node changed back as it was: the parts in order with their headers (names, views,
// windows, tiling, attributes, channel names and pixel types), the view the canonical passes came
// from, the native samples that a float pass cannot hold exactly, and the lower mip levels.

#include <OpenImageIO/imageio.h>

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/camera.h"
#include "core/image.h"

namespace posthaste {

/// One mip level of a part as read, at native pixel types (every channel of the part).
struct SourceLevel {
    OIIO::ImageSpec spec;
    std::shared_ptr<const std::vector<unsigned char>> pixels;
    int lx = 0, ly = 0;  ///< OpenEXR's level indices (lx == ly in a MIP map)
};

/// One attribute of a part's OpenEXR header as the file holds it: its name, its OpenEXR type
/// name and its value's bytes. OpenImageIO reads some types into others (a chromaticities under
/// another name and a floatvector of 2, 3 or 16 floats come back as plain float arrays) and
/// some not at all (opaque types, previews, compression- or envmap-typed attributes under other
/// names); the writer puts these back as they were (exr_header.cpp).
struct HeaderAttribute {
    std::string name;
    std::string type;
    std::vector<char> value;
};

struct SourcePart {
    /// The part's header as OpenImageIO read it (windows, channels, formats, tiles, attributes).
    OIIO::ImageSpec spec;
    std::string name;  ///< Part name ("" for a single-part file without one).
    std::string view;  ///< The part's view ("" when it has none).
    /// Per channel: its view (single-part multi-view files name other views' channels
    /// "layer.view.channel"; multi-part files give the view per part).
    std::vector<std::string> channel_views;
    int mip_levels = 1;
    /// A ripmap: its levels halve the width and the height independently.
    bool ripmap = false;
    /// The levels other than level 0, as read (only for tiled mip- or rip-mapped parts that
    /// were read whole): a MIP map's 1.., a ripmap's every (lx, ly) but (0, 0), ly major.
    std::vector<SourceLevel> levels;
    /// The part's OpenEXR attributes as the file holds them (all but the channel list).
    std::vector<HeaderAttribute> attributes;
    Rect data_window() const { return {spec.x, spec.y, spec.x + spec.width, spec.y + spec.height}; }
};

struct SourceFile {
    std::string path;
    std::vector<SourcePart> parts;
    /// The file's views, in order ("multiView" first); empty when it has none.
    std::vector<std::string> views;
    /// The view the canonical passes came from ("" for a file without views).
    std::string view;
    /// One part whose channels carry the view in their names (OpenEXR's single-part multi-view).
    bool single_part_views = false;
    /// The camera as the header had it (a write touches the camera attributes only if it changed).
    Camera camera;
    /// Native samples of channels whose float pass cannot reproduce the file's bits (32-bit uint
    /// ids beyond 2^24; channels an alias rule scaled, offset, clipped or decoded), keyed by
    /// (part, channel), over the part's data window, row-major.
    std::map<std::pair<int, int>, std::shared_ptr<const std::vector<unsigned char>>> raw;
};

/// The same file moved by (dx, dy) pixels (crop's `reformat`): every part's and level's windows
/// shifted, the samples shared. A write of the moved frame then puts each channel back at its
/// pixels' new place.
inline std::shared_ptr<const SourceFile> moved_source(const SourceFile &src, int dx, int dy)
{
    auto out = std::make_shared<SourceFile>(src);
    const auto move = [dx, dy](OIIO::ImageSpec &spec) {
        spec.x += dx;
        spec.y += dy;
        spec.full_x += dx;
        spec.full_y += dy;
    };
    for (SourcePart &part : out->parts) {
        move(part.spec);
        for (SourceLevel &level : part.levels) {
            move(level.spec);
        }
    }
    return out;
}

/// The same file on a new pixel grid (transform, reformat): every part takes the frame's new
/// data window, which every pass now covers; its samples as read (raw channels, lower mip levels)
/// no longer lie on the grid and are dropped, so a write makes them from the passes.
inline std::shared_ptr<const SourceFile> regridded_source(const SourceFile &src, const Rect &window)
{
    auto out = std::make_shared<SourceFile>(src);
    for (SourcePart &part : out->parts) {
        part.spec.x = window.x0;
        part.spec.y = window.y0;
        part.spec.width = window.width();
        part.spec.height = window.height();
        part.levels.clear();
    }
    out->raw.clear();
    return out;
}

}  // namespace posthaste
