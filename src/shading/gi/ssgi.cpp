#include "shading/gi/ssgi.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "core/sanitize.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/fast_math.h"
#include "shading/gi/ssgi_detail.h"
#include "shading/lighting/lighting.h"
#include "shading/ssr/environment.h"

namespace posthaste::shading {
namespace {

using gi_detail::Reshade;
using gi_detail::Shade;

/// Directions a probe is seen in over the arc a march leaves open (sub-arcs of equal angle):
/// on the default scene at 960x540, 1, 2, 3 and 4 gave 0.0188, 0.0162, 0.0159 and 0.0158 RMSE.
constexpr int kOpenSamples = 3;

/// The largest radiance magnitude the gather reads (see block_radiance).
constexpr float kMaxRadiance = 1e30f;

/// A 4x4 interleaved pattern: 16 values in [0, 1) spread over every 4x4 block of computed
/// pixels, so a 5x5 denoise averages every rotation.
float pattern(int x, int y, int k)
{
    static constexpr int kBayer[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};
    return (float(kBayer[((y & 3) << 2) | (x & 3)] ^ (k * 5 & 15)) + 0.5f) / 16.0f;
}

/// A slice's projected normal at signed angle g from the view vector.
struct Arc {
    float g, sin_g, cos_g;
    // The cosine-weighted measure of the slice arc from the view vector (angle 0) to signed
    // angle h is GTAO's inner integral, one side: (-cos(2h - g) + cos g + 2h sin g) / 4.

    /// At a tangent of the hemisphere, h = g +- pi / 2, where cos(2h - g) = -cos g.
    float tangent(float h) const { return 0.5f * (cos_g + h * sin_g); }
    /// For the angle h of the in-slice vector (c, s) = |.| (cos h, sin h), without a cosine:
    /// cos(2h - g) from the double-angle terms.
    float measure(float h, float c, float s) const
    {
        const float r2 = c * c + s * s;
        const float cos_2h_g = ((c * c - s * s) * cos_g + 2.0f * c * s * sin_g) / r2;
        return 0.25f * (-cos_2h_g + cos_g + 2.0f * h * sin_g);
    }
};

/// The radiance image reduced to the computed pixels' blocks (stride x stride box means, RGB),
/// non-finite values read as 0: what a sample sees is the mean of the pixels it stands for.
/// Each block's sums run over its rows, then its pixels, in order; a band of blocks is read a
/// row at a time.
Image block_radiance(const Image &radiance, int st)
{
    const int w = radiance.width(), h = radiance.height(), nc = radiance.channels();
    const int ow = (w + st - 1) / st, oh = (h + st - 1) / st;
    Image out(ow, oh, 3);
    const auto finite = [](float v) {
        std::uint32_t u;
        std::memcpy(&u, &v, sizeof(u));
        return (u & 0x7f800000u) != 0x7f800000u ? v : 0.0f;
    };
    // The channel count known at compile time where it usually is (4 or 3).
    const auto band = [&]<int kNc>(int by) {
        const int n = kNc > 0 ? kNc : nc, used = std::min(n, 3);
        std::vector<float> sum(std::size_t(ow) * 3, 0.0f);
        const int y0 = by * st, y1 = std::min(h, by * st + st);
        for (int y = y0; y < y1; ++y) {
            const float *row = radiance.pixel(0, y);
            for (int bx = 0; bx < ow; ++bx) {
                float *s = &sum[std::size_t(bx) * 3];
                for (int x = bx * st; x < std::min(w, bx * st + st); ++x) {
                    for (int c = 0; c < used; ++c) {
                        s[c] += finite(row[std::size_t(x) * std::size_t(n) + std::size_t(c)]);
                    }
                }
            }
        }
        for (int bx = 0; bx < ow; ++bx) {
            const float count = float((y1 - y0) * (std::min(w, bx * st + st) - bx * st));
            const float *s = &sum[std::size_t(bx) * 3];
            float *o = out.pixel(bx, by);
            for (int c = 0; c < 3; ++c) {
                // At most 1e30 in magnitude (a block of values near float's top sums past it;
                // the gather and the denoise sum a few hundred weighted radiances at most).
                const float v = (n == 1 ? s[0] : s[c]) / count;
                o[c] = v > kMaxRadiance ? kMaxRadiance : v < -kMaxRadiance ? -kMaxRadiance : v;
            }
        }
    };
    parallel_for(0, oh, [&](int by) {
        if (nc == 4) {
            band.template operator()<4>(by);
        } else if (nc == 3) {
            band.template operator()<3>(by);
        } else {
            band.template operator()<0>(by);
        }
    });
    return out;
}

glm::vec3 normal_at(const Image &normal, int x, int y, const glm::vec3 &view)
{
    const glm::vec3 n(finite_or_zero(normal.at(x, y, 0)),
                      finite_or_zero(normal.at(x, y, 1)),
                      finite_or_zero(normal.at(x, y, 2)));
    const float len2 = glm::dot(n, n);
    if (!(len2 > 1e-12f) || !std::isfinite(len2)) {
        return view;
    }
    const glm::vec3 u = n / std::sqrt(len2);
    return glm::dot(u, view) < 0.0f ? -u : u;  // the side the camera sees
}

/// The probe's surfaces, box-filtered into a small latitude-longitude map: radiance where the
/// probe sees a surface, 0 where it sees the sky. A bounce integrates light over wide arcs, so
/// a coarse map loses little, and it stays in cache (the march's look-ups are scattered).
Image surface_map(const SsgiEnvironment &env, int mw, int mh)
{
    const Image &r = *env.radiance, &d = *env.distance;
    const int w = r.width(), h = r.height(), nc = r.channels();
    Image out(mw, mh, 3);
    parallel_for(0, mh, [&](int my) {
        const int y0 = my * h / mh, y1 = std::max(y0 + 1, (my + 1) * h / mh);
        for (int mx = 0; mx < mw; ++mx) {
            const int x0 = mx * w / mw, x1 = std::max(x0 + 1, (mx + 1) * w / mw);
            glm::vec3 sum(0.0f);
            for (int y = y0; y < y1; ++y) {
                for (int x = x0; x < x1; ++x) {
                    if (!std::isfinite(
                            d.at(std::min(x, d.width() - 1), std::min(y, d.height() - 1), 0))) {
                        continue;  // the sky
                    }
                    const float *px = r.pixel(x, y);
                    sum += nc >= 3 ? glm::vec3(px[0], px[1], px[2]) : glm::vec3(px[0]);
                }
            }
            sum /= float((x1 - x0) * (y1 - y0));
            float *o = out.pixel(mx, my);
            o[0] = sum.x;
            o[1] = sum.y;
            o[2] = sum.z;
        }
    });
    return out;
}

/// The probe's surfaces on a cube (LatLongCube): a look-up is a division, not an arctangent and
/// an arccosine.
using SurfaceCube = LatLongCube<glm::vec3>;

/// The sky's radiance as add_sky_light looks it up (SceneSky::radiance from the sky camera, no
/// sun disc) on a cube of 64 x 64 texels a face (1.4 degrees), made once per sky: the
/// re-shading looks it up for the computed pixels and for every sample of a glossy surface, and
/// the sky's own look-up (square roots, an arccosine, a bilinear fetch and, below the horizon,
/// three exponentials) was a sixteenth of the node's time.
using SkyCube = LatLongCube<glm::vec3>;
const SkyCube &sky_cube(const SceneSky &sky)
{
    static std::mutex mutex;
    static std::vector<std::pair<const SceneSky *, std::unique_ptr<SkyCube>>> cubes;
    std::lock_guard lock(mutex);
    for (const auto &[key, cube] : cubes) {
        if (key == &sky) {
            return *cube;
        }
    }
    auto cube = std::make_unique<SkyCube>(SkyCube::from_directions(64, [&](const glm::vec3 &d) {
        return sky.radiance(d, glm::vec3(0.0f, kSkyCameraY, 0.0f), false);
    }));
    cubes.emplace_back(&sky, std::move(cube));
    return *cubes.back().second;
}

/// The view-dependent shading of a surface toward v: the sun's response (with the lobe's
/// roughness) and the sky light, as render and ssr shade it (add_sky_light, the sky looked up
/// on the cube). Without `sun_specular`, the sun's diffuse response alone (a glossy
/// plane's highlight that the reflected sun's trace carries instead).
glm::vec3 view_shading(const Reshade &r,
                       const Surface &surf,
                       const Surface &lobe,
                       const glm::vec3 &n,
                       const glm::vec3 &v,
                       const SsgiParams &p,
                       const SkyCube &sky,
                       bool sun_specular = true)
{
    glm::vec3 c(0.0f);
    const float nl = glm::dot(n, p.sun_direction);
    if (r.vis > 0.0f && nl > 0.0f) {
        c = sun_specular ? direct_response(lobe, n, v, p.sun_direction, DirectOptions{})
                         : lambert(diffuse_albedo(surf)) * nl;
        c *= p.sun_irradiance * r.vis;
    }
    return add_sky_light_from(
        c, surf, n, v, r.ambient, p.sky_scale, [&](const glm::vec3 &d) { return sky.at(d); });
}

}  // namespace

Image ssgi(const Image &depth,
           const Image &normal,
           const Image &radiance,
           const CameraRays &rays,
           const SsgiParams &p,
           const SsgiEnvironment *environment,
           const SsgiSurfaces *surfaces)
{
    const gi_detail::Grid grid(rays, depth.width(), depth.height(), std::max(1, p.stride));
    const int st = grid.stride, ow = grid.ow, oh = grid.oh;
    const glm::vec3 cam = rays.position();
    const float inv_w = grid.inv_w, inv_h = grid.inv_h;
    // The computed pixels' surfaces, once: camera depth (0 for the sky), the normal on the
    // camera's side and the lit colour (the march reads these, not the full-resolution passes).
    // A sample's world position is made again from its depth: the depths alone (4 bytes a
    // computed pixel) stay in cache where positions would not, and the march's samples are
    // scattered.
    const std::size_t count = std::size_t(ow) * std::size_t(oh);
    std::vector<float> zs(count);
    std::vector<Shade> shades(count);
    const bool reshade =
        surfaces && surfaces->albedo && surfaces->material && p.sun_irradiance != glm::vec3(0.0f);
    std::vector<Reshade> reshades(reshade ? count : 0);
    const SceneSky &scene = scene_sky(p.sun_direction);
    const SkyCube *sky = reshade ? &sky_cube(scene) : nullptr;
    const Image lit = block_radiance(radiance, st);
    parallel_for(0, oh, [&](int oy) {
        // The sky's ambient light for the last normal seen: a row of a flat face repeats it.
        glm::vec3 last_n(std::numeric_limits<float>::quiet_NaN()), last_ambient(0.0f);
        for (int ox = 0; ox < ow; ++ox) {
            const int x = ox * st, y = oy * st;
            const std::size_t i = std::size_t(oy) * std::size_t(ow) + std::size_t(ox);
            const float z = depth.at(x, y, 0);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                zs[i] = 0.0f;  // the sky
                continue;
            }
            zs[i] = z;
            const glm::vec3 v_cam = glm::normalize(cam - grid.position(ox, oy, z));
            shades[i].n = normal_at(normal, x, y, v_cam);
            const float *l = lit.pixel(ox, oy);
            shades[i].l = glm::vec3(l[0], l[1], l[2]);
            if (reshade) {
                Reshade &r = reshades[i];
                r.albedo = glm::vec3(finite_or_zero(surfaces->albedo->at(x, y, 0)),
                                     finite_or_zero(surfaces->albedo->at(x, y, 1)),
                                     finite_or_zero(surfaces->albedo->at(x, y, 2)));
                // Non-finite material reads as 1, a non-finite shadow as 0 (SsgiSurfaces).
                const auto finite_or = [](float v, float other) {
                    return std::isfinite(v) ? v : other;
                };
                r.roughness =
                    std::clamp(finite_or(surfaces->material->at(x, y, 0), 1.0f), 0.0f, 1.0f);
                r.metallic =
                    std::clamp(finite_or(surfaces->material->at(x, y, 1), 1.0f), 0.0f, 1.0f);
                r.vis = surfaces->shadow ? finite_or(surfaces->shadow->at(x, y, 0), 0.0f) : 1.0f;
                if (shades[i].n != last_n) {
                    last_n = shades[i].n;
                    last_ambient = scene.ambient(last_n);
                }
                r.ambient = last_ambient;
                const Surface surf = r.surface();
                r.seen = view_shading(r, surf, surf, shades[i].n, v_cam, p, *sky);
            }
        }
    });
    // The glossy planes whose reflected sun is traced, and the computed pixels on them.
    const gi_detail::Glints glints =
        reshade && p.reflected_sun
            ? gi_detail::find_glints(zs, shades, reshades, p.sun_direction, grid)
            : gi_detail::Glints{};
    const float px_world_1 = grid.px_world_1;
    const int slices = std::max(1, p.slices), steps = std::max(1, p.steps);
    const SurfaceCube env_cube =
        environment ? SurfaceCube(surface_map(*environment,
                                              std::min(128, environment->radiance->width()),
                                              std::min(64, environment->radiance->height())),
                                  32,
                                  [](const float *px) { return glm::vec3(px[0], px[1], px[2]); })
                    : SurfaceCube();
    // Screen directions of each slice for each of the pattern's 16 rotations.
    std::vector<glm::vec2> slice_dirs(std::size_t(slices) * 16);
    for (int s = 0; s < slices; ++s) {
        for (int k = 0; k < 16; ++k) {
            const float phi = kPi * (float(s) + (float(k) + 0.5f) / 16.0f) / float(slices);
            slice_dirs[std::size_t(s) * 16 + std::size_t(k)] = {std::cos(phi), std::sin(phi)};
        }
    }
    Image out(ow, oh, 3);
    parallel_for(0, oh, [&](int oy) {
        for (int ox = 0; ox < ow; ++ox) {
            const std::size_t ci = std::size_t(oy) * std::size_t(ow) + std::size_t(ox);
            const float cz = zs[ci];
            if (cz == 0.0f) {
                continue;  // the sky: 0
            }
            const glm::vec3 P = grid.position(ox, oy, cz), &N = shades[ci].n;
            const glm::vec3 V = glm::normalize(cam - P);
            // The search radius in computed pixels.
            const float r_px =
                std::min(p.max_radius_px / float(st), p.radius / std::max(cz * px_world_1, 1e-20f));
            if (!(r_px >= 1.0f)) {
                continue;  // the radius is under a computed pixel: nothing to gather
            }
            glm::vec3 sum(0.0f);
            float total = 0.0f;
            for (int s = 0; s < slices; ++s) {
                const glm::vec2 dir2 =
                    slice_dirs[std::size_t(s) * 16 +
                               std::size_t(pattern(ox + int(p.seed), oy, s) * 16.0f)];
                const float dx = dir2.x, dy = dir2.y;
                // The slice plane: the view vector and the world direction of the screen
                // direction at the point's depth.
                const glm::vec3 along = rays.ray_du() * (dx * inv_w) + rays.ray_dv() * (dy * inv_h);
                glm::vec3 e2 = along - V * glm::dot(along, V);
                const float e2len = glm::length(e2);
                if (!(e2len > 0.0f)) {
                    continue;
                }
                e2 /= e2len;
                const float n1 = glm::dot(N, V), n2 = glm::dot(N, e2);
                const float nlen = std::sqrt(n1 * n1 + n2 * n2);
                if (!(nlen > 1e-6f)) {
                    continue;
                }
                // The normal faces the camera (n1 >= 0): g in [-pi/2, pi/2], so the hemisphere
                // spans [g - pi/2, g + pi/2] with the view vector (0) inside it.
                const Arc arc{
                    std::clamp(fast_atan2(n2, n1), -kPi / 2, kPi / 2), n2 / nlen, n1 / nlen};
                total += nlen * (arc.cos_g + arc.g * arc.sin_g);  // both sides open
                for (int side = 0; side < 2; ++side) {
                    const float sign = side == 0 ? 1.0f : -1.0f;
                    // The hemisphere's part on this side, as signed angles from V.
                    const float lo = side == 0 ? 0.0f : arc.g - kPi / 2;
                    const float hi = side == 0 ? arc.g + kPi / 2 : 0.0f;
                    if (!(hi > lo)) {
                        continue;
                    }
                    // The horizon so far, as an angle, its measure, and an in-slice vector
                    // (cosine, sine) along it of any length. Nothing seen yet: the tangent.
                    float horizon = side == 0 ? hi : lo;
                    float f_horizon = arc.tangent(horizon);
                    float hc = -sign * arc.sin_g, hs = sign * arc.cos_g;
                    const float jitter = pattern(ox, oy + int(p.seed), s + 4 * side + 1);
                    for (int k = 0; k < steps; ++k) {
                        const float t = (float(k) + jitter) / float(steps);
                        const float dist = std::max(1.0f, t * t * r_px);
                        const float sx = float(ox) + 0.5f + sign * dx * dist;
                        const float sy = float(oy) + 0.5f + sign * dy * dist;
                        if (!(sx >= 0.0f && sy >= 0.0f && sx < float(ow) && sy < float(oh))) {
                            break;  // off screen: nothing more this frame shows
                        }
                        const int qx = int(sx), qy = int(sy);
                        const std::size_t qi = std::size_t(qy) * std::size_t(ow) + std::size_t(qx);
                        const float qz = zs[qi];
                        if (qz == 0.0f) {
                            continue;  // sky
                        }
                        const glm::vec3 d = grid.position(qx, qy, qz) - P;
                        const float dc = glm::dot(d, V), ds = glm::dot(d, e2);
                        // On this side of the slice (a sample rounded onto the slice's line or
                        // the point itself is not) and above the horizon: sin(horizon - a) > 0
                        // on side 0, sin(a - horizon) > 0 on side 1, both angles on the side.
                        if (!(sign * ds > 0.0f) || !(sign * (hs * dc - hc * ds) > 0.0f)) {
                            continue;
                        }
                        if (glm::dot(d, d) > p.radius * p.radius) {
                            continue;
                        }
                        // The arc between the old horizon and q now sees q.
                        const float a = fast_atan2(ds, dc);
                        const float f_edge = arc.measure(a, dc, ds);
                        const float m = std::abs(f_horizon - f_edge);
                        horizon = a;
                        f_horizon = f_edge;
                        hc = dc;
                        hs = ds;
                        if (glm::dot(shades[qi].n, d) < 0.0f) {  // q faces the point
                            glm::vec3 L = shades[qi].l;
                            if (reshade) {
                                // q's radiance toward the point, not toward the camera.
                                const Reshade &r = reshades[qi];
                                const Surface surf = r.surface();
                                Surface lobe = surf;
                                lobe.roughness =
                                    std::max(lobe.roughness, kReflectedSunMinRoughness);
                                const glm::vec3 to_p = -d / std::sqrt(glm::dot(d, d));
                                const bool traced =
                                    !glints.family.empty() && glints.family[qi] >= 0;
                                L = glm::max(
                                    L +
                                        view_shading(
                                            r, surf, lobe, shades[qi].n, to_p, p, *sky, !traced) -
                                        r.seen,
                                    glm::vec3(0.0f));
                            }
                            sum += (nlen * m) * L;
                        }
                    }
                    // The arc the march left open (the sky, beyond the radius or off screen):
                    // the probe's surfaces, kOpenSamples sub-arcs of equal angle, each seen in
                    // one direction inside it (jittered with the pattern) and weighted by its
                    // measure. Boundaries and directions step by a rotation of the sub-arc's
                    // angle, so each side takes three sine-cosine pairs.
                    const float open_from = side == 0 ? lo : horizon;
                    const float open_to = side == 0 ? horizon : hi;
                    if (environment && open_to > open_from) {
                        const float step = (open_to - open_from) / float(kOpenSamples);
                        const float jit = pattern(oy, ox + int(p.seed), s + 4 * side + 9);
                        const float cs = std::cos(step), ss = std::sin(step);
                        float bc = std::cos(open_from), bs = std::sin(open_from);
                        float dc = std::cos(open_from + jit * step),
                              dsn = std::sin(open_from + jit * step);
                        float prev = arc.measure(open_from, bc, bs);
                        for (int j = 0; j < kOpenSamples; ++j) {
                            const float nbc = bc * cs - bs * ss, nbs = bs * cs + bc * ss;
                            bc = nbc;
                            bs = nbs;
                            const float f1 = arc.measure(open_from + float(j + 1) * step, bc, bs);
                            const float m = std::abs(f1 - prev);
                            prev = f1;
                            sum += (nlen * m) * env_cube.at(dc * V + dsn * e2);
                            const float ndc = dc * cs - dsn * ss, nds = dsn * cs + dc * ss;
                            dc = ndc;
                            dsn = nds;
                        }
                    }
                }
            }
            // The sun reflected by the glossy planes (ssgi_glint.cpp).
            const glm::vec3 glint =
                glints.count > 0
                    ? gi_detail::glint_light(glints,
                                             zs,
                                             reshades,
                                             grid,
                                             p.sun_direction,
                                             p.radius,
                                             P,
                                             N,
                                             cz,
                                             pattern(ox + 2, oy + 1 + int(p.seed), 13)) *
                          p.sun_irradiance
                    : glm::vec3(0.0f);
            if (total > 0.0f || glints.count > 0) {
                float *o = out.pixel(ox, oy);
                for (int k = 0; k < 3; ++k) {
                    o[k] = (total > 0.0f ? sum[k] / total : 0.0f) + glint[k];
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
