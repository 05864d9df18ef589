#pragma once
// Screen-space reflections: for each glossy pixel, a few reflected rays drawn from the GGX lobe of
// its roughness are marched through the depth pass in screen space (perspective-correct depth
// along the projected segment, McGuire and Mara 2014's idea without their DDA: samples spaced
// closer near the origin), a hit is refined by bisection and takes the colour pass's radiance
// there, re-shaded for the ray's view (its sun response and sky light); a ray that leaves the
// screen, meets nothing, or meets the back of a surface sees the sky (or the environment
// input: a reflection probe, shading/ssr/environment.h). The n.l-weighted mean of what the rays see
// replaces the sky lookup of the renderer's specular term (shading::sky_reflection_weight), which
// is what raster::render_reflection_truth computes exactly. Near the screen's edges hits fade into
// the sky (a ray that hits there would soon have left the screen, so its neighbours disagree).

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "core/image.h"
#include "shading/camera_rays.h"
#include "shading/ssr/environment.h"

namespace posthaste::shading {

struct SsrParams {
    /// GGX rays per pixel at roughness 0.35 and above; fewer on smoother surfaces (one on a
    /// mirror): ceil(rays * roughness / 0.35).
    int rays = 4;
    int steps = 16;               ///< Depth samples along each ray's screen segment.
    int refine = 5;               ///< Bisection steps after a hit.
    float thickness = 0.5f;       ///< World units a surface is taken to extend behind its depth.
    float max_distance = 60.0f;   ///< World units a ray may travel.
    float edge_fade = 0.02f;      ///< Fraction of the smaller image side over which hits fade.
    float max_roughness = 0.78f;  ///< Rougher pixels are left as they are.
    float sky_scale = 1.0f;       ///< The renderer's sky-light scale (a scene's sky_ambient).
    glm::vec3 sun_direction{
        0.4f, 0.75f, 0.3f};  ///< Unit; chooses the sky (shading/atmosphere/sky.h).
    /// A ray that leaves the screen in front of the surface its last sample saw meets that
    /// surface's colour (the surface taken to go on past the edge) instead of the sky.
    bool extend = false;
    /// The sun's irradiance (colour times illuminance) for re-shading hits: a hit's sun
    /// response and sky light as the reflected ray sees them instead of as the camera saw them.
    /// Zero: hits keep the colour the camera saw.
    glm::vec3 sun_irradiance{0.0f};
    /// 1: rays from every glossy pixel; 2: from every other pixel in x and y (a quarter of the
    /// rays); 4: every fourth (a sixteenth); the resolve fills the others from their traced
    /// neighbours on the same surface. The march's depth grid has cells of min(stride, 2).
    int stride = 4;
    /// Resolve window radius in pixels (0: each pixel keeps its own rays' estimate); at least
    /// `stride` where stride > 1, so that every pixel's window reaches a traced cell on either
    /// side.
    int denoise = 3;
    float intensity = 1.0f;  ///< Share of the change applied.
    std::uint32_t seed = 0;
    /// The colour pass's specular term: false, the rasterizer's (sky_reflection_weight:
    /// Schlick at n.v times the gloss); true, a physically based GGX lobe's directional albedo
    /// (ggx_reflection_weight, shading/lighting/env_brdf.h): a production renderer's.
    bool ggx = false;
};

/// The frame's passes, all of one size (the colour RGB(A), depth Z with +inf sky, world unit
/// normals, albedo, material roughness/metallic), and the camera they were seen through (NDC
/// [0, 1]^2 spanning the images).
struct SsrInputs {
    const Image *color = nullptr;
    const Image *depth = nullptr;
    const Image *normal = nullptr;
    const Image *albedo = nullptr;
    const Image *material = nullptr;
    glm::mat4 world_to_camera{1.0f};
    glm::mat4 world_to_ndc{1.0f};
    /// Optional: what a ray that the screen does not answer sees instead of the sky (a
    /// reflection probe or the scene's environment map, shading/ssr/environment.h).
    const Probe *environment = nullptr;
    /// Optional: what the colour pass's glossy surfaces reflect already, which the reflections
    /// replace: a renderer's world, a latitude-longitude map (shading/ssr/environment.h) looked
    /// up in each pixel's mirror direction. Without it, the sky model (sun_direction,
    /// sky_scale), as the rasterizer's beauty reflects. RGB(A), finite.
    const Image *world = nullptr;
    /// Optional: the sun's visibility (shadow pass, 1 lit .. 0 shadowed) for re-shading hits;
    /// without it a hit facing the sun is taken to be lit.
    const Image *shadow = nullptr;
};

/// What ssr() did, for the bench and the tests.
struct SsrStats {
    long long pixels = 0;  ///< Glossy pixels that traced rays.
    long long rays = 0;    ///< Rays marched.
    long long hits = 0;    ///< Rays that met a surface on screen.
};

/// The colour with screen-space reflections (same channels as the colour pass). Inputs must be
/// finite apart from +inf depth (the node sanitises them). Rows in parallel; the same bits for
/// any thread count.
Image ssr(const SsrInputs &in, const SsrParams &p, SsrStats *stats = nullptr);

}  // namespace posthaste::shading
