#include "shading/dof/dof_coc.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/parallel.h"

namespace posthaste::shading {

float coc_diameter_px(const DofLens &lens, float z_m, int width_px)
{
    const double f = double(lens.focal_mm) * 1e-3;  // metres
    const double s = std::max(double(lens.focus_m), 1.001 * f);
    const double aperture = f / double(lens.fstop);  // A = f / N, metres
    const double px_per_m = double(width_px) / (double(lens.sensor_mm) * 1e-3);
    // On the sensor: A f (z - s) / (z (s - f)); (z - s) / z -> 1 as z -> inf.
    const double ratio = std::isinf(z_m) ? (z_m > 0 ? 1.0 : -1.0) : (double(z_m) - s) / double(z_m);
    return float(aperture * f * ratio / (s - f) * px_per_m);
}

CocField compute_coc(const Image &depth, const DofLens &lens, float max_radius_px)
{
    CocField c;
    c.width = depth.width();
    c.height = depth.height();
    c.radius.resize(depth.pixel_count());
    c.tiles_x = (c.width + c.tile - 1) / c.tile;
    c.tiles_y = (c.height + c.tile - 1) / c.tile;
    // Radius from 1/z is affine: r = k0 - k1 / z; precompute both (double, then float).
    const double f = double(lens.focal_mm) * 1e-3;
    const double s = std::max(double(lens.focus_m), 1.001 * f);
    const double px_per_m = double(c.width) / (double(lens.sensor_mm) * 1e-3);
    const double k0 = 0.5 * (f / double(lens.fstop)) * f / (s - f) * px_per_m;
    const float k0f = float(k0), k1f = float(k0 * s);
    const float rmax = std::max(0.0f, max_radius_px);
    const int w = c.width;
    // Whole rows: a bandwidth-bound pass (64-pixel tile rows are too short for the prefetcher).
    parallel_for(0, c.height, [&](int y) {
        const float *zr = depth.pixel(0, y);
        const int stride = depth.channels();
        float *out = c.radius.data() + std::size_t(y) * std::size_t(w);
        for (int x = 0; x < w; ++x) {
            const float z = zr[std::size_t(x) * std::size_t(stride)];
            float r;
            if (!(z > 0.0f)) {
                r = 0.0f;  // NaN, zero or negative depth is not a depth: leave it sharp
            } else {
                r = k0f - k1f / z;  // z = +inf gives k0 exactly
            }
            out[x] = std::clamp(r, -rmax, rmax);
        }
    });
    return c;
}

void reduce_tiles(CocField &c)
{
    const int nt = c.tiles_x * c.tiles_y;
    c.tile_max.assign(std::size_t(nt), 0.0f);
    c.tile_min.assign(std::size_t(nt), 0.0f);
    c.gather.assign(std::size_t(nt), 0.0f);
    c.near_gather.assign(std::size_t(nt), 0.0f);
    std::vector<float> near_max(std::size_t(nt), 0.0f);
    parallel_for(0, nt, [&](int i) {
        const int tx = i % c.tiles_x, ty = i / c.tiles_x;
        const int x0 = tx * c.tile, y0 = ty * c.tile;
        const int x1 = std::min(x0 + c.tile, c.width), y1 = std::min(y0 + c.tile, c.height);
        float mx = 0.0f, mn = std::numeric_limits<float>::infinity(), nmx = 0.0f;
        for (int y = y0; y < y1; ++y) {
            const float *row = c.radius.data() + std::size_t(y) * std::size_t(c.width);
            for (int x = x0; x < x1; ++x) {
                const float a = std::fabs(row[x]);
                mx = std::max(mx, a);
                mn = std::min(mn, a);
                nmx = std::max(nmx, -row[x]);
            }
        }
        near_max[std::size_t(i)] = nmx;
        c.tile_max[std::size_t(i)] = mx;
        c.tile_min[std::size_t(i)] = mn;
    });
    float global = 0.0f;
    for (float m : c.tile_max) {
        global = std::max(global, m);
    }
    c.max_radius = global;
    // Dilation: a tile t' at Chebyshev tile distance k can reach t only if its radius covers
    // the (k - 1) full tiles between them.
    const int reach =
        std::min(int(std::ceil(global / float(c.tile))) + 1, std::max(c.tiles_x, c.tiles_y));
    parallel_for(0, nt, [&](int i) {
        const int tx = i % c.tiles_x, ty = i / c.tiles_x;
        float g = c.tile_max[std::size_t(i)], gn = near_max[std::size_t(i)];
        for (int dy = -reach; dy <= reach; ++dy) {
            const int uy = ty + dy;
            if (uy < 0 || uy >= c.tiles_y) {
                continue;
            }
            for (int dx = -reach; dx <= reach; ++dx) {
                const int ux = tx + dx;
                if (ux < 0 || ux >= c.tiles_x) {
                    continue;
                }
                const float r = c.tile_max[std::size_t(uy * c.tiles_x + ux)];
                const float rn = near_max[std::size_t(uy * c.tiles_x + ux)];
                const float gap =
                    float(std::max(std::max(std::abs(dx), std::abs(dy)) - 1, 0) * c.tile);
                if (r > g && r >= gap) {
                    g = r;
                }
                if (rn > gn && rn >= gap) {
                    gn = rn;
                }
            }
        }
        c.gather[std::size_t(i)] = g;
        c.near_gather[std::size_t(i)] = gn;
    });
}

}  // namespace posthaste::shading
