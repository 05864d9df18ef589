#include "shading/lighting.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

#include "shading/scene_sky.h"
#include "shading/sky.h"

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
    const glm::vec3 amb = ambient * scale;
    c += diffuse_albedo(s) * amb;
    const float nv = std::max(glm::dot(n, v), 0.0f);
    const glm::vec3 r = glm::reflect(-v, n);
    const float gloss = (1.0f - s.roughness) * (1.0f - s.roughness);
    // Rough materials (gloss < 0.05, roughness > 0.78) reflect the ambient term alone: the sky
    // lookup would change them by less than 5% of a small term.
    const glm::vec3 env =
        gloss < 0.05f
            ? amb
            : glm::mix(
                  amb, sky.radiance(r, glm::vec3(0.0f, kSkyCameraY, 0.0f), false) * scale, gloss);
    c += fresnel_schlick(specular_f0(s), nv) * env;
    return c;
}

}  // namespace posthaste::shading
