#include "shading/lighting/brdf.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <mutex>

#include "core/hash.h"
#include "core/parallel.h"

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

float d_ggx(float n_dot_h, float sin2_h, float alpha)
{
    if (n_dot_h <= 0.0f) {
        return 0.0f;
    }
    const float a2 = alpha * alpha;
    const float d = sin2_h * (1.0f - a2) + a2;
    return a2 / (kPi * d * d);
}

float sin2_across(const glm::vec3 &n, const glm::vec3 &h)
{
    const glm::vec3 q = h - n * glm::dot(n, h);
    return std::min(glm::dot(q, q), 1.0f);
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

float dv_ggx_smith_correlated(
    float n_dot_h, float sin2_h, float n_dot_v, float n_dot_l, float alpha)
{
    if (n_dot_h <= 0.0f) {
        return 0.0f;
    }
    const float nv = clamp_cos(n_dot_v);
    const float nl = clamp_cos(n_dot_l);
    const float a2 = alpha * alpha;
    const float d = sin2_h * (1.0f - a2) + a2;
    const float gv = nl * std::sqrt(nv * nv * (1.0f - a2) + a2);
    const float gl = nv * std::sqrt(nl * nl * (1.0f - a2) + a2);
    return (0.5f * a2) / (kPi * d * d * (gv + gl));
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

namespace {

// evaluate() takes the anisotropic D for this surface and masking term.
bool aniso_lobe(const Surface &s, Geometry geometry)
{
    return s.anisotropy != 0.0f && geometry != Geometry::CookTorrance;
}

}  // namespace

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
    // The default lobe takes 1 - (n.h)^2 as |h - n (n.h)|^2 and the anisotropic D adds (n.h)^2,
    // so neither amplifies h's rounding: one division and three products serve. The separable
    // and V-cavity lobes take D from n.h alone, whose 1 - (n.h)^2 cancels at a glossy peak: the
    // exactly rounded components keep that error at its least.
    if (!(hlen > 1e-8f)) {
        h = n;
    } else if (geometry == Geometry::SmithCorrelated || aniso_lobe(s, geometry)) {
        h *= 1.0f / hlen;
    } else {
        h /= hlen;
    }
    const float nh = std::max(glm::dot(n, h), 0.0f);
    const float vh = std::max(glm::dot(v, h), 0.0f);
    const float alpha = roughness_to_alpha(s.roughness);

    float dv = 0.0f;  // D * V, with V = G / (4 n.l n.v)
    const bool aniso = aniso_lobe(s, geometry);
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
    } else if (geometry == Geometry::SmithCorrelated) {
        dv = dv_ggx_smith_correlated(nh, sin2_across(n, h), nv, nl, alpha);
    } else {
        const float d = d_ggx(nh, alpha);
        const float g = geometry == Geometry::SmithSeparable ? g2_smith_separable(nv, nl, alpha)
                                                             : g_cook_torrance(nh, nv, nl, vh);
        dv = d * (g / (4.0f * clamp_cos(nl) * nv));
    }
    const glm::vec3 f = fresnel_schlick(specular_f0(s), vh);
    return (lambert(diffuse_albedo(s)) + f * dv) * nl;
}

glm::vec3 burley(
    const glm::vec3 &albedo, float roughness, float n_dot_v, float n_dot_l, float l_dot_h)
{
    auto p5 = [](float c) {
        const float m = 1.0f - std::clamp(c, 0.0f, 1.0f);
        return (m * m) * (m * m) * m;
    };
    const float lh = std::clamp(l_dot_h, 0.0f, 1.0f);
    const float f90 = 0.5f + 2.0f * std::clamp(roughness, 0.0f, 1.0f) * lh * lh;
    const float k = (1.0f + (f90 - 1.0f) * p5(n_dot_l)) * (1.0f + (f90 - 1.0f) * p5(n_dot_v));
    return albedo * (k / kPi);
}

float toon_band(float n_dot_l, int bands)
{
    return n_dot_l > 0.0f ? std::ceil(n_dot_l * float(bands)) / float(bands) : 0.0f;
}

namespace {

}  // namespace

float specular_albedo(float roughness, float mu, Geometry geometry, int samples, float f0)
{
    // Local frame n = z, v in the xz plane. h is drawn from the distribution of visible normals
    // (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"), l = reflect(v, h), so
    // pdf(l) = G1(v) D(h) / (4 n.v). D is evaluated at the h that evaluate() rebuilds from v + l,
    // in the form evaluate() uses for `geometry`, so that its float rounding cancels (it matters
    // for alpha ~ 0.002).
    const float nv = std::clamp(mu, kMinCosine, 1.0f);
    const glm::vec3 n(0, 0, 1), v(std::sqrt(1.0f - nv * nv), 0.0f, nv);
    Surface s;
    s.albedo = glm::vec3(f0);
    s.metallic = 1.0f;  // F0 = f0 (1: F = 1 exactly), no diffuse
    s.roughness = roughness;
    const float alpha = roughness_to_alpha(roughness);
    const glm::vec3 vh_dir = glm::normalize(glm::vec3(alpha * v.x, alpha * v.y, v.z));
    const float lensq = vh_dir.x * vh_dir.x + vh_dir.y * vh_dir.y;
    const glm::vec3 t1 =
        lensq > 0.0f ? glm::vec3(-vh_dir.y, vh_dir.x, 0.0f) / std::sqrt(lensq) : glm::vec3(1, 0, 0);
    const glm::vec3 t2 = glm::cross(vh_dir, t1);
    const float g1v = g1_smith_ggx(nv, alpha);
    double sum = 0.0;
    for (int i = 0; i < samples; ++i) {
        const float u1 = (float(i) + 0.5f) / float(samples);
        const float u2 = posthaste::radical_inverse_base2(std::uint32_t(i));
        const float r = std::sqrt(u1), phi = 2.0f * kPi * u2;
        const float p1 = r * std::cos(phi);
        const float sh = 0.5f * (1.0f + vh_dir.z);
        const float p2 =
            (1.0f - sh) * std::sqrt(std::max(0.0f, 1.0f - p1 * p1)) + sh * r * std::sin(phi);
        const glm::vec3 nh =
            p1 * t1 + p2 * t2 + std::sqrt(std::max(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh_dir;
        const glm::vec3 h =
            glm::normalize(glm::vec3(alpha * nh.x, alpha * nh.y, std::max(0.0f, nh.z)));
        const float vh = glm::dot(v, h);
        if (vh <= 0.0f) {
            continue;
        }
        const glm::vec3 l = 2.0f * vh * h - v;
        if (l.z <= 0.0f) {
            continue;
        }
        glm::vec3 he = v + l;  // exactly as evaluate() rebuilds h
        he = he / glm::length(he);
        const float d = geometry == Geometry::SmithCorrelated
                            ? d_ggx(std::max(glm::dot(n, he), 0.0f), sin2_across(n, he), alpha)
                            : d_ggx(std::max(glm::dot(n, he), 0.0f), alpha);
        const float pdf = g1v * d / (4.0f * nv);
        if (pdf > 0.0f) {
            sum += double(evaluate(s, n, v, l, geometry).x / pdf);
        }
    }
    return float(sum / double(samples));
}

float EnergyTable::lookup_e(float roughness, float mu) const
{
    const float fr = std::clamp(roughness, 0.0f, 1.0f) * float(kRoughness - 1);
    const float fm = std::clamp(mu * float(kMu) - 0.5f, 0.0f, float(kMu - 1));
    const int j0 = std::min(int(fr), kRoughness - 2), i0 = std::min(int(fm), kMu - 2);
    const float tr = fr - float(j0), tm = fm - float(i0);
    const float *r0 = &e[std::size_t(j0 * kMu)];
    const float *r1 = r0 + kMu;
    const float a = r0[i0] + (r0[i0 + 1] - r0[i0]) * tm;
    const float b = r1[i0] + (r1[i0 + 1] - r1[i0]) * tm;
    return a + (b - a) * tr;
}

float EnergyTable::lookup_e_avg(float roughness) const
{
    const float fr = std::clamp(roughness, 0.0f, 1.0f) * float(kRoughness - 1);
    const int j0 = std::min(int(fr), kRoughness - 2);
    const float tr = fr - float(j0);
    return e_avg[std::size_t(j0)] + (e_avg[std::size_t(j0 + 1)] - e_avg[std::size_t(j0)]) * tr;
}

const EnergyTable &energy_table(Geometry geometry)
{
    static std::once_flag once[3];
    static EnergyTable tables[3];
    const int g = int(geometry);
    std::call_once(once[g], [&] {
        EnergyTable &t = tables[g];
        constexpr int nm = EnergyTable::kMu, nr = EnergyTable::kRoughness;
        // Isolated: a thread waiting inside this loop must not pick up a task that blocks on
        // this call_once.
        tbb::this_task_arena::isolate([&] {
            parallel_for(0, nr, [&](int j) {
                const float r = float(j) / float(nr - 1);
                double avg = 0.0;
                for (int i = 0; i < nm; ++i) {
                    const float mu = (float(i) + 0.5f) / float(nm);
                    const float e =
                        std::min(specular_albedo(r, mu, geometry, EnergyTable::kSamples), 1.0f);
                    t.e[std::size_t(j * nm + i)] = e;
                    avg += 2.0 * double(e) * double(mu) / double(nm);
                }
                t.e_avg[std::size_t(j)] = float(avg);
            });
        });
    });
    return tables[g];
}

glm::vec3 multiscatter(const Surface &s, float n_dot_v, float n_dot_l, Geometry geometry)
{
    if (n_dot_l <= 0.0f) {
        return glm::vec3(0.0f);
    }
    const EnergyTable &t = energy_table(geometry);
    const float e_avg = t.lookup_e_avg(s.roughness);
    if (e_avg > 1.0f - 1e-6f) {
        return glm::vec3(0.0f);
    }
    const float ev = t.lookup_e(s.roughness, std::clamp(n_dot_v, kMinCosine, 1.0f));
    const float el = t.lookup_e(s.roughness, std::min(n_dot_l, 1.0f));
    const float fms = (1.0f - ev) * (1.0f - el) / (kPi * (1.0f - e_avg));
    const glm::vec3 f_avg = (20.0f * specular_f0(s) + glm::vec3(1.0f)) / 21.0f;
    const glm::vec3 colour = f_avg * f_avg * e_avg / (glm::vec3(1.0f) - f_avg * (1.0f - e_avg));
    return colour * (fms * n_dot_l);
}

}  // namespace posthaste::shading
