#include "shading/tiles.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <vector>

#include "core/parallel.h"

namespace posthaste::shading {

void tile_max_bounds(const Image &field, int tile, int first, Image *max, Image *bounds)
{
    const int tw = (field.width() + tile - 1) / tile, th = (field.height() + tile - 1) / tile;
    if (max) {
        *max = Image(tw, th, 2);
    }
    if (bounds) {
        *bounds = Image(tw, th, 4);
    }
    constexpr float kInf = std::numeric_limits<float>::infinity();
    parallel_for(0, th, [&](int ty) {
        // Per tile of the band: the longest vector so far (length^2, x, y) and the box. Rows
        // are read whole, in order; each tile still sees its pixels in scan order.
        std::vector<float> acc(std::size_t(tw) * 7);
        for (int tx = 0; tx < tw; ++tx) {
            float *a = &acc[std::size_t(tx) * 7];
            a[0] = a[1] = a[2] = 0.0f;
            a[3] = a[4] = kInf;
            a[5] = a[6] = -kInf;
        }
        const int y0 = ty * tile, y1 = std::min(field.height(), y0 + tile);
        for (int y = y0; y < y1; ++y) {
            const float *p = field.pixel(0, y) + first;
            const int stride = field.channels();
            for (int tx = 0; tx < tw; ++tx) {
                float *a = &acc[std::size_t(tx) * 7];
                const int x1 = std::min(field.width(), (tx + 1) * tile);
                for (int x = tx * tile; x < x1; ++x, p += stride) {
                    const float vx = p[0], vy = p[1];
                    const float l = vx * vx + vy * vy;
                    if (l > a[0] && std::isfinite(l)) {
                        a[0] = l;
                        a[1] = vx;
                        a[2] = vy;
                    }
                    const bool ok = std::isfinite(vx) && std::isfinite(vy);
                    const float bx = ok ? vx : 0.0f, by = ok ? vy : 0.0f;
                    a[3] = std::min(a[3], bx);
                    a[4] = std::min(a[4], by);
                    a[5] = std::max(a[5], bx);
                    a[6] = std::max(a[6], by);
                }
            }
        }
        for (int tx = 0; tx < tw; ++tx) {
            const float *a = &acc[std::size_t(tx) * 7];
            if (max) {
                max->at(tx, ty, 0) = a[1];
                max->at(tx, ty, 1) = a[2];
            }
            if (bounds) {
                std::copy(a + 3, a + 7, bounds->pixel(tx, ty));
            }
        }
    });
}

Image tile_max(const Image &field, int tile, int first)
{
    Image out;
    tile_max_bounds(field, tile, first, &out, nullptr);
    return out;
}

namespace {

/// The one window loop of the neighbour reductions: per tile, over the tiles within `radius`
/// (Chebyshev) that `admit(d, x, y)` accepts (d: the Chebyshev distance to tile (x, y)), the
/// longest vector of `tiles` (ties keep the first in scan order) into `nmax`, and the union of
/// the (min x, min y, max x, max y) boxes of `bounds` into `nbounds`. Either pair may be null.
template <class Admit>
void neighbours_if(const Image *tiles,
                   const Image *bounds,
                   int radius,
                   const Admit &admit,
                   Image *nmax,
                   Image *nbounds)
{
    const bool with_max = tiles && nmax, with_bounds = bounds && nbounds;
    const Image &dims = with_max ? *tiles : *bounds;
    const int tw = dims.width(), th = dims.height();
    if (with_max) {
        *nmax = Image(tw, th, 2);
    }
    if (with_bounds) {
        *nbounds = Image(tw, th, 4);
    }
    constexpr float kInf = std::numeric_limits<float>::infinity();
    parallel_for(0, th, [&](int ty) {
        for (int tx = 0; tx < tw; ++tx) {
            float best = 0.0f, bx = 0.0f, by = 0.0f;
            float b[4] = {kInf, kInf, -kInf, -kInf};
            for (int y = std::max(0, ty - radius); y <= std::min(th - 1, ty + radius); ++y) {
                const int dy = std::abs(y - ty);
                for (int x = std::max(0, tx - radius); x <= std::min(tw - 1, tx + radius); ++x) {
                    if (!admit(std::max(std::abs(x - tx), dy), x, y)) {
                        continue;
                    }
                    if (with_max) {
                        const float *v = tiles->pixel(x, y);
                        const float l = v[0] * v[0] + v[1] * v[1];
                        if (l > best) {
                            best = l;
                            bx = v[0];
                            by = v[1];
                        }
                    }
                    if (with_bounds) {
                        const float *p = bounds->pixel(x, y);
                        b[0] = std::min(b[0], p[0]);
                        b[1] = std::min(b[1], p[1]);
                        b[2] = std::max(b[2], p[2]);
                        b[3] = std::max(b[3], p[3]);
                    }
                }
            }
            if (with_max) {
                nmax->at(tx, ty, 0) = bx;
                nmax->at(tx, ty, 1) = by;
            }
            if (with_bounds) {
                std::copy(b, b + 4, nbounds->pixel(tx, ty));
            }
        }
    });
}

constexpr auto kAll = [](int, int, int) { return true; };

}  // namespace

Image neighbour_max(const Image &tiles, int radius)
{
    Image out;
    neighbours_if(&tiles, nullptr, radius, kAll, &out, nullptr);
    return out;
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

void neighbour_reach(const Image &tiles,
                     const Image *bounds,
                     int tile,
                     int margin,
                     int radius,
                     Image *nmax,
                     Image *nbounds)
{
    const std::vector<int> reach = tile_reach(tiles, tile, margin);
    const std::size_t tw = std::size_t(tiles.width());
    neighbours_if(
        &tiles,
        bounds,
        radius,
        [&](int d, int x, int y) { return d <= reach[std::size_t(y) * tw + std::size_t(x)]; },
        nmax,
        nbounds);
}

Image neighbour_max_reach(const Image &tiles, int tile, int margin, int radius)
{
    Image out;
    neighbour_reach(tiles, nullptr, tile, margin, radius, &out, nullptr);
    return out;
}

Image neighbour_bounds_reach(
    const Image &bounds, const Image &tiles, int tile, int margin, int radius)
{
    Image out;
    neighbour_reach(tiles, &bounds, tile, margin, radius, nullptr, &out);
    return out;
}

Image tile_bounds(const Image &field, int tile, int first)
{
    Image out;
    tile_max_bounds(field, tile, first, nullptr, &out);
    return out;
}

Image neighbour_bounds(const Image &bounds, int radius)
{
    Image out;
    neighbours_if(nullptr, &bounds, radius, kAll, nullptr, &out);
    return out;
}

std::vector<std::uint8_t> occupied_tiles(const float *const planes[4],
                                         int width,
                                         int height,
                                         int tile)
{
    const int tx = (width + tile - 1) / tile, ty = (height + tile - 1) / tile;
    std::vector<std::uint8_t> occupied(std::size_t(tx) * std::size_t(ty), 0);
    parallel_for(0, ty, [&](int j) {
        const int y1 = std::min(height, (j + 1) * tile);
        for (int y = j * tile; y < y1; ++y) {
            const std::size_t row = std::size_t(y) * std::size_t(width);
            for (int i = 0; i < tx; ++i) {
                std::uint8_t &o = occupied[std::size_t(j) * std::size_t(tx) + std::size_t(i)];
                const int x1 = std::min(width, (i + 1) * tile);
                for (int k = 0; k < 4 && !o; ++k) {
                    for (int x = i * tile; x < x1; ++x) {
                        if (planes[k][row + std::size_t(x)] != 0.0f ||
                            std::isnan(planes[k][row + std::size_t(x)])) {
                            o = 1;
                            break;
                        }
                    }
                }
            }
        }
    });
    return occupied;
}

std::vector<std::uint8_t> tiles_in_reach(const std::vector<std::uint8_t> &occupied,
                                         int tiles_x,
                                         int tiles_y,
                                         const std::function<int(std::size_t)> &reach)
{
    // Summed-area table: each tile's window is four lookups.
    const std::size_t sx = std::size_t(tiles_x) + 1;
    std::vector<int> sum(sx * (std::size_t(tiles_y) + 1), 0);
    for (int y = 0; y < tiles_y; ++y) {
        for (int x = 0; x < tiles_x; ++x) {
            sum[std::size_t(y + 1) * sx + std::size_t(x + 1)] =
                occupied[std::size_t(y) * std::size_t(tiles_x) + std::size_t(x)] +
                sum[std::size_t(y) * sx + std::size_t(x + 1)] +
                sum[std::size_t(y + 1) * sx + std::size_t(x)] -
                sum[std::size_t(y) * sx + std::size_t(x)];
        }
    }
    std::vector<std::uint8_t> out(occupied.size(), 0);
    for (int y = 0; y < tiles_y; ++y) {
        for (int x = 0; x < tiles_x; ++x) {
            const std::size_t t = std::size_t(y) * std::size_t(tiles_x) + std::size_t(x);
            const int r = std::max(reach(t), 0);
            const std::size_t x0 = std::size_t(std::max(x - r, 0)),
                              x1 = std::size_t(std::min(x + r + 1, tiles_x));
            const std::size_t y0 = std::size_t(std::max(y - r, 0)),
                              y1 = std::size_t(std::min(y + r + 1, tiles_y));
            out[t] =
                sum[y1 * sx + x1] - sum[y0 * sx + x1] - sum[y1 * sx + x0] + sum[y0 * sx + x0] > 0;
        }
    }
    return out;
}

}  // namespace posthaste::shading
