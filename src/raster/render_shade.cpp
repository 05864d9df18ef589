// The rasterizer's colour: each visible surface shaded with the shared BRDF and sky
// (shading/lighting.h), eight lanes at a time with AVX2, with the sun's shadow.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>

#include "core/parallel.h"
#include "core/timing.h"
#include "raster/color_row.h"
#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {

glm::vec3 shade(
    const Lighting &lt, const Hit &h, const glm::vec3 &view_dir, SkyCache &sky, glm::vec3 *specular)
{
    const Scene &s = *lt.scene;
    const Material &mat = lt.materials->m[h.material];
    const glm::vec3 v = -view_dir;
    glm::vec3 n = h.n;
    if (glm::dot(n, v) < 0.0f) {
        n = -n;  // seen from behind (near-plane cuts): shade the side we see
    }
    shading::Surface surf;
    surf.albedo = mat.albedo;
    surf.roughness = mat.roughness;
    surf.metallic = mat.metallic;
    surf.anisotropy = mat.anisotropy;
    surf.tangent = h.t;
    const glm::vec3 l = s.sun.direction;
    float vis = glm::dot(n, l) > 0.0f ? 1.0f : 0.0f;
    if (vis > 0.0f && lt.static_map) {
        vis *= shadow_lookup(*lt.static_map, h.p, n);
    }
    if (vis > 0.0f && lt.dynamic_map) {
        vis *= shadow_lookup(*lt.dynamic_map, h.p, n);
    }
    const glm::vec3 e_sun = s.sun.color * s.sun.illuminance * vis;
    glm::vec3 c(0.0f);
    if (vis > 0.0f) {
        // Toon materials: n.l quantised to thirds, plus the specular lobe (shading/lighting.h).
        shading::DirectOptions direct;
        direct.toon_bands = mat.toon ? 3 : 0;
        c = shading::direct_response(surf, n, v, l, direct) * e_sun;
    }
    const glm::vec3 &ambient = sky.ambient(n);
    const glm::vec3 out = shading::add_sky_light(c, surf, n, v, *sky.sky, ambient, s.sky_ambient);
    if (specular) {
        const glm::vec3 kd = shading::diffuse_albedo(surf);
        const float nl = glm::dot(n, l);
        glm::vec3 diffuse = kd * (ambient * s.sky_ambient);
        if (vis > 0.0f && nl > 0.0f) {
            diffuse += kd / shading::kPi * (mat.toon ? shading::toon_band(nl, 3) : nl) * e_sun;
        }
        *specular = out - diffuse;
    }
    return out;
}

#if POSTHASTE_HAVE_AVX2_TARGET
POSTHASTE_AVX2_INLINE v8::V dot3(v8::V ax, v8::V ay, v8::V az, v8::V bx, v8::V by, v8::V bz)
{
    return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(ax, bx), _mm256_mul_ps(ay, by)),
                         _mm256_mul_ps(az, bz));
}

// The expressions of shading::evaluate (isotropic, height-correlated Smith) and
// shading::add_sky_light, eight lanes at a time, for lanes [0, count) (arrays padded to 8).
POSTHASTE_AVX2 void shade_lanes_avx2(SurfaceLanes &s, int count, const KernelLight &kl)
{
    using v8::set1;
    using v8::V;
    const V zero = _mm256_setzero_ps(), one = set1(1.0f);
    const V lx = set1(kl.l.x), ly = set1(kl.l.y), lz = set1(kl.l.z);
    const V inv_pi = set1(1.0f / shading::kPi), pi = set1(shading::kPi);
    const V min_cos = set1(shading::kMinCosine), f0d = set1(0.04f), scale = set1(kl.scale);
    const V sun[3] = {set1(kl.sun_rgb.x), set1(kl.sun_rgb.y), set1(kl.sun_rgb.z)};
    for (int i = 0; i < count; i += 8) {
        const V nx = _mm256_loadu_ps(&s.nx[i]), ny = _mm256_loadu_ps(&s.ny[i]),
                nz = _mm256_loadu_ps(&s.nz[i]);
        const V vx = _mm256_loadu_ps(&s.vx[i]), vy = _mm256_loadu_ps(&s.vy[i]),
                vz = _mm256_loadu_ps(&s.vz[i]);
        const V rough = _mm256_loadu_ps(&s.rough[i]), metal = _mm256_loadu_ps(&s.metal[i]);
        const V vis = _mm256_loadu_ps(&s.vis[i]);
        const V alb[3] = {
            _mm256_loadu_ps(&s.ar[i]), _mm256_loadu_ps(&s.ag[i]), _mm256_loadu_ps(&s.ab[i])};

        const V nl = dot3(nx, ny, nz, lx, ly, lz);
        const V nv_raw = dot3(nx, ny, nz, vx, vy, vz);
        const V nv = _mm256_max_ps(nv_raw, min_cos);
        V hx = _mm256_add_ps(vx, lx), hy = _mm256_add_ps(vy, ly), hz = _mm256_add_ps(vz, lz);
        const V hlen = _mm256_sqrt_ps(dot3(hx, hy, hz, hx, hy, hz));
        const V hok = _mm256_cmp_ps(hlen, set1(1e-8f), _CMP_GT_OQ);
        hx = _mm256_blendv_ps(nx, _mm256_div_ps(hx, hlen), hok);
        hy = _mm256_blendv_ps(ny, _mm256_div_ps(hy, hlen), hok);
        hz = _mm256_blendv_ps(nz, _mm256_div_ps(hz, hlen), hok);
        const V nh = _mm256_max_ps(dot3(nx, ny, nz, hx, hy, hz), zero);
        const V vh = _mm256_max_ps(dot3(vx, vy, vz, hx, hy, hz), zero);
        const V r = v8::clamp(rough, set1(shading::kMinRoughness), one);
        const V alpha = _mm256_mul_ps(r, r);
        const V a2 = _mm256_mul_ps(alpha, alpha);
        // D (zero for n.h <= 0) times the correlated Smith V.
        const V d =
            _mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nh, nh), _mm256_sub_ps(a2, one)), one);
        V dggx = _mm256_div_ps(a2, _mm256_mul_ps(_mm256_mul_ps(pi, d), d));
        dggx = _mm256_and_ps(dggx, _mm256_cmp_ps(nh, zero, _CMP_GT_OQ));
        const V nlc = _mm256_max_ps(nl, min_cos);
        const V one_a2 = _mm256_sub_ps(one, a2);
        const V gv = _mm256_mul_ps(
            nlc, _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nv, nv), one_a2), a2)));
        const V gl = _mm256_mul_ps(
            nv, _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(_mm256_mul_ps(nlc, nlc), one_a2), a2)));
        const V dv = _mm256_mul_ps(dggx, _mm256_div_ps(set1(0.5f), _mm256_add_ps(gv, gl)));
        // Schlick at v.h (direct) and at n.v (sky).
        const V mh = _mm256_sub_ps(one, v8::clamp(vh, zero, one));
        const V mh5 =
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(mh, mh), _mm256_mul_ps(mh, mh)), mh);
        const V nv2 = _mm256_max_ps(nv_raw, zero);
        const V mv = _mm256_sub_ps(one, v8::clamp(nv2, zero, one));
        const V mv5 =
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(mv, mv), _mm256_mul_ps(mv, mv)), mv);
        const V lit = _mm256_cmp_ps(vis, zero, _CMP_GT_OQ);  // vis > 0 implies n.l > 0
        const V gloss = _mm256_mul_ps(_mm256_sub_ps(one, rough), _mm256_sub_ps(one, rough));
        const V glossy = _mm256_cmp_ps(gloss, set1(0.05f), _CMP_GE_OQ);
        const V one_metal = _mm256_sub_ps(one, metal);
        const V amb_in[3] = {_mm256_loadu_ps(&s.amb_r[i]),
                             _mm256_loadu_ps(&s.amb_g[i]),
                             _mm256_loadu_ps(&s.amb_b[i])};
        const V env_in[3] = {_mm256_loadu_ps(&s.env_r[i]),
                             _mm256_loadu_ps(&s.env_g[i]),
                             _mm256_loadu_ps(&s.env_b[i])};
        float *out[3] = {&s.out_r[i], &s.out_g[i], &s.out_b[i]};
        float *dif[3] = {&s.dif_r[i], &s.dif_g[i], &s.dif_b[i]};
        for (int c = 0; c < 3; ++c) {
            const V f0 = _mm256_add_ps(_mm256_mul_ps(f0d, one_metal), _mm256_mul_ps(alb[c], metal));
            const V one_f0 = _mm256_sub_ps(one, f0);
            const V diffuse = _mm256_mul_ps(alb[c], one_metal);
            const V f = _mm256_add_ps(f0, _mm256_mul_ps(one_f0, mh5));
            const V direct = _mm256_mul_ps(
                _mm256_add_ps(_mm256_mul_ps(diffuse, inv_pi), _mm256_mul_ps(f, dv)), nl);
            V col = _mm256_and_ps(_mm256_mul_ps(direct, _mm256_mul_ps(sun[c], vis)), lit);
            const V amb = _mm256_mul_ps(amb_in[c], scale);
            const V dif_amb = _mm256_mul_ps(diffuse, amb);
            col = _mm256_add_ps(col, dif_amb);
            const V dif_sun =
                _mm256_and_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(diffuse, inv_pi), nl),
                                            _mm256_mul_ps(sun[c], vis)),
                              lit);
            _mm256_storeu_ps(dif[c], _mm256_add_ps(dif_sun, dif_amb));
            const V env_mix = _mm256_add_ps(_mm256_mul_ps(amb, _mm256_sub_ps(one, gloss)),
                                            _mm256_mul_ps(_mm256_mul_ps(env_in[c], scale), gloss));
            const V env = _mm256_blendv_ps(amb, env_mix, glossy);
            const V fs = _mm256_add_ps(f0, _mm256_mul_ps(one_f0, mv5));
            col = _mm256_add_ps(col, _mm256_mul_ps(fs, env));
            _mm256_storeu_ps(out[c], col);
        }
    }
}
#endif

// Beauty of one view into `out` (RGBA), averaging ss x ss samples per pixel when vis is ss times
// the output size.
void shade_color(const Geometry &g,
                 const View &v,
                 const Visibility &vis,
                 const Lighting &lt,
                 int ss,
                 Image &out,
                 Image *specular)
{
    parallel_for_tiles(out.bounds(), [&](const Rect &tile) {
        SurfaceHitter hitter(g, v.origin);
        SkyCache sky(*lt.scene);
        const int x0 = tile.x0 * ss, x1 = tile.x1 * ss;
        ColorRow row(lt, sky, x1 - x0, specular != nullptr);
        std::vector<glm::vec3> sum(std::size_t(tile.x1 - tile.x0));
        std::vector<glm::vec3> spec_sum(specular ? sum.size() : 0);
        for (int y = tile.y0; y < tile.y1; ++y) {
            std::fill(sum.begin(), sum.end(), glm::vec3(0.0f));
            std::fill(spec_sum.begin(), spec_sum.end(), glm::vec3(0.0f));
            for (int sy = 0; sy < ss; ++sy) {
                const int Y = y * ss + sy;
                const std::uint32_t *ids = &vis.ids[std::size_t(Y) * std::size_t(vis.width)];
                for (int X = x0; X < x1; ++X) {
                    const std::uint32_t id = ids[X];
                    const glm::vec3 d = v.ray_dir(float(X) + 0.5f, float(Y) + 0.5f);
                    const glm::vec3 dn = glm::normalize(d);
                    if (id == kNoTriangle) {
                        row.add_sky(X - x0, dn);
                    } else {
                        row.add_surface(X - x0, hitter.hit(id, d), dn);
                    }
                }
                // Per pixel the samples add up in the order (sy, sx), as one loop per pixel.
                const std::vector<glm::vec3> &c = row.finish();
                for (std::size_t i = 0; i < sum.size(); ++i) {
                    for (int sx = 0; sx < ss; ++sx) {
                        sum[i] += c[i * std::size_t(ss) + std::size_t(sx)];
                    }
                }
                for (std::size_t i = 0; i < spec_sum.size(); ++i) {
                    for (int sx = 0; sx < ss; ++sx) {
                        spec_sum[i] += row.specular()[i * std::size_t(ss) + std::size_t(sx)];
                    }
                }
            }
            for (int x = tile.x0; x < tile.x1; ++x) {
                const glm::vec3 c = sum[std::size_t(x - tile.x0)] / float(ss * ss);
                float *px = out.pixel(x, y);
                px[0] = c.x;
                px[1] = c.y;
                px[2] = c.z;
                px[3] = 1.0f;
                if (specular) {
                    const glm::vec3 sp = spec_sum[std::size_t(x - tile.x0)] / float(ss * ss);
                    float *q = specular->pixel(x, y);
                    q[0] = sp.x;
                    q[1] = sp.y;
                    q[2] = sp.z;
                }
            }
        }
    });
}

// Render the beauty of the scene at time t through `lens` into out (RGBA, options size).
void render_color(const Scene &s,
                  SceneCache &cache,
                  double t,
                  glm::vec2 lens,
                  const CameraState &cam,
                  const RenderOptions &o,
                  Image &out,
                  RenderStats *stats)
{
    const auto meshes = scene_meshes(s, cache, o.greedy_meshing);
    const Geometry g = make_geometry(s, *meshes, t, t - 1.0);
    const LightingState ls(s, cache, g, o, stats);
    const View v =
        make_view(cam, o.width * o.supersample, o.height * o.supersample, s.near_clip, lens);
    const Visibility vis = visibility(g, v, stats);
    auto t0 = Clock::now();
    shade_color(g, v, vis, ls.lighting, o.supersample, out);
    if (stats) {
        stats->shade_ms += ms_since(t0);
    }
}

}  // namespace posthaste::raster::render_detail
