#include "shading/brdf.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace posthaste::shading {
namespace {

float clamp_cos(float c)
{
    return std::max(c, kMinCosine);
}

// Smith Lambda for GGX from alpha^2 and cos^2 (Heitz 2014 eq. 72).
float lambda_ggx(float cos_theta, float alpha2)
{
    const float c2 = cos_theta * cos_theta;
    const float tan2 = std::max(1.0f - c2, 0.0f) / c2;
    return 0.5f * (std::sqrt(1.0f + alpha2 * tan2) - 1.0f);
}

}  // namespace

float roughness_to_alpha(float roughness)
{
    const float r = std::clamp(roughness, kMinRoughness, 1.0f);
    return r * r;
}

void anisotropic_alphas(float alpha, float anisotropy, float &alpha_x, float &alpha_y)
{
    const float a = std::clamp(anisotropy, -1.0f, 1.0f);
    const float min_alpha = kMinRoughness * kMinRoughness;
    alpha_x = std::max(alpha * (1.0f + a), min_alpha);
    alpha_y = std::max(alpha * (1.0f - a), min_alpha);
}

float d_ggx(float n_dot_h, float alpha)
{
    if (n_dot_h <= 0.0f) {
        return 0.0f;
    }
    const float a2 = alpha * alpha;
    const float d = n_dot_h * n_dot_h * (a2 - 1.0f) + 1.0f;
    return a2 / (kPi * d * d);
}

float d_ggx_aniso(float n_dot_h, float t_dot_h, float b_dot_h, float alpha_x, float alpha_y)
{
    if (n_dot_h <= 0.0f) {
        return 0.0f;
    }
    const float x = t_dot_h / alpha_x;
    const float y = b_dot_h / alpha_y;
    const float d = x * x + y * y + n_dot_h * n_dot_h;
    return 1.0f / (kPi * alpha_x * alpha_y * d * d);
}

float g1_smith_ggx(float n_dot_x, float alpha)
{
    const float c = clamp_cos(n_dot_x);
    const float a2 = alpha * alpha;
    return 2.0f * c / (c + std::sqrt(a2 + (1.0f - a2) * c * c));
}

float g2_smith_separable(float n_dot_v, float n_dot_l, float alpha)
{
    return g1_smith_ggx(n_dot_v, alpha) * g1_smith_ggx(n_dot_l, alpha);
}

float g2_smith_correlated(float n_dot_v, float n_dot_l, float alpha)
{
    const float a2 = alpha * alpha;
    return 1.0f / (1.0f + lambda_ggx(clamp_cos(n_dot_v), a2) + lambda_ggx(clamp_cos(n_dot_l), a2));
}

float v_smith_correlated(float n_dot_v, float n_dot_l, float alpha)
{
    const float nv = clamp_cos(n_dot_v);
    const float nl = clamp_cos(n_dot_l);
    const float a2 = alpha * alpha;
    const float gv = nl * std::sqrt(nv * nv * (1.0f - a2) + a2);
    const float gl = nv * std::sqrt(nl * nl * (1.0f - a2) + a2);
    return 0.5f / (gv + gl);
}

float v_smith_correlated_aniso(float n_dot_v,
                               float n_dot_l,
                               float t_dot_v,
                               float b_dot_v,
                               float t_dot_l,
                               float b_dot_l,
                               float alpha_x,
                               float alpha_y)
{
    // V = 0.5 / (n.l |(ax t.v, ay b.v, n.v)| + n.v |(ax t.l, ay b.l, n.l)|), the anisotropic
    // form of the closed expression above (Heitz 2014 eq. 86 with Lambda_aniso).
    const float nv = clamp_cos(n_dot_v);
    const float nl = clamp_cos(n_dot_l);
    const float lv = std::sqrt(alpha_x * alpha_x * t_dot_v * t_dot_v +
                               alpha_y * alpha_y * b_dot_v * b_dot_v + nv * nv);
    const float ll = std::sqrt(alpha_x * alpha_x * t_dot_l * t_dot_l +
                               alpha_y * alpha_y * b_dot_l * b_dot_l + nl * nl);
    return 0.5f / (nl * lv + nv * ll);
}

float g_cook_torrance(float n_dot_h, float n_dot_v, float n_dot_l, float v_dot_h)
{
    const float vh = std::max(v_dot_h, kMinCosine);
    const float g = 2.0f * std::max(n_dot_h, 0.0f) / vh;
    return std::min({1.0f, g * std::max(n_dot_v, 0.0f), g * std::max(n_dot_l, 0.0f)});
}

glm::vec3 fresnel_schlick(const glm::vec3 &f0, float cos_theta)
{
    const float m = 1.0f - std::clamp(cos_theta, 0.0f, 1.0f);
    const float m5 = (m * m) * (m * m) * m;
    return f0 + (glm::vec3(1.0f) - f0) * m5;
}

float fresnel_schlick(float f0, float cos_theta)
{
    const float m = 1.0f - std::clamp(cos_theta, 0.0f, 1.0f);
    return f0 + (1.0f - f0) * (m * m) * (m * m) * m;
}

glm::vec3 lambert(const glm::vec3 &albedo)
{
    return albedo * (1.0f / kPi);
}

glm::vec3 specular_f0(const Surface &s)
{
    return glm::mix(glm::vec3(0.04f), s.albedo, s.metallic);
}

glm::vec3 diffuse_albedo(const Surface &s)
{
    return s.albedo * (1.0f - s.metallic);
}

glm::vec3 evaluate(
    const Surface &s, const glm::vec3 &n, const glm::vec3 &v, const glm::vec3 &l, Geometry geometry)
{
    const float nl = glm::dot(n, l);
    if (nl <= 0.0f) {
        return glm::vec3(0.0f);
    }
    const float nv = clamp_cos(glm::dot(n, v));
    glm::vec3 h = v + l;
    const float hlen = glm::length(h);
    h = hlen > 1e-8f ? h / hlen : n;
    const float nh = std::max(glm::dot(n, h), 0.0f);
    const float vh = std::max(glm::dot(v, h), 0.0f);
    const float alpha = roughness_to_alpha(s.roughness);

    float dv = 0.0f;  // D * V, with V = G / (4 n.l n.v)
    const bool aniso = s.anisotropy != 0.0f && geometry != Geometry::CookTorrance;
    if (aniso) {
        const glm::vec3 t = glm::normalize(s.tangent - n * glm::dot(n, s.tangent));
        const glm::vec3 b = glm::cross(n, t);
        float ax, ay;
        anisotropic_alphas(alpha, s.anisotropy, ax, ay);
        const float d = d_ggx_aniso(nh, glm::dot(t, h), glm::dot(b, h), ax, ay);
        float vis;
        if (geometry == Geometry::SmithCorrelated) {
            vis = v_smith_correlated_aniso(
                nv, nl, glm::dot(t, v), glm::dot(b, v), glm::dot(t, l), glm::dot(b, l), ax, ay);
        } else {
            // Separable: G1 per direction with the projected alpha (Heitz 2014 eq. 80).
            auto g1 = [&](float c, float tx, float bx) {
                const float s2 = std::max(1.0f - c * c, 1e-12f);
                const float a2 = (tx * tx * ax * ax + bx * bx * ay * ay) / s2;
                return g1_smith_ggx(c, std::sqrt(a2));
            };
            vis = g1(nv, glm::dot(t, v), glm::dot(b, v)) * g1(nl, glm::dot(t, l), glm::dot(b, l)) /
                  (4.0f * nl * nv);
        }
        dv = d * vis;
    } else {
        const float d = d_ggx(nh, alpha);
        float vis;
        switch (geometry) {
            case Geometry::SmithSeparable:
                vis = g2_smith_separable(nv, nl, alpha) / (4.0f * clamp_cos(nl) * nv);
                break;
            case Geometry::CookTorrance:
                vis = g_cook_torrance(nh, nv, nl, vh) / (4.0f * clamp_cos(nl) * nv);
                break;
            default:
                vis = v_smith_correlated(nv, nl, alpha);
                break;
        }
        dv = d * vis;
    }
    const glm::vec3 f = fresnel_schlick(specular_f0(s), vh);
    return (lambert(diffuse_albedo(s)) + f * dv) * nl;
}

}  // namespace posthaste::shading
