#pragma once
// Geometric operations on a whole frame (reformat, transform, crop): every pass moved the same
// way, the windows and the camera updated so that projecting a world point through the header
// still lands on the pixel that shows it, and motion vectors (pixels) mapped by the same linear
// part. See docs/GRAPHS.md for the nodes built on them.

#include <string>
#include <vector>

#include "core/frame.h"
#include "filter/image_ops.h"

namespace posthaste::filter {

/// The camera of a frame whose pixels moved by `to_output` (input -> output file coordinates)
/// and whose display window went from `display` to `new_display`: the NDC change folded into
/// worldToNDC (and the previous frame's), the sensor size divided by the map's scale along each
/// axis. The same camera when the NDC map is the identity (a reformat of the whole format).
Camera moved_camera(const Camera &camera,
                    const Affine &to_output,
                    const Rect &display,
                    const Rect &new_display);

struct FrameWarp {
    Affine to_output{1.0};  ///< input -> output file coordinates
    Rect window;            ///< the output data window
    Rect display;           ///< the output display window
    /// How the filtered passes are resampled: ImageBufAlgo::resize (the map takes the display
    /// window onto the new one; minification prefilters) or ImageBufAlgo::warp.
    bool resize = false;
    /// "bicubic" (Catmull-Rom) or "bilinear": the lens node's Highway kernels, point samples
    /// without prefiltering; another name: that OpenImageIO filter; "nearest": none.
    std::string filter;
    std::vector<std::string> filtered;  ///< passes resampled with `filter` (before any "@view")
};

/// `in` with every pass resampled through `w` into `out` (whose passes are replaced; their file
/// origins kept, so a write puts them back into the channels they came from). Filtered passes
/// go through OpenImageIO; the others (depth, ids, normals, motion...) take the nearest input
/// pixel, values unchanged except motion, whose vectors are mapped by the linear part of the
/// map. Outside the input: 0, depth +inf. Non-finite input values read as 0 (depth: NaN and -inf
/// as +inf), as every node that moves pixels.
void warp_frame(const Frame &in, const FrameWarp &w, Frame &out);

/// `out`'s passes replaced by `in`'s cut (or padded: 0, depth +inf) to `window`, and its data
/// window set to it moved by (dx, dy); the channels' file origins kept, the camera and display
/// window left as they are. Used by crop, and by write's crop to the display window.
void cut_data_window(const Frame &in, const Rect &window, Frame &out, int dx = 0, int dy = 0);

}  // namespace posthaste::filter
