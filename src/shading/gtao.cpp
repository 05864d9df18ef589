// Ground-truth-based ambient occlusion (see gtao.h).

#include "shading/gtao.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <vector>

#include "core/parallel.h"

namespace posthaste::shading {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kHalfPi = 0.5f * kPi;

/// acos to about 7e-5 rad over [-1, 1] (Abramowitz and Stegun 4.4.45), without a libm call.
float fast_acos(float c)
{
    const float a = std::abs(c);
    const float p =
        std::sqrt(1.0f - a) * (1.5707288f + a * (-0.2121144f + a * (0.0742610f - 0.0187293f * a)));
    return c >= 0.0f ? p : kPi - p;
}

/// The cosine-weighted visible arc of one side of a slice, between the view vector's angle 0 and
/// the horizon angle h (cosine ch, sine sh), for a projected normal at angle n (cosine cn, sine
/// sn): (-cos(2h - n) + cos n + 2 h sin n) / 4 (Jimenez et al. 2016, eq. 10, one side).
float arc(float h, float ch, float sh, float cn, float sn)
{
    const float cos_2h = 2.0f * ch * ch - 1.0f, sin_2h = 2.0f * sh * ch;
    return 0.25f * (-(cos_2h * cn + sin_2h * sn) + cn + 2.0f * h * sn);
}

/// A 4x4 interleaved pattern: 16 values in [0, 1) spread over every 4x4 block of pixels, so the
/// 5x5 denoise averages every rotation (Jimenez et al.'s spatial noise, without the temporal).
float pattern(int x, int y, int k)
{
    static constexpr int kBayer[16] = {0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5};
    return (float(kBayer[((y & 3) << 2) | (x & 3)] ^ (k * 5 & 15)) + 0.5f) / 16.0f;
}

}  // namespace

Image gtao(const Image &depth, const Image &normal, const CameraRays &rays, const GtaoParams &p)
{
    const int w = depth.width(), h = depth.height();
    const int st = std::max(1, p.stride);
    const int ow = (w + st - 1) / st, oh = (h + st - 1) / st;
    Image out = Image::uninitialized(ow, oh, 1);
    const float inv_w = 1.0f / float(w), inv_h = 1.0f / float(h);
    const glm::vec3 cam = rays.position();
    auto world = [&](int x, int y, float z) {
        return cam + z * rays.depth_ray((float(x) + 0.5f) * inv_w, (float(y) + 0.5f) * inv_h);
    };
    const float r2 = p.radius * p.radius;
    // World units per pixel at depth 1 (times z at a pixel's depth).
    const float px_world_1 = glm::length(rays.depth_ray(inv_w, 0.0f) - rays.depth_ray(0.0f, 0.0f));
    const int slices = std::max(1, p.slices), steps = std::max(1, p.steps);
    // Slice directions for each of the pattern's 16 rotations.
    std::vector<glm::vec2> dirs(std::size_t(16 * slices));
    for (int r = 0; r < 16; ++r) {
        for (int s = 0; s < slices; ++s) {
            const float phi = (float(s) + (float(r) + 0.5f) / 16.0f) * (kPi / float(slices));
            dirs[std::size_t(r * slices + s)] = glm::vec2(std::cos(phi), std::sin(phi));
        }
    }
    parallel_for(0, oh, [&](int oy) {
        for (int ox = 0; ox < ow; ++ox) {
            // The output pixel is the full-resolution pixel (x, y) = stride (ox, oy); samples are
            // taken in the full-resolution depth.
            const int x = ox * st, y = oy * st;
            const float z = depth.at(x, y, 0);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                out.at(ox, oy, 0) = 1.0f;
                continue;
            }
            const glm::vec3 pos = world(x, y, z);
            const glm::vec3 view = glm::normalize(cam - pos);
            glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
            const float nl = glm::length(n);
            n = nl > 1e-6f && std::isfinite(nl) ? n / nl : view;
            // World units per pixel at this depth, and the search radius on screen.
            const float px_world = z * px_world_1;
            const float radius_px =
                std::min(p.radius / std::max(px_world, 1e-12f), p.max_radius_px);
            if (radius_px < 1.0f) {
                out.at(ox, oy, 0) = 1.0f;  // the radius is under a pixel: nothing to find
                continue;
            }
            const int px = ox + int(p.seed & 3u), py = oy + int((p.seed >> 2) & 3u);
            const int rot = int(pattern(px, py, 0) * 16.0f);
            const float jitter = pattern(px, py, 1);
            float visibility = 0.0f;
            for (int s = 0; s < slices; ++s) {
                const float dx = dirs[std::size_t(rot * slices + s)].x;
                const float dy = dirs[std::size_t(rot * slices + s)].y;
                // The slice's world direction: toward the neighbouring pixel along (dx, dy).
                const glm::vec3 side =
                    rays.depth_ray(dx * inv_w, dy * inv_h) - rays.depth_ray(0.0f, 0.0f);
                const glm::vec3 ortho = glm::normalize(side - glm::dot(side, view) * view);
                const glm::vec3 axis = glm::cross(ortho, view);
                const glm::vec3 pn = n - axis * glm::dot(n, axis);
                const float pn_len = glm::length(pn);
                if (pn_len < 1e-6f) {
                    continue;  // the normal is perpendicular to the slice: no weight
                }
                const float cos_n = std::clamp(glm::dot(pn, view) / pn_len, -1.0f, 1.0f);
                const float sgn_n = glm::dot(pn, ortho) < 0.0f ? -1.0f : 1.0f;
                const float ang_n = sgn_n * fast_acos(cos_n);
                const float sin_n = sgn_n * std::sqrt(std::max(0.0f, 1.0f - cos_n * cos_n));
                // Angles in the slice are measured from the view vector, positive toward +ortho
                // (side 1); the lowest horizons are the tangent plane, n - pi/2 on side 0 and
                // n + pi/2 on side 1, kept as cosines from the view vector.
                // cos(n -/+ pi/2) = +/- sin n.
                float hc[2] = {sin_n, -sin_n};
                for (int side_i = 0; side_i < 2; ++side_i) {
                    const float sgn = side_i == 0 ? -1.0f : 1.0f;
                    // The last sample within the radius: the surface between it and a sample
                    // just beyond is taken as straight, and where it crosses the radius is a
                    // horizon candidate (discrete samples would otherwise stop short of the
                    // radius and under-occlude, the more so the fewer the steps).
                    glm::vec3 prev(0.0f);
                    bool have_prev = false;
                    for (int k = 0; k < steps; ++k) {
                        // Quadratic spacing: more samples near the pixel, where occluders are
                        // both likelier and more important.
                        const float t = (float(k) + jitter) / float(steps);
                        const float d = std::max(1.0f, t * t * radius_px);
                        const int sx = int(std::floor(float(x) + 0.5f + sgn * d * dx));
                        const int sy = int(std::floor(float(y) + 0.5f + sgn * d * dy));
                        if (sx < 0 || sy < 0 || sx >= w || sy >= h) {
                            break;  // off screen: nothing known beyond
                        }
                        const float sz = depth.at(sx, sy, 0);
                        if (!(sz > 0.0f) || !std::isfinite(sz)) {
                            have_prev = false;
                            continue;
                        }
                        const glm::vec3 delta = world(sx, sy, sz) - pos;
                        const float len2 = glm::dot(delta, delta);
                        if (len2 < 1e-12f) {
                            continue;
                        }
                        if (len2 > r2) {
                            // Beyond the radius: not an occluder itself. Within twice the radius
                            // of a sample inside it, the crossing point stands in for the surface
                            // in between (a larger jump is a depth edge, not one surface).
                            if (have_prev && len2 < 4.0f * r2) {
                                const glm::vec3 a = delta - prev;
                                const float aa = glm::dot(a, a), b = glm::dot(prev, a);
                                const float cc = glm::dot(prev, prev) - r2;
                                const float disc = b * b - aa * cc;
                                if (aa > 0.0f && disc >= 0.0f) {
                                    const float u = (-b + std::sqrt(disc)) / aa;
                                    const glm::vec3 q = prev + u * a;
                                    hc[side_i] = std::max(hc[side_i], glm::dot(q, view) / p.radius);
                                }
                            }
                            have_prev = false;
                            continue;
                        }
                        const float c = glm::dot(delta, view) / std::sqrt(len2);
                        hc[side_i] = std::max(hc[side_i], c);
                        prev = delta;
                        have_prev = true;
                    }
                }
                // Horizon angles (side 0 negative), at most pi/2 from the normal; their cosines
                // and sines from the angle only where the clamp moved them.
                float h0 = -fast_acos(hc[0]), h1 = fast_acos(hc[1]);
                float c0 = hc[0], s0 = -std::sqrt(std::max(0.0f, 1.0f - c0 * c0));
                float c1 = hc[1], s1 = std::sqrt(std::max(0.0f, 1.0f - c1 * c1));
                if (h0 < ang_n - kHalfPi) {
                    h0 = ang_n - kHalfPi;
                    c0 = sin_n;  // cos(n - pi/2)
                    s0 = -cos_n;
                }
                if (h1 > ang_n + kHalfPi) {
                    h1 = ang_n + kHalfPi;
                    c1 = -sin_n;  // cos(n + pi/2)
                    s1 = cos_n;
                }
                visibility +=
                    pn_len * (arc(h0, c0, s0, cos_n, sin_n) + arc(h1, c1, s1, cos_n, sin_n));
            }
            // The mean over slices (the projected normal's length is the slice's weight in the
            // hemisphere integral: unoccluded, the mean over all slice directions is exactly 1).
            // A few slices scatter around it either way; the node clamps after denoising.
            out.at(ox, oy, 0) = visibility / float(slices);
        }
    });
    return out;
}

Image gtao_denoise(const Image &ao, const Image &depth, int stride)
{
    const int w = ao.width(), h = ao.height(), st = std::max(1, stride);
    Image out = Image::uninitialized(w, h, 1);
    auto depth_of = [&](int i, int j) { return depth.at(i * st, j * st, 0); };
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth_of(x, y);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                out.at(x, y, 0) = ao.at(x, y, 0);
                continue;
            }
            const float inv_scale = 1.0f / (0.1f * z);
            float sum = 0.0f, wsum = 0.0f;
            for (int j = std::max(0, y - 2); j <= std::min(h - 1, y + 2); ++j) {
                for (int i = std::max(0, x - 2); i <= std::min(w - 1, x + 2); ++i) {
                    const float nz = depth_of(i, j);
                    if (!(nz > 0.0f) || !std::isfinite(nz)) {
                        continue;
                    }
                    const float wt = std::max(0.0f, 1.0f - std::abs(nz - z) * inv_scale);
                    sum += wt * ao.at(i, j, 0);
                    wsum += wt;
                }
            }
            out.at(x, y, 0) = sum / wsum;  // the centre is always in: wsum >= 1
        }
    });
    return out;
}

Image gtao_upsample(const Image &ao, const Image &depth, int stride)
{
    const int w = depth.width(), h = depth.height(), st = std::max(1, stride);
    if (st == 1) {
        return ao;
    }
    const int lw = ao.width(), lh = ao.height();
    Image out = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        const int j0 = std::min(y / st, lh - 1), j1 = std::min(j0 + 1, lh - 1);
        const float fy = float(y - j0 * st) / float(st);
        for (int x = 0; x < w; ++x) {
            const int i0 = std::min(x / st, lw - 1), i1 = std::min(i0 + 1, lw - 1);
            const float fx = float(x - i0 * st) / float(st);
            const float z = depth.at(x, y, 0);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                out.at(x, y, 0) = 1.0f;
                continue;
            }
            const float inv_scale = 1.0f / (0.1f * z);
            float sum = 0.0f, wsum = 0.0f, best = HUGE_VALF, nearest = 1.0f;
            const int is[2] = {i0, i1}, js[2] = {j0, j1};
            for (int b = 0; b < 2; ++b) {
                for (int a = 0; a < 2; ++a) {
                    const float lz = depth.at(is[a] * st, js[b] * st, 0);
                    if (!(lz > 0.0f) || !std::isfinite(lz)) {
                        continue;
                    }
                    const float dz = std::abs(lz - z);
                    const float bw = (a ? fx : 1.0f - fx) * (b ? fy : 1.0f - fy);
                    const float wt = bw * std::max(0.0f, 1.0f - dz * inv_scale);
                    sum += wt * ao.at(is[a], js[b], 0);
                    wsum += wt;
                    if (dz < best) {
                        best = dz;
                        nearest = ao.at(is[a], js[b], 0);
                    }
                }
            }
            // No neighbour on this surface (a thin feature between the samples): the closest in
            // depth.
            out.at(x, y, 0) = wsum > 1e-6f ? sum / wsum : nearest;
        }
    });
    return out;
}

}  // namespace posthaste::shading
