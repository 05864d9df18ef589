// Ground-truth-based ambient occlusion (see gtao.h).

#include "shading/ao/gtao.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "shading/ao/gtao_kernels.h"

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
    kp.thickness = p.thickness;
    if (p.thickness_map || p.reach_map) {
        const int ms = p.map_stride;
        kp.map_shift = ms == 1 ? 0 : ms == 2 ? 1 : ms == 4 ? 2 : ms == 8 ? 3 : -1;
        kp.map_w = (w + ms - 1) / std::max(ms, 1);
        kp.map_h = (h + ms - 1) / std::max(ms, 1);
        for (const Image *map : {p.thickness_map, p.reach_map}) {
            if (map && (kp.map_shift < 0 || map->width() != kp.map_w || map->height() != kp.map_h ||
                        map->channels() != 1)) {
                throw Error(ExitCode::Runtime,
                            "gtao: a thickness or reach map is not one channel over every 1st, "
                            "2nd, 4th or 8th pixel of the depth pass");
            }
        }
        if (p.thickness_map && p.thickness > 0.0f) {
            kp.thickness_map = p.thickness_map->data();
        }
        kp.reach_map = p.reach_map ? p.reach_map->data() : nullptr;
    }
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

Image gtao_depth(const Image &depth, int stride)
{
    const int st = std::max(1, stride);
    const int w = (depth.width() + st - 1) / st, h = (depth.height() + st - 1) / st;
    Image ld = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x * st, y * st, 0);
            ld.at(x, y, 0) =
                z > 0.0f && std::isfinite(z) ? z : std::numeric_limits<float>::quiet_NaN();
        }
    });
    return ld;
}

Image gtao_denoise(const Image &ao, const Image &ld)
{
    const int w = ao.width(), h = ao.height();
    Image out = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        // Row at a time, tap by tap: simple loops the compiler vectorises.
        const std::size_t n = static_cast<std::size_t>(w);
        std::vector<float> sum(n, 0.0f), wsum(n, 0.0f), inv(n);
        const float *zr = ld.pixel(0, y);
        for (int x = 0; x < w; ++x) {
            inv[std::size_t(x)] = 1.0f / (0.1f * zr[x]);
        }
        for (int j = std::max(0, y - 2); j <= std::min(h - 1, y + 2); ++j) {
            const float *nzr = ld.pixel(0, j);
            const float *aor = ao.pixel(0, j);
            for (int dx = -2; dx <= 2; ++dx) {
                const int x0 = std::max(0, -dx), x1 = std::min(w, w - dx);
                for (int x = x0; x < x1; ++x) {
                    const float t = 1.0f - std::abs(nzr[x + dx] - zr[x]) * inv[std::size_t(x)];
                    const float wt = 0.0f < t ? t : 0.0f;  // NaN (no surface) -> 0
                    sum[std::size_t(x)] += wt * aor[x + dx];
                    wsum[std::size_t(x)] += wt;
                }
            }
        }
        float *o = out.pixel(0, y);
        const float *ar = ao.pixel(0, y);
        for (int x = 0; x < w; ++x) {
            // Without a surface (or, never, no weight) the pixel keeps its value; the centre's
            // own weight is 1 otherwise.
            o[x] = wsum[std::size_t(x)] > 0.0f ? sum[std::size_t(x)] / wsum[std::size_t(x)] : ar[x];
        }
    });
    return out;
}

Image gtao_upsample(const Image &ao, const Image &ld, const Image &depth, int stride)
{
    const int w = depth.width(), h = depth.height(), st = std::max(1, stride);
    if (st == 1) {
        return ao;
    }
    const int lw = ao.width(), lh = ao.height();
    // Per column: the two AO pixels either side and the bilinear weight of the right one.
    const std::size_t nw = static_cast<std::size_t>(w);
    std::vector<std::int32_t> i0(nw), i1(nw);
    std::vector<float> fx(nw);
    for (int x = 0; x < w; ++x) {
        i0[std::size_t(x)] = std::min(x / st, lw - 1);
        i1[std::size_t(x)] = std::min(i0[std::size_t(x)] + 1, lw - 1);
        fx[std::size_t(x)] = float(x - i0[std::size_t(x)] * st) / float(st);
    }
    Image out = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        const int j0 = std::min(y / st, lh - 1), j1 = std::min(j0 + 1, lh - 1);
        const GtaoUpsampleRow row{ld.pixel(0, j0),
                                  ld.pixel(0, j1),
                                  ao.pixel(0, j0),
                                  ao.pixel(0, j1),
                                  depth.pixel(0, y),
                                  i0.data(),
                                  i1.data(),
                                  fx.data(),
                                  float(y - j0 * st) / float(st)};
        gtao_upsample_row(row, w, out.pixel(0, y));
    });
    return out;
}

}  // namespace posthaste::shading
