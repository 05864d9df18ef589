#pragma once
// The directional albedo of the GGX specular lobe: how much of a uniform environment a
// physically based renderer's specular term reflects toward the viewer. With Schlick's Fresnel
// on v.h it splits as F0 A + B (the split sum's environment BRDF, Karis 2013), A and B
// functions of n.v and roughness alone. Tabulated once, on first use, by integrating the lobe
// (Smith separable masking, as Cycles' microfacet BSDFs; brdf.h specular_albedo) over a fixed
// point set, so its values are the same on every machine.

#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "shading/lighting/brdf.h"

namespace posthaste::shading {

/// (A, B) of the GGX lobe at n.v (clamped to [0, 1]) and perceptual roughness (clamped to
/// [0, 1]): bilinear in a 32 x 32 table.
glm::vec2 ggx_directional_albedo(float n_dot_v, float roughness);

/// specular_f0(s) A + B: the share of a uniform environment the surface's GGX lobe reflects
/// toward v (unit n and v); the weight of a physically based renderer's reflections, where
/// sky_reflection_weight is the rasterizer's.
glm::vec3 ggx_reflection_weight(const Surface &s, const glm::vec3 &n, const glm::vec3 &v);
/// The same from n.v: ggx_reflection_weight(s, n, v) is ggx_reflection_weight(s, dot(n, v)).
glm::vec3 ggx_reflection_weight(const Surface &s, float n_dot_v);

/// The table ggx_directional_albedo interpolates, for vector kernels that give its bits: (A, B)
/// pairs, kGgxAlbedoTableSize of them a row along n.v = i / (size - 1), one row per roughness
/// j / (size - 1): A of point (i, j) at [2 (j size + i)], B after it.
inline constexpr int kGgxAlbedoTableSize = 32;
const float *ggx_albedo_table();

}  // namespace posthaste::shading
