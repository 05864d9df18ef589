#pragma once
// How Minecrappy lights a surface, shared by the rasterizer's beauty (raster/render.cpp) and the
// relight node, so that relighting a G-buffer reproduces the beauty: the response to one light
// (metallic-workflow BRDF, toon bands, optional Burley diffuse and Kulla-Conty compensation) and
// the sky light (hemispherical diffuse plus a specular sky stand-in).
//
// Conventions as shading/lighting/brdf.h: unit vectors, n faces the viewer, v toward the viewer, l
// toward the light.

#include <algorithm>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

#include "shading/lighting/brdf.h"

namespace posthaste::shading {

class SceneSky;

/// The least roughness of the sun's highlight on a surface that a reflected ray meets, in the
/// reflection truth (raster/ray_cast.h) and in ssr's re-shaded hits: path regularisation
/// (Kaplanyan and Dachsbacher 2013), which keeps near-mirror sun glints seen in a reflection
/// from turning into fireflies.
inline constexpr float kReflectedSunMinRoughness = 0.3f;

/// Options of direct_response. The defaults are exactly the rasterizer's non-toon shading.
struct DirectOptions {
    Geometry geometry = Geometry::SmithCorrelated;
    bool burley = false;               ///< Burley diffuse instead of Lambert.
    bool energy_compensation = false;  ///< Add the Kulla-Conty multiple-scattering lobe.
    int toon_bands = 0;                ///< > 0: toon material, n.l quantised to this many bands.
    /// > 0 (toon only): the specular lobe's shape D(h)/D(n) quantised to this many steps
    /// (crisp highlight rings). 0: continuous specular, as the rasterizer.
    int toon_specular_steps = 0;
};

/// Reflected radiance toward v per unit irradiance (at normal incidence) from a light in
/// direction l: (diffuse + specular) * n.l, zero when n.l <= 0. With default options it is
/// evaluate(s, n, v, l). Toon: diffuse_albedo / pi * toon_band(n.l) plus the specular of a
/// black dielectric (the rasterizer's toon look).
glm::vec3 direct_response(const Surface &s,
                          const glm::vec3 &n,
                          const glm::vec3 &v,
                          const glm::vec3 &l,
                          const DirectOptions &options = {});

/// Add the rasterizer's sky light to c and return it: diffuse_albedo * the hemispherical sky
/// ambient, plus Schlick F(n.v) times the sky radiance in the mirror direction blended toward
/// the ambient by roughness (a split-sum stand-in). `sun_dir` only moves the sky's sun glow
/// (zero vector: no glow); `scale` is the scene's sky_ambient.
glm::vec3 add_sky_light(glm::vec3 c,
                        const Surface &s,
                        const glm::vec3 &n,
                        const glm::vec3 &v,
                        const glm::vec3 &sun_dir,
                        float scale);

/// add_sky_light for callers that look the sky up once per tile: `sky` is shading::scene_sky
/// (shading/atmosphere/sky.h) of the sun direction and `ambient` its ambient(n), unscaled. The same
/// result, bit for bit.
glm::vec3 add_sky_light(glm::vec3 c,
                        const Surface &s,
                        const glm::vec3 &n,
                        const glm::vec3 &v,
                        const SceneSky &sky,
                        const glm::vec3 &ambient,
                        float scale);

/// add_sky_light with the sky's radiance in a direction given by `sky_at(dir)` (unscaled, as
/// SceneSky::radiance from the sky camera without the sun's disc; a caller may look it up on a
/// table of it), called only for glossy surfaces. The overloads above are this with the sky's
/// own look-up.
template <typename SkyAt>
glm::vec3 add_sky_light_from(glm::vec3 c,
                             const Surface &s,
                             const glm::vec3 &n,
                             const glm::vec3 &v,
                             const glm::vec3 &ambient,
                             float scale,
                             const SkyAt &sky_at)
{
    const glm::vec3 amb = ambient * scale;
    c += diffuse_albedo(s) * amb;
    const float nv = std::max(glm::dot(n, v), 0.0f);
    const glm::vec3 r = glm::reflect(-v, n);
    const float gloss = (1.0f - s.roughness) * (1.0f - s.roughness);
    // Rough materials (gloss < 0.05, roughness > 0.78) reflect the ambient term alone: the sky
    // lookup would change them by less than 5% of a small term.
    const glm::vec3 env = gloss < 0.05f ? amb : glm::mix(amb, sky_at(r) * scale, gloss);
    c += fresnel_schlick(specular_f0(s), nv) * env;
    return c;
}

/// The weight of the sky lookup in add_sky_light's specular term: Schlick F(n.v) times the
/// gloss (1 - roughness)^2, zero for rough materials (gloss < 0.05) that reflect the ambient
/// alone. add_sky_light adds weight * scale * sky(reflect(-v, n)) (plus the ambient's share);
/// adding weight * (L - scale * sky(reflect(-v, n))) replaces that lookup by the radiance L the
/// reflected rays really meet (the reflection truth and the ssr node both do so).
glm::vec3 sky_reflection_weight(const Surface &s, const glm::vec3 &n, const glm::vec3 &v);

/// A unit direction around unit normal n drawn with density cos(theta) / pi from (u1, u2) in
/// [0, 1)^2 (a uniform point of the unit disc, radius sqrt(u1) and turn u2, lifted onto the
/// hemisphere: Malley's method). Used by the AO truth and the node's ray-traced method alike.
glm::vec3 sample_cosine_hemisphere(const glm::vec3 &n, float u1, float u2);

/// A reflected direction for GGX roughness `alpha` around unit normal n seen from v: a half
/// vector drawn with density D(h) (n.h) (Walter et al. 2007) from (u1, u2) in [0, 1)^2,
/// and v mirrored about it. May point below the surface (n.l <= 0): callers drop those. With
/// the weights n.l of the drawn directions, the weighted mean of the radiance they meet is the
/// prefiltered radiance of the split-sum approximation (Karis 2013).
glm::vec3 sample_ggx_reflection(
    const glm::vec3 &n, const glm::vec3 &v, float alpha, float u1, float u2);

}  // namespace posthaste::shading
