// The relight method's portable path (the reference): a tile row is prepared pixel by pixel,
// the common options go through a 4-wide SSE2 kernel, the rest one pixel at a time through
// shading::direct_light. shade() picks the AVX2 rows where it can (relight_avx2.cpp).
#include "shading/relight.h"

#include <algorithm>
#include <cmath>
#include <limits>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>

#include "core/parallel.h"
#include "core/simd.h"
#include "shading/relight_pixel.h"

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
    l = d / max_t;
    float falloff = 1.0f / std::max(d2, light.radius * light.radius);
    if (light.type == LightType::Spot) {
        const float cs = -glm::dot(l, light.direction);
        const float t =
            std::clamp((cs - light.cos_outer) / (light.cos_inner - light.cos_outer), 0.0f, 1.0f);
        falloff *= t * t * (3.0f - 2.0f * t);  // smoothstep
    }
    e = light.power * falloff;
    return true;
}

// A tile row in structure-of-arrays form for the 4-wide kernel; r, g, b receive the lights' sum.
struct Row {
    static constexpr int kMax = kDefaultTileSize;
    Prepared px[kMax];
    alignas(16) float x[kMax], y[kMax], z[kMax];     // position
    alignas(16) float nx[kMax], ny[kMax], nz[kMax];  // normal (facing the viewer)
    alignas(16) float vx[kMax], vy[kMax], vz[kMax];  // toward the viewer
    alignas(16) float nv[kMax];                      // raw n.v
    alignas(16) float a2[kMax], sv[kMax];            // alpha^2, sqrt(nv^2 (1 - a2) + a2)
    alignas(16) float f0r[kMax], f0g[kMax], f0b[kMax];
    alignas(16) float kdr[kMax], kdg[kMax], kdb[kMax];  // diffuse albedo / pi
    alignas(16) float r[kMax], g[kMax], b[kMax];

    Row()
    {
        for (int i = 0; i < kMax; ++i) {
            clear_lane(i);
        }
    }
    void clear_lane(int i)
    {
        x[i] = y[i] = z[i] = 0.0f;
        nx[i] = ny[i] = vx[i] = vy[i] = 0.0f;
        nz[i] = vz[i] = nv[i] = a2[i] = sv[i] = 1.0f;
        f0r[i] = f0g[i] = f0b[i] = kdr[i] = kdg[i] = kdb[i] = 0.0f;
        r[i] = g[i] = b[i] = 0.0f;
    }
    void set_lane(int i, const Prepared &pr)
    {
        x[i] = pr.p.x;
        y[i] = pr.p.y;
        z[i] = pr.p.z;
        nx[i] = pr.n.x;
        ny[i] = pr.n.y;
        nz[i] = pr.n.z;
        vx[i] = pr.v.x;
        vy[i] = pr.v.y;
        vz[i] = pr.v.z;
        nv[i] = glm::dot(pr.n, pr.v);
        // Inline forms of roughness_to_alpha, specular_f0 and diffuse_albedo (brdf.cpp).
        const float rough = std::clamp(pr.surf.roughness, shading::kMinRoughness, 1.0f);
        const float alpha = rough * rough;
        a2[i] = alpha * alpha;
        const float c = std::max(nv[i], shading::kMinCosine);
        sv[i] = std::sqrt(c * c * (1.0f - a2[i]) + a2[i]);
        const float metal = pr.surf.metallic;
        const glm::vec3 f0 = glm::mix(glm::vec3(0.04f), pr.surf.albedo, metal);
        const glm::vec3 kd = pr.surf.albedo * ((1.0f - metal) * (1.0f / shading::kPi));
        f0r[i] = f0.x;
        f0g[i] = f0.y;
        f0b[i] = f0.z;
        kdr[i] = kd.x;
        kdg[i] = kd.y;
        kdb[i] = kd.z;
    }
};

#if defined(__SSE2__)
// 1 / x and 1 / sqrt(x) from the hardware estimates plus one Newton step (relative error about
// 5e-7 instead of 0.5 ulp; the accuracy test bounds the effect on the image). Measured 28 %
// less work than divps/sqrtps. Departure from bit-portability: the estimates differ between CPU
// vendors, so outputs may differ in the last bits across machines (never across thread counts).
inline __m128 rcp_nr(__m128 x)
{
    const __m128 r = _mm_rcp_ps(x);
    return _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(2.0f), _mm_mul_ps(x, r)));
}
inline __m128 rsqrt_nr(__m128 x)
{
    const __m128 r = _mm_rsqrt_ps(x);
    const __m128 hx = _mm_mul_ps(_mm_set1_ps(0.5f), x);
    return _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(1.5f), _mm_mul_ps(hx, _mm_mul_ps(r, r))));
}

// shading::evaluate (Lambert + GGX, height-correlated Smith, Schlick), 4 lanes at once, summed
// over the lights into row.r/g/b. Same formulas as brdf.cpp; float results differ from the
// scalar path by rounding only (a few ulp).
void shade_lanes(Row &row, int count, const std::vector<Light> &lights, float clamp)
{
    const __m128 zero = _mm_setzero_ps(), one = _mm_set1_ps(1.0f), half = _mm_set1_ps(0.5f);
    const __m128 min_cos = _mm_set1_ps(shading::kMinCosine);
    const __m128 inv_pi = _mm_set1_ps(1.0f / shading::kPi);
    const __m128 clamp_v = _mm_set1_ps(clamp > 0.0f ? clamp : std::numeric_limits<float>::max());
    // Lights outside, pixel groups inside: consecutive groups are independent, so the core
    // overlaps their long sqrt/rcp chains.
    for (const Light &light : lights) {
        for (int i = 0; i < count; i += 4) {
            const __m128 px = _mm_load_ps(row.x + i), py = _mm_load_ps(row.y + i),
                         pz = _mm_load_ps(row.z + i);
            const __m128 nx = _mm_load_ps(row.nx + i), ny = _mm_load_ps(row.ny + i),
                         nz = _mm_load_ps(row.nz + i);
            const __m128 vx = _mm_load_ps(row.vx + i), vy = _mm_load_ps(row.vy + i),
                         vz = _mm_load_ps(row.vz + i);
            const __m128 nv_raw = _mm_load_ps(row.nv + i);
            const __m128 nv = _mm_max_ps(nv_raw, min_cos);
            const __m128 a2 = _mm_load_ps(row.a2 + i), sv = _mm_load_ps(row.sv + i);
            const __m128 one_minus_a2 = _mm_sub_ps(one, a2);
            const __m128 f0r = _mm_load_ps(row.f0r + i), f0g = _mm_load_ps(row.f0g + i),
                         f0b = _mm_load_ps(row.f0b + i);
            const __m128 kdr = _mm_load_ps(row.kdr + i), kdg = _mm_load_ps(row.kdg + i),
                         kdb = _mm_load_ps(row.kdb + i);
            __m128 ar = _mm_load_ps(row.r + i), ag = _mm_load_ps(row.g + i),
                   ab = _mm_load_ps(row.b + i);
            {
                __m128 lx, ly, lz, er, eg, eb;
                if (light.type == LightType::Directional) {
                    lx = _mm_set1_ps(light.direction.x);
                    ly = _mm_set1_ps(light.direction.y);
                    lz = _mm_set1_ps(light.direction.z);
                    er = _mm_set1_ps(light.power.x);
                    eg = _mm_set1_ps(light.power.y);
                    eb = _mm_set1_ps(light.power.z);
                } else {
                    const __m128 dx = _mm_sub_ps(_mm_set1_ps(light.position.x), px);
                    const __m128 dy = _mm_sub_ps(_mm_set1_ps(light.position.y), py);
                    const __m128 dz = _mm_sub_ps(_mm_set1_ps(light.position.z), pz);
                    const __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
                                                 _mm_mul_ps(dz, dz));
                    // At the light (d2 = 0) the lane gets l = 0, so n.l = 0 and no light.
                    const __m128 inv = _mm_and_ps(_mm_cmpgt_ps(d2, zero), rsqrt_nr(d2));
                    lx = _mm_mul_ps(dx, inv);
                    ly = _mm_mul_ps(dy, inv);
                    lz = _mm_mul_ps(dz, inv);
                    __m128 falloff =
                        rcp_nr(_mm_max_ps(d2, _mm_set1_ps(light.radius * light.radius)));
                    if (light.type == LightType::Spot) {
                        const __m128 cs = _mm_sub_ps(
                            zero,
                            _mm_add_ps(_mm_add_ps(_mm_mul_ps(lx, _mm_set1_ps(light.direction.x)),
                                                  _mm_mul_ps(ly, _mm_set1_ps(light.direction.y))),
                                       _mm_mul_ps(lz, _mm_set1_ps(light.direction.z))));
                        __m128 t =
                            _mm_mul_ps(_mm_sub_ps(cs, _mm_set1_ps(light.cos_outer)),
                                       _mm_set1_ps(1.0f / (light.cos_inner - light.cos_outer)));
                        t = _mm_min_ps(_mm_max_ps(t, zero), one);
                        falloff =
                            _mm_mul_ps(falloff,
                                       _mm_mul_ps(_mm_mul_ps(t, t),
                                                  _mm_sub_ps(_mm_set1_ps(3.0f), _mm_add_ps(t, t))));
                    }
                    er = _mm_mul_ps(_mm_set1_ps(light.power.x), falloff);
                    eg = _mm_mul_ps(_mm_set1_ps(light.power.y), falloff);
                    eb = _mm_mul_ps(_mm_set1_ps(light.power.z), falloff);
                }
                const __m128 nl = _mm_add_ps(_mm_add_ps(_mm_mul_ps(nx, lx), _mm_mul_ps(ny, ly)),
                                             _mm_mul_ps(nz, lz));
                const __m128 lit = _mm_cmpgt_ps(nl, zero);
                if (_mm_movemask_ps(lit) == 0) {
                    continue;
                }
                // h = (v + l) / |v + l|; n.h and v.h from dot products.
                const __m128 hx = _mm_add_ps(vx, lx), hy = _mm_add_ps(vy, ly),
                             hz = _mm_add_ps(vz, lz);
                const __m128 hlen2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(hx, hx), _mm_mul_ps(hy, hy)),
                                                _mm_mul_ps(hz, hz));
                const __m128 hok = _mm_cmpgt_ps(hlen2, _mm_set1_ps(1e-16f));
                const __m128 inv_h =
                    rsqrt_nr(_mm_or_ps(_mm_and_ps(hok, hlen2), _mm_andnot_ps(hok, one)));
                // Degenerate h (v = -l) falls back to h = n, as evaluate(): n.h = 1, v.h = n.v.
                const __m128 nh =
                    _mm_max_ps(_mm_or_ps(_mm_and_ps(hok, _mm_mul_ps(_mm_add_ps(nv_raw, nl), inv_h)),
                                         _mm_andnot_ps(hok, one)),
                               zero);
                const __m128 vl = _mm_add_ps(_mm_add_ps(_mm_mul_ps(vx, lx), _mm_mul_ps(vy, ly)),
                                             _mm_mul_ps(vz, lz));
                const __m128 vh =
                    _mm_max_ps(_mm_or_ps(_mm_and_ps(hok, _mm_mul_ps(_mm_add_ps(one, vl), inv_h)),
                                         _mm_andnot_ps(hok, nv_raw)),
                               zero);
                // D = a2 / (pi d^2), d = (n.h)^2 (a2 - 1) + 1.
                const __m128 dd =
                    _mm_add_ps(_mm_mul_ps(_mm_mul_ps(nh, nh), _mm_sub_ps(a2, one)), one);
                const __m128 d = _mm_mul_ps(_mm_mul_ps(a2, inv_pi), rcp_nr(_mm_mul_ps(dd, dd)));
                // V = 0.5 / (n.l sv + n.v sqrt(n.l^2 (1 - a2) + a2)), cosines clamped.
                const __m128 nlc = _mm_max_ps(nl, min_cos);
                const __m128 sl2 = _mm_add_ps(_mm_mul_ps(_mm_mul_ps(nlc, nlc), one_minus_a2), a2);
                const __m128 sl = _mm_mul_ps(sl2, rsqrt_nr(sl2));  // sl2 >= a2 > 0
                const __m128 vis =
                    _mm_mul_ps(half, rcp_nr(_mm_add_ps(_mm_mul_ps(nlc, sv), _mm_mul_ps(nv, sl))));
                const __m128 dv = _mm_mul_ps(d, vis);
                // Schlick: F = f0 + (1 - f0) m^5, m = 1 - clamp(v.h, 0, 1).
                const __m128 m = _mm_sub_ps(one, _mm_min_ps(vh, one));
                const __m128 m2 = _mm_mul_ps(m, m);
                const __m128 m5 = _mm_mul_ps(_mm_mul_ps(m2, m2), m);
                auto channel = [&](__m128 f0, __m128 kd, __m128 e) {
                    const __m128 f = _mm_add_ps(f0, _mm_mul_ps(_mm_sub_ps(one, f0), m5));
                    const __m128 c =
                        _mm_mul_ps(_mm_mul_ps(_mm_add_ps(kd, _mm_mul_ps(f, dv)), nl), e);
                    return _mm_and_ps(lit, _mm_min_ps(c, clamp_v));
                };
                ar = _mm_add_ps(ar, channel(f0r, kdr, er));
                ag = _mm_add_ps(ag, channel(f0g, kdg, eg));
                ab = _mm_add_ps(ab, channel(f0b, kdb, eb));
            }
            _mm_store_ps(row.r + i, ar);
            _mm_store_ps(row.g + i, ag);
            _mm_store_ps(row.b + i, ab);
        }
    }
}
#else
// No SSE2: every pixel takes the scalar path.
void shade_lanes(Row &row, int count, const std::vector<Light> &, float)
{
    for (int i = 0; i < count; ++i) {
        row.px[i].fast = false;
    }
}
#endif

}  // namespace

// Stage 1 for one pixel: its surface, or pr.valid = false for background and unusable pixels.
void prepare_pixel(const Inputs &sh, int x, int y, Prepared &pr)
{
    pr.valid = false;
    pr.fast = false;
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
    pr.fast = sh.fast_ok && !is_toon && surf.anisotropy == 0.0f;
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

// One row of a tile without AVX2: scalar setup, the 4-wide SSE2 kernel for the common case,
// scalar direct_response for the rest.
void shade_row_portable(const Inputs &sh, int x0, int x1, int y, Row &row, Image &out)
{
    const int n_px = x1 - x0, nc = sh.color->channels();
    std::copy(sh.color->pixel(x0, y), sh.color->pixel(x0, y) + n_px * nc, out.pixel(x0, y));
    for (int i = 0; i < n_px; ++i) {
        Prepared &pr = row.px[i];
        row.clear_lane(i);
        prepare_pixel(sh, x0 + i, y, pr);
        if (pr.fast) {
            row.set_lane(i, pr);
        }
    }
    if (sh.fast_ok) {
        shade_lanes(row, n_px, sh.setup->lights, sh.clamp);
    }
    for (int i = 0; i < n_px; ++i) {
        const Prepared &pr = row.px[i];
        if (!pr.valid) {
            continue;
        }
        const int x = x0 + i;
        const glm::vec3 lit =
            pr.fast ? glm::vec3(row.r[i], row.g[i], row.b[i]) : light_sum_scalar(sh, pr, x, y);
        float *dst = out.pixel(x, y);
        const glm::vec3 c = finish_pixel(sh, pr, lit, dst);
        dst[0] = c.x;
        dst[1] = c.y;
        dst[2] = c.z;
    }
}

}  // namespace

void shade(const Inputs &sh, Image &out)
{
    bool use_avx2 = false;
#if POSTHASTE_HAVE_AVX2_TARGET
    use_avx2 = simd::avx2() && sh.avx2_ok;
#endif
    if (use_avx2) {
#if POSTHASTE_HAVE_AVX2_TARGET
        shade_rows_avx2(sh, out);
#endif
        return;
    }
    parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
        Row row;
        for (int y = tile.y0; y < tile.y1; ++y) {
            shade_row_portable(sh, tile.x0, tile.x1, y, row, out);
        }
    });
}

}  // namespace posthaste::shading::relight
