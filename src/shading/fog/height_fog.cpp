#include "shading/fog/height_fog.h"

#include <algorithm>
#include <cassert>
#include <cstring>
#include <vector>

#include "core/parallel.h"
#include "shading/fog/height_fog_kernels.h"

namespace posthaste::shading {
namespace {

void composite(float *px, const FogResult &f)
{
    px[0] = px[0] * f.transmittance + f.inscatter.x;
    px[1] = px[1] * f.transmittance + f.inscatter.y;
    px[2] = px[2] * f.transmittance + f.inscatter.z;
}

}  // namespace

void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      Image &color)
{
    apply_height_fog(fog, rays, depth, color, color);
}

void apply_height_fog(const HeightFog &fog,
                      const CameraRays &rays,
                      const Image &depth,
                      const Image &source,
                      Image &color)
{
    assert(color.channels() >= 3 && depth.channels() == 1);
    assert(color.width() == depth.width() && color.height() == depth.height());
    assert(source.width() == color.width() && source.height() == color.height() &&
           source.channels() == color.channels());
    const HeightFogCamera c = prepare_height_fog(fog, rays.position());
    const std::size_t row_bytes =
        sizeof(float) * std::size_t(color.width()) * std::size_t(color.channels());
    if (c.empty) {
        if (&source != &color) {
            parallel_for(0, color.height(), [&](int y) {
                std::memcpy(color.pixel(0, y), source.pixel(0, y), row_bytes);
            });
        }
        return;
    }
    const float inv_w = 1.0f / float(color.width());
    const float inv_h = 1.0f / float(color.height());
    const int channels = color.channels();
    // The vector kernel takes the closed form, whose preconditions hold for the whole frame.
    const bool fast = c.fog.start_distance == 0.0f && c.density_at_camera > 1e-20f;
    FogRowParams kp;
    kp.inv_w = inv_w;
    kp.falloff = c.fog.falloff;
    kp.density = c.density_at_camera;
    kp.opaque_sky = c.fog.opaque_sky;
    kp.has_lobe = c.has_lobe;
    kp.lobe_a = c.lobe_a;
    kp.lobe_b = c.lobe_b;
    for (int i = 0; i < 3; ++i) {
        kp.sun[i] = c.fog.sun_direction[i];
        kp.fog_rgb[i] = c.fog.color[i];
        kp.lobe_rgb[i] = c.lobe_scale[i];
    }
    const int w = color.width();
    // Bands of whole rows: the pass streams through memory (it is bandwidth-bound: a 64-pixel
    // tile row is only 1 KiB of RGBA, too short for the hardware prefetcher).
    const int band = 4, bands = (color.height() + band - 1) / band;
    parallel_for(0, bands, [&](int b) {
        std::vector<std::int32_t> fallback(fast ? std::size_t(w) : 0);
        FogRowParams rp = kp;
        for (int y = b * band; y < std::min(color.height(), (b + 1) * band); ++y) {
            const float v = (float(y) + 0.5f) * inv_h;
            const float *z = depth.pixel(0, y);
            float *row = color.pixel(0, y);
            if (&source != &color) {
                std::memcpy(row, source.pixel(0, y), row_bytes);  // then in place, in cache
            }
            const auto exact = [&](int x) {
                const glm::vec3 ray = rays.depth_ray((float(x) + 0.5f) * inv_w, v);
                const float len = glm::length(ray);
                return height_fog(c, ray * (1.0f / len), z[x] * len);
            };
            if (!fast) {
                // The general integral (a start distance, or a density too small for the
                // closed form's product), pixel by pixel.
                for (int x = 0; x < w; ++x) {
                    composite(row + std::size_t(x) * std::size_t(channels), exact(x));
                }
                continue;
            }
            const glm::vec3 row_origin = rays.depth_ray(0.0f, v);
            const glm::vec3 du = rays.depth_ray(1.0f, v) - row_origin;
            for (int i = 0; i < 3; ++i) {
                rp.origin[i] = row_origin[i];
                rp.du[i] = du[i];
            }
            const int n_exact = fog_row(rp, z, row, channels, w, fallback.data());
            for (int k = 0; k < n_exact; ++k) {
                const int x = fallback[std::size_t(k)];
                composite(row + std::size_t(x) * std::size_t(channels), exact(x));
            }
        }
    });
}

}  // namespace posthaste::shading
