// The relight method's reference: one pixel at a time, prepared here and lit through
// shading::direct_response. shade() runs the vector rows (relight_kernels.cpp, the same
// operations lane by lane, the same bits) for the options they cover, and this for the rest
// (screen-space shadows, Burley diffuse, the other masking terms) and under
// POSTHASTE_SIMD=scalar.
#include "shading/lighting/relight.h"

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <limits>

#include "core/parallel.h"
#include "core/simd.h"
#include "shading/lighting/relight_pixel.h"

namespace posthaste::shading::relight {
namespace {

bool finite3(const glm::vec3 &v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

glm::vec3 load3(const Image &img, int x, int y)
{
    const float *p = img.pixel(x, y);
    return glm::vec3(p[0], p[1], p[2]);
}

// Direction to the light, irradiance at normal incidence (color * intensity * falloff) and
// distance (infinite for a sun) at world point p; false when p is at the light.
bool light_at(const Light &light, const glm::vec3 &p, glm::vec3 &l, glm::vec3 &e, float &max_t)
{
    if (light.type == LightType::Directional) {
        l = light.direction;
        e = light.power;
        max_t = std::numeric_limits<float>::infinity();
        return true;
    }
    const glm::vec3 d = light.position - p;
    const float d2 = glm::dot(d, d);
    max_t = std::sqrt(d2);
    if (!(max_t > 0.0f)) {
        return false;
    }
    l = d * (1.0f / max_t);  // one division: an ulp more in l is far below what it feeds needs
    float falloff = 1.0f / std::max(d2, light.radius * light.radius);
    if (light.type == LightType::Spot) {
        const float cs = -glm::dot(l, light.direction);
        const float t = std::clamp(
            (cs - light.cos_outer) * (1.0f / (light.cos_inner - light.cos_outer)), 0.0f, 1.0f);
        falloff *= t * t * (3.0f - 2.0f * t);  // smoothstep
    }
    e = light.power * falloff;
    return true;
}

}  // namespace

// Stage 1 for one pixel: its surface, or pr.valid = false for background and unusable pixels.
void prepare_pixel(const Inputs &sh, int x, int y, Prepared &pr)
{
    pr.valid = false;
    // World position of the pixel's surface, or a background pixel.
    glm::vec3 p;
    if (sh.from_depth) {
        const float z = sh.depth->at(x, y, 0);
        if (!std::isfinite(z)) {
            return;
        }
        // Solve the two NDC equations u (row3 . q) = row0 . q (and v) for the camera point
        // q = (X, Y, z, 1).
        const float u = (float(x) + 0.5f) / float(sh.width);
        const float v = (float(y) + 0.5f) / float(sh.height);
        const glm::mat4 &m = sh.cam_to_ndc;
        const float a00 = m[0][0] - u * m[0][3], a01 = m[1][0] - u * m[1][3];
        const float a10 = m[0][1] - v * m[0][3], a11 = m[1][1] - v * m[1][3];
        const float b0 = -((m[2][0] - u * m[2][3]) * z + m[3][0] - u * m[3][3]);
        const float b1 = -((m[2][1] - v * m[2][3]) * z + m[3][1] - v * m[3][3]);
        const float det = a00 * a11 - a01 * a10;
        if (det == 0.0f) {
            return;
        }
        const glm::vec4 q((b0 * a11 - a01 * b1) / det, (a00 * b1 - a10 * b0) / det, z, 1.0f);
        p = glm::vec3(sh.c2w * q);
    } else {
        p = load3(*sh.position, x, y);
    }
    glm::vec3 n = load3(*sh.normal, x, y);
    const float nlen = glm::length(n);
    if (!finite3(p) || !(nlen > 0.5f) || !std::isfinite(nlen) ||
        (sh.depth && !std::isfinite(sh.depth->at(x, y, 0)))) {
        return;  // background, or no usable normal
    }
    n *= 1.0f / nlen;
    const glm::vec3 to_eye = sh.eye - p;
    const float elen = glm::length(to_eye);
    if (!(elen > 0.0f)) {
        return;
    }
    const glm::vec3 v = to_eye * (1.0f / elen);
    if (glm::dot(n, v) < 0.0f) {
        n = -n;  // seen from behind: shade the side we see (as the rasterizer)
    }
    const glm::vec3 mat = load3(*sh.material, x, y);
    shading::Surface &surf = pr.surf;
    surf = shading::Surface{};
    surf.albedo = load3(*sh.albedo, x, y);
    surf.roughness = std::isfinite(mat.x) ? std::clamp(mat.x, 0.0f, 1.0f) : 1.0f;
    surf.metallic = std::isfinite(mat.y) ? std::clamp(mat.y, 0.0f, 1.0f) : 0.0f;
    if (sh.tangent && std::isfinite(mat.z) && mat.z != 0.0f) {
        // A degenerate tangent (zero, NaN, parallel to n) shades isotropically.
        const glm::vec3 t = load3(*sh.tangent, x, y);
        const glm::vec3 tp = t - n * glm::dot(n, t);
        if (finite3(tp) && glm::dot(tp, tp) > 1e-8f) {
            surf.anisotropy = std::clamp(mat.z, -1.0f, 1.0f);
            surf.tangent = t;
        }
    }
    if (!finite3(surf.albedo)) {
        surf.albedo = glm::vec3(0.0f);
    }
    bool is_toon = false;
    if (sh.id) {
        const float m = sh.id->at(x, y, 0);
        is_toon = m >= 0.5f && m < 255.5f && sh.setup->is_toon[std::size_t(m + 0.5f)];
    }
    pr.opts = is_toon ? &sh.toon : &sh.base;
    pr.p = p;
    pr.n = n;
    pr.v = v;
    pr.valid = true;
}

// The lights' sum at a prepared pixel through direct_response (the reference path).
glm::vec3 light_sum_scalar(const Inputs &sh, const Prepared &pr, int x, int y)
{
    glm::vec3 c(0.0f);
    const std::vector<Light> &lights = sh.setup->lights;
    for (std::size_t k = 0; k < lights.size(); ++k) {
        glm::vec3 l, e;
        float max_t;
        if (!light_at(lights[k], pr.p, l, e, max_t) || glm::dot(pr.n, l) <= 0.0f) {
            continue;
        }
        if (sh.shadows && sh.ss.visibility(pr.p, pr.n, l, max_t, x, y, int(k)) == 0.0f) {
            continue;
        }
        glm::vec3 add = shading::direct_response(pr.surf, pr.n, pr.v, l, *pr.opts) * e;
        if (sh.clamp > 0.0f) {
            add = glm::min(add, glm::vec3(sh.clamp));
        }
        c += add;
    }
    return c;
}

// Ambient and the mode: the final color of a surface pixel from its lights' sum c.
glm::vec3 finish_pixel(const Inputs &sh, const Prepared &pr, glm::vec3 c, const float *in)
{
    if (sh.ambient > 0.0f) {
        c = shading::add_sky_light(c, pr.surf, pr.n, pr.v, sh.sky_sun, sh.ambient);
    }
    if (!sh.replace) {
        c += glm::vec3(in[0], in[1], in[2]);
    }
    return c;
}

namespace {

// One row of a tile through the reference.
void shade_row_reference(const Inputs &sh, int x0, int x1, int y, Image &out)
{
    const int n_px = x1 - x0, nc = sh.color->channels();
    std::copy(sh.color->pixel(x0, y), sh.color->pixel(x0, y) + n_px * nc, out.pixel(x0, y));
    for (int i = 0; i < n_px; ++i) {
        Prepared pr;
        prepare_pixel(sh, x0 + i, y, pr);
        if (!pr.valid) {
            continue;
        }
        const int x = x0 + i;
        float *dst = out.pixel(x, y);
        const glm::vec3 c = finish_pixel(sh, pr, light_sum_scalar(sh, pr, x, y), dst);
        dst[0] = c.x;
        dst[1] = c.y;
        dst[2] = c.z;
    }
}

}  // namespace

void shade(const Inputs &sh, Image &out)
{
    if (sh.kernel_ok && simd::requested() != simd::Level::Scalar) {
        shade_rows_vector(sh, out);
        return;
    }
    parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
        for (int y = tile.y0; y < tile.y1; ++y) {
            shade_row_reference(sh, tile.x0, tile.x1, y, out);
        }
    });
}

}  // namespace posthaste::shading::relight
