#include "shading/tiles.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace posthaste::shading {

Image tile_max(const Image &field, int tile, int first)
{
    const int tw = (field.width() + tile - 1) / tile, th = (field.height() + tile - 1) / tile;
    Image out(tw, th, 2);
    parallel_for(0, th, [&](int ty) {
        const int y0 = ty * tile, y1 = std::min(field.height(), y0 + tile);
        for (int tx = 0; tx < tw; ++tx) {
            const int x0 = tx * tile, x1 = std::min(field.width(), x0 + tile);
            float best = 0.0f, bx = 0.0f, by = 0.0f;
            for (int y = y0; y < y1; ++y) {
                const float *p = field.pixel(x0, y) + first;
                for (int x = x0; x < x1; ++x, p += field.channels()) {
                    const float l = p[0] * p[0] + p[1] * p[1];
                    if (l > best && std::isfinite(l)) {
                        best = l;
                        bx = p[0];
                        by = p[1];
                    }
                }
            }
            out.at(tx, ty, 0) = bx;
            out.at(tx, ty, 1) = by;
        }
    });
    return out;
}

Image neighbour_max(const Image &tiles, int radius)
{
    const int tw = tiles.width(), th = tiles.height();
    Image out(tw, th, 2);
    parallel_for(0, th, [&](int ty) {
        for (int tx = 0; tx < tw; ++tx) {
            float best = 0.0f, bx = 0.0f, by = 0.0f;
            for (int y = std::max(0, ty - radius); y <= std::min(th - 1, ty + radius); ++y) {
                for (int x = std::max(0, tx - radius); x <= std::min(tw - 1, tx + radius); ++x) {
                    const float vx = tiles.at(x, y, 0), vy = tiles.at(x, y, 1);
                    const float l = vx * vx + vy * vy;
                    if (l > best) {
                        best = l;
                        bx = vx;
                        by = vy;
                    }
                }
            }
            out.at(tx, ty, 0) = bx;
            out.at(tx, ty, 1) = by;
        }
    });
    return out;
}

}  // namespace posthaste::shading
