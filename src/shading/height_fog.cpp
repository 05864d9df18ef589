#include "shading/height_fog.h"

#include <cassert>

#include "core/parallel.h"

namespace posthaste::shading {

void apply_height_fog(const HeightFog &fog, const CameraRays &rays, const Image &depth, Image &color)
{
    assert(color.channels() >= 3 && depth.channels() == 1);
    assert(color.width() == depth.width() && color.height() == depth.height());
    const HeightFogCamera c = prepare_height_fog(fog, rays.position());
    if (c.empty) {
        return;
    }
    const float inv_w = 1.0f / float(color.width());
    const float inv_h = 1.0f / float(color.height());
    const int channels = color.channels();
    parallel_for_tiles(color.bounds(), [&](const Rect &tile) {
        for (int y = tile.y0; y < tile.y1; ++y) {
            const float v = (float(y) + 0.5f) * inv_h;
            float *px = color.pixel(tile.x0, y);
            const float *z = depth.pixel(tile.x0, y);
            for (int x = tile.x0; x < tile.x1; ++x, px += channels, ++z) {
                const glm::vec3 ray = rays.depth_ray((float(x) + 0.5f) * inv_w, v);
                const float len = glm::length(ray);
                const FogResult f = height_fog(c, ray * (1.0f / len), *z * len);
                px[0] = px[0] * f.transmittance + f.inscatter.x;
                px[1] = px[1] * f.transmittance + f.inscatter.y;
                px[2] = px[2] * f.transmittance + f.inscatter.z;
            }
        }
    });
}

}  // namespace posthaste::shading
