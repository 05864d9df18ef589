#pragma once
// Minecrappy's renderer: one frame of a Scene into a Frame with only the requested passes, and
// ground truth by accumulation (motion blur over the shutter, depth of field over the aperture).
//
// Data passes take one sample at each pixel centre, from a visibility buffer: the rasterizer
// finds the nearest triangle per pixel, then the pixel's camera ray is intersected with that
// triangle in world space, so depth, position, normal and motion are exact at pixel centres.
// Passes (names from core/passes.h):
//   color     R G B A, premultiplied scene-linear; alpha is 1 everywhere (the sky is drawn).
//   depth     Z, camera-space z in metres; +inf on sky.
//   normal    N, world unit normal (interpolated vertex normals); 0 on sky.
//   position  P, world position; 0 on sky.
//   motion    pixels from the previous frame (frame - 1) to this one, x right, y down, from
//             camera and object motion; on sky, from camera rotation alone.
//   albedo, material (roughness, metallic, anisotropy), tangent (world, unit): 0 on sky.
//   id        material id of the surface (0 on sky).
//   specular  R G B, the view-dependent share of color (color less albedo (1 - metallic) times
//             the sun's n.l / pi and the sky ambient); 0 on sky. Shaded with color, at its
//             supersampling.
//   specular_motion, diffuse_motion  X Y as motion: where the specular share and the rest of
//             color move. On a ball, the virtual image of a distant light (R/2 behind the
//             surface) and the ball's shape, both carried by its translation, not its spin; on
//             flat faces and sky, the motion pass itself (render.cpp, specular_point).
//   specular_depth  Z: the camera depth of that image (where a thin lens focuses the
//             highlight); depth itself on flat faces, +inf on sky.
// Header: frame.number, frame.camera (matrices of this and the previous frame, lens, shutter,
// near/far), attributes "posthaste:scene" (scene name) and "posthaste:fps".

#include <cstddef>
#include <set>
#include <string>

#include "core/frame.h"
#include "raster/scene.h"

namespace posthaste::raster {

struct RenderOptions {
    int width = 1920, height = 1080;
    /// Passes to produce; anything else is not computed. Names: color depth normal position
    /// motion albedo material tangent id specular specular_motion diffuse_motion specular_depth.
    std::set<std::string> passes = {"color"};
    /// Beauty supersampling per axis (1, 2 or 4): color is the box-filtered mean of
    /// supersample^2 samples per pixel. Data passes stay one sample per pixel.
    int supersample = 1;
    bool shadows = true;          ///< Sun shadow map on or off.
    int shadow_map_size = 2048;   ///< Texels per side of the static shadow map.
    bool greedy_meshing = false;  ///< Fewer triangles, but T-junctions can crack edges.
    /// Ranks of each cryptomatte (CryptoObject, CryptoMaterial; 2 a rank layer), 1..16.
    int cryptomatte_ranks = 6;
    /// Overscan: pixels rendered beyond the display window on the left and right (x) and on
    /// the top and bottom (y). Every pass and truth covers the data window, (-overscan_x,
    /// -overscan_y) to (width + overscan_x, height + overscan_y); the header's camera and
    /// display window stay those of width x height, so a display pixel shows what it shows
    /// without overscan (the wide render's sensor is widened by the same factor).
    int overscan_x = 0, overscan_y = 0;
};

/// The cryptomattes the renderer writes, and the name of rank layer k of one ("CryptoObject03").
inline constexpr const char *kCryptoObject = "CryptoObject";
inline constexpr const char *kCryptoMaterial = "CryptoMaterial";
std::string crypto_layer(const char *type, int k);

/// Ground-truth accumulation settings.
struct TruthOptions {
    bool motion = true;      ///< Average over the shutter, centred on the frame time.
    bool dof = false;        ///< Average over a thin-lens aperture.
    int samples = 64;        ///< Accumulated renders.
    std::uint32_t seed = 0;  ///< Jitter seed.
};

/// Time spent per stage of the last render, milliseconds, and triangle counts.
struct RenderStats {
    double mesh_ms = 0, setup_bin_ms = 0, raster_ms = 0, shade_ms = 0, shadow_ms = 0;
    std::size_t triangles = 0;         ///< Submitted after chunk culling.
    std::size_t triangles_binned = 0;  ///< After back-face culling and clipping.
};

/// Every pass name render_frame accepts.
const std::set<std::string> &render_pass_names();

/// Throws Error (usage) for an unknown pass, a non-positive size or a bad supersample factor.
void validate(const RenderOptions &options);

/// Render frame `frame` (integer frames; time = frame). Meshes of the static world are built on
/// the first call and cached in scene.cache (thread-safe). Deterministic: same bits for any
/// thread count.
Frame render_frame(const Scene &scene,
                   int frame,
                   const RenderOptions &options,
                   RenderStats *stats = nullptr);

/// Ground truth color for frame `frame`: the mean of `truth.samples` beauty renders at
/// stratified shutter times t = frame + (u - 0.5) shutter (camera and objects moved for each)
/// and/or thin-lens samples (aperture diameter = focal length / f-number, concentric disc
/// mapping, focus plane at the focus distance). Motion and dof together are jointly stratified
/// (time strata permuted against a 2D lens sequence). options.passes is ignored; each sample
/// uses options.supersample and options.shadows. Returns a Frame with the "color" pass
/// and the same header as render_frame; hash-based jitter, same bits for any thread count.
Frame render_truth(const Scene &scene,
                   int frame,
                   const RenderOptions &options,
                   const TruthOptions &truth);

}  // namespace posthaste::raster
