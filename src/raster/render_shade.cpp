// The rasterizer's colour: each visible surface shaded with the shared BRDF and sky
// (shading/lighting/lighting.h) with the sun's shadow: shade() per pixel, the vector lanes in
// render_shade_kernels.cpp.
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

float sun_visibility(const Lighting &lt, const glm::vec3 &p, const glm::vec3 &n)
{
    float vis = glm::dot(n, lt.scene->sun.direction) > 0.0f ? 1.0f : 0.0f;
    if (vis > 0.0f && lt.static_map) {
        vis *= shadow_lookup(*lt.static_map, p, n);
    }
    if (vis > 0.0f && lt.dynamic_map) {
        vis *= shadow_lookup(*lt.dynamic_map, p, n);
    }
    return vis;
}

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
    const float vis = sun_visibility(lt, h.p, n);
    const glm::vec3 e_sun = s.sun.color * s.sun.illuminance * vis;
    glm::vec3 c(0.0f);
    if (vis > 0.0f) {
        // Toon materials: n.l quantised to thirds, plus the specular lobe (shading/lighting/lighting.h).
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
