// The motion blur's pack: each pixel's record (colour, log depth, coverage density, |v|) into
// field planes, row by row: the driver and the scalar rows. The vector rows
// (motion_blur_pack_kernels.cpp) also fold the tile max and bounds of the velocities while they
// pack, for tiles a multiple of their lanes wide.
#include "shading/motion_blur/motion_blur_pack.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "core/parallel.h"
#include "core/simd.h"
#include "shading/tiles.h"

namespace posthaste::shading::motion_blur_detail {

void Packer::pixel(int y, int x, float &vx_out, float &vy_out) const
{
    const float *m = motion.pixel(x, y);
    float vx = m[0] * scale, vy = m[1] * scale;
    if (!std::isfinite(vx) || !std::isfinite(vy)) {
        vx = vy = 0.0f;
    }
    float len = std::sqrt(vx * vx + vy * vy);
    if (!std::isfinite(len)) {
        vx = vy = len = 0.0f;
    }
    if (len > max_r) {
        const float k = max_r / len;
        vx *= k;
        vy *= k;
        len = max_r;
    }
    const float z = depth.empty() ? 1.0f : depth.at(x, y, 0);
    // NaN, zero or negative depth is treated as sky.
    const float lz = (z > 0.0f && std::isfinite(z)) ? std::log(z) : kSkyLogZ;
    const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
    const float *c = color.pixel(x, y);
    for (int k = 0; k < 4; ++k) {
        out.plane(kRed + k)[i] = k < nc ? c[k] : 0.0f;
    }
    const float density = len >= 0.5f ? 1.0f / (2.0f * len * len) : 0.0f;
    out.plane(kWx)[i] = vx * density;
    out.plane(kWy)[i] = vy * density;
    out.plane(kLogZ)[i] = lz;
    out.plane(kLen)[i] = len;
    if (!out.velocity.empty()) {
        out.velocity.at(x, y, 0) = vx;
        out.velocity.at(x, y, 1) = vy;
    }
    vx_out = vx;
    vy_out = vy;
}

bool Packer::pixels(int y, int x0, int x1, float *vx, float *vy) const
{
    bool opaque = nc == 4;
    for (int x = x0; x < x1; ++x) {
        float a, b;
        pixel(y, x, a, b);
        if (vx) {
            vx[x - x0] = a;
            vy[x - x0] = b;
        }
        opaque = opaque && color.pixel(x, y)[3] == 1.0f;
    }
    return opaque;
}

Packed pack(const Image &color,
            const Image &motion,
            const Image &depth,
            const MotionBlurOptions &o,
            bool vector,
            bool bounds)
{
    const int w = motion.width(), h = motion.height();
    const std::size_t n = std::size_t(w) * std::size_t(h);
    const std::size_t stride = (n + 15) / 16 * 16;
    // The vector rows fold the tile reductions themselves where vectors tile the tiles.
    const bool fold = vector && o.tile % pack_lanes() == 0;
    Packed out{.block = scratch<float>(stride * kFields),
               .stride = stride,
               .velocity = fold ? Image() : Image::uninitialized(w, h, 2),
               .opaque_rows = std::vector<unsigned char>(std::size_t(h), 0),
               .tiles = Image(),
               .bounds = Image()};
    const Packer p{.color = color,
                   .motion = motion,
                   .depth = depth,
                   .out = out,
                   .w = w,
                   .nc = std::min(color.channels(), 4),
                   .scale = 0.5f * o.shutter,
                   .max_r = std::max(o.max_radius, 0.0f)};
    if (fold) {
        const int tw = (w + o.tile - 1) / o.tile, th = (h + o.tile - 1) / o.tile;
        out.tiles = Image(tw, th, 2);
        if (bounds) {
            out.bounds = Image(tw, th, 4);
        }
        parallel_for(0, th, [&](int ty) { pack_band_vector(p, ty, o.tile, out); });
        return out;
    }
    if (vector) {
        parallel_for(0, h, [&](int y) { out.opaque_rows[std::size_t(y)] = pack_row_vector(p, y); });
        return out;
    }
    parallel_for(0, h, [&](int y) { out.opaque_rows[std::size_t(y)] = p.pixels(y, 0, w); });
    return out;
}

}  // namespace posthaste::shading::motion_blur_detail
