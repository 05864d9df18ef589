#include "shading/lighting/lighting.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"

namespace posthaste::shading {

glm::vec3 direct_response(const Surface &s,
                          const glm::vec3 &n,
                          const glm::vec3 &v,
                          const glm::vec3 &l,
                          const DirectOptions &o)
{
    const float nl = glm::dot(n, l);
    if (nl <= 0.0f) {
        return glm::vec3(0.0f);
    }
    if (o.toon_bands > 0) {
        // Exactly the rasterizer's toon expression when toon_specular_steps is 0.
        Surface spec = s;
        spec.albedo = glm::vec3(0.0f);
        spec.metallic = 0.0f;
        glm::vec3 specular = evaluate(spec, n, v, l, o.geometry);
        if (o.toon_specular_steps > 0) {
            const glm::vec3 h = glm::normalize(v + l);
            const float alpha = roughness_to_alpha(s.roughness);
            const float t = d_ggx(glm::dot(n, h), alpha) / d_ggx(1.0f, alpha);
            const float steps = float(o.toon_specular_steps);
            const float q = std::floor(t * steps + 0.5f) / steps;
            specular = t > 0.0f ? specular * (q / t) : glm::vec3(0.0f);
        }
        return diffuse_albedo(s) / kPi * toon_band(nl, o.toon_bands) + specular;
    }
    if (!o.burley && !o.energy_compensation) {
        return evaluate(s, n, v, l, o.geometry);
    }
    Surface spec = s;
    glm::vec3 diffuse(0.0f);
    if (o.burley) {
        spec.albedo = specular_f0(s);  // metallic 1 with albedo F0: the same specular, no diffuse
        spec.metallic = 1.0f;
        const glm::vec3 h = glm::normalize(v + l);
        diffuse = burley(diffuse_albedo(s), s.roughness, glm::dot(n, v), nl, glm::dot(l, h)) * nl;
    }
    glm::vec3 c = evaluate(spec, n, v, l, o.geometry) + diffuse;
    if (o.energy_compensation) {
        c += multiscatter(s, glm::dot(n, v), nl, o.geometry);
    }
    return c;
}

glm::vec3 add_sky_light(glm::vec3 c,
                        const Surface &s,
                        const glm::vec3 &n,
                        const glm::vec3 &v,
                        const glm::vec3 &sun_dir,
                        float scale)
{
    const SceneSky &sky = scene_sky(sun_dir);
    return add_sky_light(c, s, n, v, sky, sky.ambient(n), scale);
}

glm::vec3 add_sky_light(glm::vec3 c,
                        const Surface &s,
                        const glm::vec3 &n,
                        const glm::vec3 &v,
                        const SceneSky &sky,
                        const glm::vec3 &ambient,
                        float scale)
{
    return add_sky_light_from(c, s, n, v, ambient, scale, [&](const glm::vec3 &r) {
        return sky.radiance(r, glm::vec3(0.0f, kSkyCameraY, 0.0f), false);
    });
}

glm::vec3 sky_reflection_weight(const Surface &s, const glm::vec3 &n, const glm::vec3 &v)
{
    const float gloss = (1.0f - s.roughness) * (1.0f - s.roughness);
    if (gloss < 0.05f) {
        return glm::vec3(0.0f);  // add_sky_light's rough branch: no sky lookup
    }
    const float nv = std::max(glm::dot(n, v), 0.0f);
    return fresnel_schlick(specular_f0(s), nv) * gloss;
}

glm::vec3 sample_cosine_hemisphere(const glm::vec3 &n, float u1, float u2)
{
    // An orthonormal basis around n (Duff et al. 2017).
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z), b = n.x * n.y * a;
    const glm::vec3 t1(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    const glm::vec3 t2(b, sign + n.y * n.y * a, -n.y);
    const float r = std::sqrt(u1), phi = 6.28318530718f * u2;
    return glm::normalize(t1 * (r * std::cos(phi)) + t2 * (r * std::sin(phi)) +
                          n * std::sqrt(std::max(0.0f, 1.0f - u1)));
}

glm::vec3 sample_ggx_reflection(
    const glm::vec3 &n, const glm::vec3 &v, float alpha, float u1, float u2)
{
    // tan^2(theta_h) = alpha^2 u1 / (1 - u1) inverts the CDF of D(h) (n.h).
    const float a2 = alpha * alpha;
    const float cos2 = (1.0f - u1) / (1.0f + (a2 - 1.0f) * u1);
    const float cos_t = std::sqrt(std::clamp(cos2, 0.0f, 1.0f));
    const float sin_t = std::sqrt(std::max(0.0f, 1.0f - cos_t * cos_t));
    const float phi = 2.0f * kPi * u2;
    // An orthonormal basis around n (Duff et al. 2017).
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z), b = n.x * n.y * a;
    const glm::vec3 t1(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    const glm::vec3 t2(b, sign + n.y * n.y * a, -n.y);
    const glm::vec3 h = t1 * (sin_t * std::cos(phi)) + t2 * (sin_t * std::sin(phi)) + n * cos_t;
    return glm::normalize(2.0f * glm::dot(v, h) * h - v);
}

}  // namespace posthaste::shading
