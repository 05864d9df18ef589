#include "shading/tiles.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <vector>

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

namespace {

/// Per tile, the longest vector among the tiles within `radius` (Chebyshev) that `admit(dx, dy,
/// x, y)` accepts, dx and dy being the offsets from the tile to tile (x, y).
template <class Admit>
Image neighbour_max_if(const Image &tiles, int radius, const Admit &admit)
{
    const int tw = tiles.width(), th = tiles.height();
    Image out(tw, th, 2);
    parallel_for(0, th, [&](int ty) {
        for (int tx = 0; tx < tw; ++tx) {
            float best = 0.0f, bx = 0.0f, by = 0.0f;
            for (int y = std::max(0, ty - radius); y <= std::min(th - 1, ty + radius); ++y) {
                for (int x = std::max(0, tx - radius); x <= std::min(tw - 1, tx + radius); ++x) {
                    if (!admit(x - tx, y - ty, x, y)) {
                        continue;
                    }
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

/// Per tile, the union of the (min x, min y, max x, max y) bounds of the tiles within `radius`
/// that `admit` accepts (as in neighbour_max_if).
template <class Admit>
Image neighbour_bounds_if(const Image &bounds, int radius, const Admit &admit)
{
    const int tw = bounds.width(), th = bounds.height();
    Image out(tw, th, 4);
    parallel_for(0, th, [&](int ty) {
        for (int tx = 0; tx < tw; ++tx) {
            float b[4] = {std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity(),
                          -std::numeric_limits<float>::infinity()};
            for (int y = std::max(0, ty - radius); y <= std::min(th - 1, ty + radius); ++y) {
                for (int x = std::max(0, tx - radius); x <= std::min(tw - 1, tx + radius); ++x) {
                    if (!admit(x - tx, y - ty, x, y)) {
                        continue;
                    }
                    const float *p = bounds.pixel(x, y);
                    b[0] = std::min(b[0], p[0]);
                    b[1] = std::min(b[1], p[1]);
                    b[2] = std::max(b[2], p[2]);
                    b[3] = std::max(b[3], p[3]);
                }
            }
            std::copy(b, b + 4, out.pixel(tx, ty));
        }
    });
    return out;
}

}  // namespace

Image neighbour_max(const Image &tiles, int radius)
{
    return neighbour_max_if(tiles, radius, [](int, int, int, int) { return true; });
}

namespace {

/// Per tile: the Chebyshev distance in tiles its longest vector can reach, plus margin.
std::vector<int> tile_reach(const Image &tiles, int tile, int margin)
{
    std::vector<int> reach(std::size_t(tiles.width()) * std::size_t(tiles.height()));
    for (int ty = 0; ty < tiles.height(); ++ty) {
        for (int tx = 0; tx < tiles.width(); ++tx) {
            const float l = std::hypot(tiles.at(tx, ty, 0), tiles.at(tx, ty, 1));
            // Clamped before the conversion: a huge (or non-finite) length reaches everything.
            const float r = std::min(std::ceil(l / float(tile)), 65536.0f);
            reach[std::size_t(ty) * std::size_t(tiles.width()) + std::size_t(tx)] =
                (r >= 0.0f ? int(r) : 65536) + margin;
        }
    }
    return reach;
}

}  // namespace

Image neighbour_max_reach(const Image &tiles, int tile, int margin, int radius)
{
    const std::vector<int> reach = tile_reach(tiles, tile, margin);
    const std::size_t tw = std::size_t(tiles.width());
    return neighbour_max_if(tiles, radius, [&](int dx, int dy, int x, int y) {
        return std::max(std::abs(dx), std::abs(dy)) <= reach[std::size_t(y) * tw + std::size_t(x)];
    });
}

Image neighbour_bounds_reach(
    const Image &bounds, const Image &tiles, int tile, int margin, int radius)
{
    const std::vector<int> reach = tile_reach(tiles, tile, margin);
    const std::size_t tw = std::size_t(bounds.width());
    return neighbour_bounds_if(bounds, radius, [&](int dx, int dy, int x, int y) {
        return std::max(std::abs(dx), std::abs(dy)) <= reach[std::size_t(y) * tw + std::size_t(x)];
    });
}

Image tile_bounds(const Image &field, int tile, int first)
{
    const int tw = (field.width() + tile - 1) / tile, th = (field.height() + tile - 1) / tile;
    Image out(tw, th, 4);
    parallel_for(0, th, [&](int ty) {
        const int y0 = ty * tile, y1 = std::min(field.height(), y0 + tile);
        for (int tx = 0; tx < tw; ++tx) {
            const int x0 = tx * tile, x1 = std::min(field.width(), x0 + tile);
            float lo[2] = {std::numeric_limits<float>::infinity(),
                           std::numeric_limits<float>::infinity()};
            float hi[2] = {-lo[0], -lo[1]};
            for (int y = y0; y < y1; ++y) {
                const float *p = field.pixel(x0, y) + first;
                for (int x = x0; x < x1; ++x, p += field.channels()) {
                    const bool ok = std::isfinite(p[0]) && std::isfinite(p[1]);
                    for (int c = 0; c < 2; ++c) {
                        const float v = ok ? p[c] : 0.0f;
                        lo[c] = std::min(lo[c], v);
                        hi[c] = std::max(hi[c], v);
                    }
                }
            }
            float *o = out.pixel(tx, ty);
            o[0] = lo[0];
            o[1] = lo[1];
            o[2] = hi[0];
            o[3] = hi[1];
        }
    });
    return out;
}

Image neighbour_bounds(const Image &bounds, int radius)
{
    return neighbour_bounds_if(bounds, radius, [](int, int, int, int) { return true; });
}

}  // namespace posthaste::shading
