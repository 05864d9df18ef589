#pragma once
// The lighting split's bookkeeping, shared by the dof and motion_blur nodes: a highlight's
// image moves (and focuses) apart from the surface that shows it, so where a pixel's specular
// share parts ways with the rest of its colour it is blurred on its own and added back.
// find_split marks those pixels once and bounds them; share_color lifts the share out of them
// over the crop where its blur runs; the filter then blurs colour less the share in place
// (MotionBlurOptions / DofSettings `subtract`, no copy of the frame), and compose_split adds
// what each blur changed. The node keeps only what is its own: which pixels part ways, and the
// geometry (motion or depth) the share is blurred with.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <vector>

#include "core/image.h"

namespace posthaste::shading {

/// The pixels whose share is lifted out of colour, and where the share's blur runs.
struct SplitRegion {
    int width = 0, height = 0;        ///< The frame's size.
    Rect box;                         ///< Bounds of the lifted pixels (empty: none).
    Rect crop;                        ///< box grown by the reach, clipped to the frame.
    std::vector<std::uint8_t> parts;  ///< Per frame pixel, row-major: 1 where it is lifted.
    bool empty() const { return box.empty(); }
    bool at(int x, int y) const
    {
        return parts[std::size_t(y) * std::size_t(width) + std::size_t(x)] != 0;
    }
};

/// Mark the lifted pixels of a width x height frame, one row at a time (`mark_row(y, row)`
/// writes 0 or 1 for each of the row's pixels: 1 where the share parts ways and rises above the
/// knee), and bound them; the crop is the box grown by `reach` on every side (what a blur spreads
/// from the box and gathers into it), clipped to the frame, its origin moved down to multiples of
/// `align`. Rows run in parallel; the result does not depend on the thread count.
SplitRegion find_split(int width,
                       int height,
                       int reach,
                       const std::function<void(int y, std::uint8_t *row)> &mark_row,
                       int align = 1);

/// Whether a pixel's specular share rises above `knee` in one of its first three channels (NaN
/// does not). Only what lies above the knee parts ways (share_color): below it the share stays
/// in colour and is blurred with the surface, where a smooth, dim reflection blurred along the
/// surface's motion changes little and a highlight a great deal. A node marks a pixel as
/// a pixel lifted only where this holds, so frames without highlights run one filter. Around a
/// lifted pixel, those whose share parts ways below the knee keep their share in colour but
/// lend the share's blur their geometry (specular motion or depth), so that the share's image
/// stays one surface around its highlight.
inline bool above_knee(const float *specular, float knee)
{
    return specular[0] > knee || specular[1] > knee || specular[2] > knee;
}

/// Whether any of `count` values rises above `knee` (NaN does not): a row's quick test before
/// its pixels are looked at one by one (most rows hold no highlight). One pass the compiler
/// vectorises, over every channel of the row.
inline bool any_above(const float *values, std::size_t count, float knee)
{
    int any = 0;
    for (std::size_t i = 0; i < count; ++i) {
        any |= int(values[i] > knee);
    }
    return any != 0;
}

/// find_split's mark for a node: 1 where the pixel's share rises above the knee (above_knee)
/// and `parts(x, y)` says its share parts ways from the rest (the node's geometry test, asked
/// only there); a row with nothing above the knee is cleared at once (any_above).
template <class Parts>
void mark_highlights(
    const Image &specular, float knee, int y, std::uint8_t *row, const Parts &parts)
{
    const int w = specular.width();
    const std::size_t sc = std::size_t(specular.channels());
    const float *sp = specular.pixel(0, y);
    if (!any_above(sp, std::size_t(w) * sc, knee)) {
        std::fill_n(row, w, std::uint8_t(0));
        return;
    }
    for (int x = 0; x < w; ++x) {
        row[x] = above_knee(sp + std::size_t(x) * sc, knee) && parts(x, y);
    }
}

/// The share over the region's crop, RGBA (the filters' packed path): at lifted pixels the
/// first three channels of `specular` less `knee`, at least 0 (with knee 0 the channels as they
/// are; non-finite values as 0), zero elsewhere and in alpha. This is what the filter subtracts
/// from colour (its rest) and what the second blur spreads; colour keeps the rest of the share,
/// so the split stays continuous where a highlight fades under the knee.
Image share_color(const Image &specular, const SplitRegion &region, float knee = 0.0f);

/// Add what the share's blur changed to `out`, the blur of colour less the share, over the
/// crop: out = color + (out - rest) + (share_blurred - share), rest = color - share, so a
/// pixel both blurs leave alone keeps color's bits. `rest_still`: the rest's blur changed
/// nothing (a filter that returned its input), and `out` is a copy of color. Channels past the
/// third keep the rest's blur.
void compose_split(const Image &color,
                   const Image &share,
                   const Image &share_blurred,
                   const SplitRegion &region,
                   bool rest_still,
                   Image &out);

}  // namespace posthaste::shading
