#pragma once
// Microfacet BRDF pieces shared by the rasterizer and the relight node: GGX / Trowbridge-Reitz
// distribution (isotropic and anisotropic), Smith masking (height-correlated and separable),
// the Cook-Torrance V-cavity term, Schlick Fresnel and Lambert, plus a metallic-workflow
// evaluate(). References: Walter et al. 2007 (GGX), Heitz 2014 "Understanding the
// Masking-Shadowing Function" (eqs. 43, 99), Burley 2012 (alpha = roughness^2, anisotropy),
// Karis 2013 and Filament (metallic workflow, minimum roughness).
//
// Conventions: all vectors are unit length, in any one space; n is the shading normal, v points
// to the viewer, l points to the light, h = normalize(v + l). Cosines are clamped to
// kMinCosine so that every function stays finite at grazing angles and for roughness 0.

#include <array>
#include <glm/vec3.hpp>

namespace posthaste::shading {

inline constexpr float kPi = 3.14159265358979323846f;
/// Smallest perceptual roughness used (Filament's limit): below it the GGX lobe is so narrow
/// that float D overflows to useless spikes. alpha = max(r, kMinRoughness)^2 ~= 0.002.
inline constexpr float kMinRoughness = 0.045f;
/// n.v and n.l are clamped to at least this before dividing by them.
inline constexpr float kMinCosine = 1e-4f;

/// GGX alpha from perceptual roughness r in [0, 1]: alpha = max(r, kMinRoughness)^2.
float roughness_to_alpha(float roughness);

/// Anisotropic alphas along the tangent (x) and bitangent (y) for anisotropy in [-1, 1]
/// (Kulla & Conty 2017: ax = alpha (1 + a), ay = alpha (1 - a)), each at least the alpha of
/// kMinRoughness. anisotropy 0 gives ax = ay = alpha.
void anisotropic_alphas(float alpha, float anisotropy, float &alpha_x, float &alpha_y);

/// Isotropic GGX normal distribution D(h) = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2);
/// zero for n.h <= 0. Normalised: integral of D(h) (n.h) over the hemisphere is 1.
float d_ggx(float n_dot_h, float alpha);

/// d_ggx with 1 - (n.h)^2 given as sin2_h = |h - n (n.h)|^2 (clamped to 1), which does not
/// cancel at the lobe's peak: a^2 / (pi d^2), d = sin2_h (1 - a^2) + a^2; zero for n.h <= 0.
/// The D of evaluate()'s default lobe (dv_ggx_smith_correlated).
float d_ggx(float n_dot_h, float sin2_h, float alpha);

/// |h - n (n.h)|^2 clamped to 1: 1 - (n.h)^2 without cancellation, for unit n and h.
float sin2_across(const glm::vec3 &n, const glm::vec3 &h);

/// Anisotropic GGX D(h) = 1 / (pi ax ay ((t.h/ax)^2 + (b.h/ay)^2 + (n.h)^2)^2); zero for n.h <= 0.
/// t and b are the unit tangent and bitangent (t, b, n orthonormal).
float d_ggx_aniso(float n_dot_h, float t_dot_h, float b_dot_h, float alpha_x, float alpha_y);

/// Smith G1 for GGX, 2 (n.x) / ((n.x) + sqrt(alpha^2 + (1 - alpha^2)(n.x)^2)).
float g1_smith_ggx(float n_dot_x, float alpha);

/// Separable Smith G2 = G1(v) G1(l).
float g2_smith_separable(float n_dot_v, float n_dot_l, float alpha);

/// Height-correlated Smith G2 = 1 / (1 + Lambda(v) + Lambda(l)) (Heitz 2014 eq. 99).
float g2_smith_correlated(float n_dot_v, float n_dot_l, float alpha);

/// Height-correlated Smith visibility V = G2 / (4 (n.l)(n.v)), in the closed form
/// 0.5 / (n.l sqrt(n.v^2 (1 - a^2) + a^2) + n.v sqrt(n.l^2 (1 - a^2) + a^2)). The default.
float v_smith_correlated(float n_dot_v, float n_dot_l, float alpha);

/// d_ggx(n.h, alpha) times v_smith_correlated(n.v, n.l, alpha), evaluate()'s default lobe, with
/// 1 - (n.h)^2 given as sin2_h = |h - n (n.h)|^2 (clamped to 1): d = sin2_h (1 - a^2) + a^2
/// does not cancel at the lobe's peak, where D amplifies an error of n.h by about 1 / alpha^2.
/// One division: (0.5 a^2) / (pi d^2 (n.l sqrt(...) + n.v sqrt(...))). Zero for n.h <= 0.
float dv_ggx_smith_correlated(
    float n_dot_h, float sin2_h, float n_dot_v, float n_dot_l, float alpha);

/// Anisotropic height-correlated Smith visibility (Heitz 2014, anisotropic Lambda).
/// t.v, b.v, t.l, b.l are the tangent/bitangent components of v and l.
float v_smith_correlated_aniso(float n_dot_v,
                               float n_dot_l,
                               float t_dot_v,
                               float b_dot_v,
                               float t_dot_l,
                               float b_dot_l,
                               float alpha_x,
                               float alpha_y);

/// Cook-Torrance V-cavity G = min(1, 2 (n.h)(n.v) / (v.h), 2 (n.h)(n.l) / (v.h)).
float g_cook_torrance(float n_dot_h, float n_dot_v, float n_dot_l, float v_dot_h);

/// Schlick Fresnel F0 + (1 - F0) (1 - cos)^5.
glm::vec3 fresnel_schlick(const glm::vec3 &f0, float cos_theta);
float fresnel_schlick(float f0, float cos_theta);

/// Lambert BRDF value for an albedo: albedo / pi.
glm::vec3 lambert(const glm::vec3 &albedo);

/// Which masking-shadowing term evaluate() uses.
enum class Geometry { SmithCorrelated, SmithSeparable, CookTorrance };

/// A surface point in the metallic workflow.
struct Surface {
    glm::vec3 albedo{0.8f};      ///< Base colour, linear.
    float roughness = 0.5f;      ///< Perceptual roughness in [0, 1].
    float metallic = 0.0f;       ///< 0 dielectric (F0 = 0.04), 1 metal (F0 = albedo).
    float anisotropy = 0.0f;     ///< [-1, 1]; needs `tangent`. 0: isotropic.
    glm::vec3 tangent{1, 0, 0};  ///< Unit tangent (used only when anisotropy != 0).
};

/// F0 = mix(0.04, albedo, metallic).
glm::vec3 specular_f0(const Surface &s);
/// Diffuse albedo = albedo (1 - metallic).
glm::vec3 diffuse_albedo(const Surface &s);

/// BRDF times n.l for one light of unit irradiance at normal incidence: the reflected radiance
/// toward v is evaluate() * light irradiance. Lambert diffuse plus GGX specular with Schlick
/// Fresnel and the chosen masking term. Zero when n.l <= 0; n.v is clamped to kMinCosine so
/// back-facing views stay finite. Anisotropic D and V are used when anisotropy != 0 (only with
/// the Smith terms; CookTorrance ignores anisotropy in G).
glm::vec3 evaluate(const Surface &s,
                   const glm::vec3 &n,
                   const glm::vec3 &v,
                   const glm::vec3 &l,
                   Geometry geometry = Geometry::SmithCorrelated);

/// Burley 2012 diffuse BRDF value:
/// albedo / pi (1 + (F90 - 1)(1 - n.l)^5)(1 + (F90 - 1)(1 - n.v)^5), F90 = 0.5 + 2 r (l.h)^2.
/// Cosines are clamped to [0, 1].
glm::vec3 burley(
    const glm::vec3 &albedo, float roughness, float n_dot_v, float n_dot_l, float l_dot_h);

/// Toon diffuse band: ceil(n.l * bands) / bands for n.l > 0, else 0 (the rasterizer uses 3).
float toon_band(float n_dot_l, int bands);

/// Directional albedo of the specular lobe alone with F = 1 (the Kulla-Conty E(mu)): the
/// integral over l of evaluate() for a metal of albedo 1, view cosine mu = n.v, computed by GGX
/// visible-normal sampling of h with `samples` Hammersley points. Deterministic. With `f0`, a
/// metal of albedo f0 (Schlick's Fresnel from F0 = f0; f0 0 leaves Schlick's weight alone).
float specular_albedo(float roughness, float mu, Geometry geometry, int samples, float f0 = 1.0f);

/// Kulla & Conty 2017 energy tables for one masking term: E(mu, roughness) on a kMu x kRoughness
/// grid (mu at cell centres (i + 0.5) / kMu, roughness at j / (kRoughness - 1)) and
/// E_avg(roughness) = 2 integral E(mu) mu dmu. Lookups interpolate bilinearly and clamp.
struct EnergyTable {
    static constexpr int kMu = 64, kRoughness = 32;
    static constexpr int kSamples = 1024;     ///< Visible-normal samples per entry.
    std::array<float, kMu * kRoughness> e{};  ///< e[j * kMu + i]: roughness j, mu i.
    std::array<float, kRoughness> e_avg{};
    float lookup_e(float roughness, float mu) const;
    float lookup_e_avg(float roughness) const;
};

/// The table of `geometry`, integrated on first use (2M BRDF evaluations, in parallel) and
/// cached for the process; thread-safe.
const EnergyTable &energy_table(Geometry geometry);

/// Kulla-Conty multiple-scattering lobe times n.l for one light of unit irradiance:
/// (1 - E(n.v))(1 - E(n.l)) / (pi (1 - E_avg)) * F_ms * n.l, with the coloured term
/// F_ms = F_avg^2 E_avg / (1 - F_avg (1 - E_avg)) and Schlick's F_avg = (20 F0 + 1) / 21.
/// Zero for n.l <= 0 and when E_avg is within 1e-6 of 1. Anisotropic surfaces use the isotropic
/// table at their base roughness.
glm::vec3 multiscatter(const Surface &s, float n_dot_v, float n_dot_l, Geometry geometry);

}  // namespace posthaste::shading
