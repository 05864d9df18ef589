#pragma once
// How deep each surface seen in a frame is taken to be where it occludes a screen-space
// shadow march. The depth pass holds one layer, so a march cannot tell a thin pole from a wall:
// a fixed thickness makes a pole cast a shadow as if it were that deep, wherever a ray passes
// behind it. Here a surface is as deep as it is wide on screen: the shorter of its runs of
// pixels along the row and the column, a run ending where depth jumps by more than the
// surface's slope gives (a silhouette, not a crease), times the pixel's footprint at its depth.

#include "core/image.h"
#include "shading/camera_rays.h"

namespace posthaste::shading {

/// One channel, metres: for each pixel of `depth` (camera-space depth, > 0 on surfaces) the
/// thickness its surface is taken to have, at most `max_thickness`; 0 where there is no surface.
/// A run that reaches the image's edge counts as unbounded (its object may go on beyond). The
/// normals (world space, any length) give each pixel's slope; without a usable normal a pixel is
/// taken to face the camera. `rays` are the camera's, NDC [0, 1]^2 spanning the image; with no
/// pixel footprint (a degenerate camera) every surface is `max_thickness` deep.
/// With `stride` > 1 the map covers every stride-th pixel in x and y (ceil(size / stride)),
/// as if the passes were that much coarser: a reduced-resolution reader's map, a quarter of the
/// work at 2.
///
/// `extent` says which run a surface is as deep as: the shorter of the two axes' (narrowest: a
/// pole is as deep as it is wide, what an occluder in a march needs), or the longer (widest:
/// how far back a surface can reach at most, as a ground whose column runs are cut by steps
/// reaches back by its rows: the gate of GTAO's radius crossings, measured better there on the
/// Cycles yard and on every rasterizer bench frame).
enum class SurfaceExtent { narrowest, widest };
Image occluder_thickness(const Image &depth,
                         const Image &normal,
                         const CameraRays &rays,
                         float max_thickness,
                         int stride = 1,
                         SurfaceExtent extent = SurfaceExtent::narrowest);

}  // namespace posthaste::shading
