// Ground-truth-based ambient occlusion (see gtao.h).

#include "shading/gtao.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "shading/gtao_kernels.h"

namespace posthaste::shading {
namespace {

constexpr float kPi = 3.14159265358979f;

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
    const float inv_w = 1.0f / float(w);
    GtaoKernelParams kp;
    kp.depth = depth.data();
    kp.w = w;
    kp.h = h;
    const glm::vec3 cam = rays.position(), o = rays.depth_ray(0.0f, 0.0f);
    const glm::vec3 du = rays.depth_ray(1.0f, 0.0f) - o, dv = rays.depth_ray(0.0f, 1.0f) - o;
    for (int c = 0; c < 3; ++c) {
        kp.cam[c] = cam[c];
        kp.origin[c] = o[c];
        kp.du[c] = du[c];
        kp.dv[c] = dv[c];
    }
    kp.radius = p.radius;
    kp.max_radius_px = p.max_radius_px;
    // World units per pixel at depth 1 (times z at a pixel's depth).
    kp.px_world_1 = glm::length(du) * inv_w;
    kp.slices = std::max(1, p.slices);
    kp.steps = std::max(1, p.steps);
    kp.stride = st;
    // Slice directions for each of the pattern's 16 rotations.
    std::vector<float> dir_x(std::size_t(16 * kp.slices)), dir_y(dir_x.size());
    for (int r = 0; r < 16; ++r) {
        for (int s = 0; s < kp.slices; ++s) {
            const float phi = (float(s) + (float(r) + 0.5f) / 16.0f) * (kPi / float(kp.slices));
            dir_x[std::size_t(r * kp.slices + s)] = std::cos(phi);
            dir_y[std::size_t(r * kp.slices + s)] = std::sin(phi);
        }
    }
    kp.dir_x = dir_x.data();
    kp.dir_y = dir_y.data();
    const std::size_t n = std::size_t(ow) + kGtaoPad;
    parallel_for(0, oh, [&](int oy) {
        // The row's computed pixels as planes for the kernel (the padding: sky, AO 1).
        std::vector<float> z(n, std::numeric_limits<float>::infinity()), nx(n, 0.0f), ny(n, 0.0f),
            nz(n, 0.0f), jitter(n, 0.0f), ao(n);
        std::vector<std::int32_t> rot(n, 0);
        const int y = oy * st;
        for (int ox = 0; ox < ow; ++ox) {
            const int x = ox * st;
            const std::size_t i = std::size_t(ox);
            z[i] = depth.at(x, y, 0);
            nx[i] = normal.at(x, y, 0);
            ny[i] = normal.at(x, y, 1);
            nz[i] = normal.at(x, y, 2);
            const int px = ox + int(p.seed & 3u), py = oy + int((p.seed >> 2) & 3u);
            rot[i] = std::int32_t(pattern(px, py, 0) * 16.0f) * kp.slices;
            jitter[i] = pattern(px, py, 1);
        }
        gtao_row(kp,
                 oy,
                 z.data(),
                 nx.data(),
                 ny.data(),
                 nz.data(),
                 rot.data(),
                 jitter.data(),
                 ow,
                 ao.data());
        std::copy(ao.begin(), ao.begin() + ow, out.pixel(0, oy));
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
