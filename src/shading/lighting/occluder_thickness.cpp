#include "shading/lighting/occluder_thickness.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

#include "core/parallel.h"

namespace posthaste::shading {

Image occluder_thickness(const Image &depth,
                         const Image &normal,
                         const CameraRays &rays,
                         float max_thickness,
                         int stride,
                         SurfaceExtent extent)
{
    // The map's grid: every st-th pixel of the passes (st = 1: every pixel).
    const int st = std::max(1, stride);
    const int full_w = depth.width(), full_h = depth.height();
    const int w = (full_w + st - 1) / st, h = (full_h + st - 1) / st;
    Image out = Image::uninitialized(w, h, 1);
    // A grid cell's width at depth 1 (a pinhole's footprint grows with depth alone).
    const float footprint =
        0.5f *
        (glm::length(rays.ray_du()) / float(full_w) + glm::length(rays.ray_dv()) / float(full_h)) *
        float(st);
    // Each pixel's depth, 0 where there is no surface (not positive or not finite).
    std::vector<float> zs(std::size_t(w) * std::size_t(h));
    const auto index = [w](int x, int y) {
        return std::size_t(y) * std::size_t(w) + std::size_t(x);
    };
    parallel_for(0, h, [&](int y) {
        float *z = zs.data() + index(0, y);
        for (int x = 0; x < w; ++x) {
            const float v = depth.at(x * st, y * st, 0);
            z[x] = v > 0.0f && v < std::numeric_limits<float>::infinity() ? v : 0.0f;
        }
    });
    if (!(footprint > 0.0f) || !std::isfinite(footprint)) {
        // No footprint (a degenerate camera): every surface as deep as the most.
        parallel_for(0, h, [&](int y) {
            for (int x = 0; x < w; ++x) {
                out.at(x, y, 0) = zs[index(x, y)] > 0.0f ? max_thickness : 0.0f;
            }
        });
        return out;
    }
    // The tangent of the angle between a pixel's normal and its view ray: how far depth steps
    // from one pixel to the next on a continuous surface (0 without a usable normal: the surface
    // is taken as facing the camera).
    const auto tangent = [&](int gx, int gy) {
        const int x = gx * st, y = gy * st;
        const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
        const glm::vec3 ray =
            rays.depth_ray((float(x) + 0.5f) / float(full_w), (float(y) + 0.5f) / float(full_h));
        const float nn = glm::length(n) * glm::length(ray);
        if (!(nn > 0.0f) || !std::isfinite(nn)) {
            return 0.0f;
        }
        const float c = std::fabs(glm::dot(n, ray)) / nn;
        const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
        return std::min(s / std::max(c, 0.05f), 20.0f);
    };
    // Neighbours a and b lie on one surface when their depths differ by no more than twice what
    // the flatter one's slope gives over a pixel, plus 1 % of the depth (noise, curvature). The
    // joins of a row of pairs are found in two loops: the depths alone (branch-free, most pairs),
    // then the slopes for the pairs beside a larger step.
    // join[i] says whether the pair (za[i], zb[i]) is joined; pixel_a(i) and pixel_b(i) are
    // their pixels on the grid, for the slopes.
    const auto joins = [&](const float *za,
                           const float *zb,
                           int n,
                           std::uint8_t *join,
                           auto pixel_a,
                           auto pixel_b) {
        int steps = 0;
        for (int i = 0; i < n; ++i) {
            // Branch-free, so that it vectorises: zs holds no NaN, so both depths are surfaces
            // where the smaller is.
            const float a = za[i], b = zb[i], m = std::min(a, b);
            const int both = m > 0.0f ? 1 : 0;
            const int near = std::fabs(a - b) <= 0.01f * m ? 1 : 0;
            join[i] = std::uint8_t(both & near);
            steps |= both & (near ^ 1);
        }
        if (!steps) {
            return;
        }
        for (int i = 0; i < n; ++i) {
            const float a = za[i], b = zb[i];
            if (join[i] != 0 || !(a > 0.0f && b > 0.0f)) {
                continue;
            }
            const glm::ivec2 pa = pixel_a(i), pb = pixel_b(i);
            const float z = std::min(a, b), step = std::fabs(a - b);
            join[i] =
                step <= z * (2.0f * footprint * std::min(tangent(pa.x, pa.y), tangent(pb.x, pb.y)) +
                             0.01f)
                    ? 1
                    : 0;
        }
    };
    // right[x, y]: pixel (x, y) joined to (x + 1, y); up[x, y]: joined to (x, y - 1).
    std::vector<std::uint8_t> right(zs.size()), up(zs.size());
    parallel_for(0, h, [&](int y) {
        const float *z = zs.data() + index(0, y);
        joins(
            z,
            z + 1,
            w - 1,
            right.data() + index(0, y),
            [y](int i) { return glm::ivec2(i, y); },
            [y](int i) { return glm::ivec2(i + 1, y); });
        if (y > 0) {
            joins(
                z - w,
                z,
                w,
                up.data() + index(0, y),
                [y](int i) { return glm::ivec2(i, y - 1); },
                [y](int i) { return glm::ivec2(i, y); });
        } else {
            std::fill_n(up.data(), w, std::uint8_t(0));
        }
    });
    // The runs of joined pixels along each row, into `out` (in pixels); a run that reaches the
    // image's edge may go on beyond it: unbounded.
    constexpr float kUnbounded = 1e30f;
    parallel_for(0, h, [&](int y) {
        float *row = out.pixel(0, y);
        const std::uint8_t *r = right.data() + index(0, y);
        int start = 0;
        for (int i = 1; i <= w; ++i) {
            if (i < w && r[i - 1] != 0) {
                continue;
            }
            std::fill(row + start, row + i, start == 0 || i == w ? kUnbounded : float(i - start));
            start = i;
        }
    });
    // Along the columns, in bands of columns swept top down (each pixel's count of joined
    // pixels above it in its run, unbounded where the run starts at the top) and bottom up (the
    // count below, carried per column), so that memory is read row by row; then the shorter
    // (narrowest) or the longer (widest) run of the two axes, times the footprint at the pixel's
    // depth.
    constexpr int kBand = 256;
    Image above = Image::uninitialized(w, h, 1);
    parallel_for(0, (w + kBand - 1) / kBand, [&](int band) {
        const int x0 = band * kBand, x1 = std::min(w, x0 + kBand);
        for (int x = x0; x < x1; ++x) {
            above.at(x, 0, 0) = kUnbounded;
        }
        for (int y = 1; y < h; ++y) {
            const std::uint8_t *u = up.data() + index(0, y);
            const float *a0 = above.pixel(0, y - 1);
            float *a1 = above.pixel(0, y);
            for (int x = x0; x < x1; ++x) {
                a1[x] = (a0[x] + 1.0f) * float(u[x]);  // u is 0 or 1: branch-free
            }
        }
        float below[kBand];
        std::fill_n(below, kBand, kUnbounded);
        for (int y = h - 1; y >= 0; --y) {
            const float *z = zs.data() + index(0, y);
            const float *a = above.pixel(0, y);
            float *o = out.pixel(0, y);
            if (y < h - 1) {
                const std::uint8_t *u = up.data() + index(0, y + 1);
                for (int x = x0; x < x1; ++x) {
                    below[x - x0] = (below[x - x0] + 1.0f) * float(u[x]);
                }
            }
            const auto finish = [&](auto pick) {
                for (int x = x0; x < x1; ++x) {
                    const float run = pick(o[x], a[x] + below[x - x0] + 1.0f);
                    const float t = std::min(max_thickness, run * footprint * z[x]);
                    o[x] = z[x] == 0.0f ? 0.0f : t;
                }
            };
            if (extent == SurfaceExtent::widest) {
                finish([](float r, float c) { return std::max(r, c); });
            } else {
                finish([](float r, float c) { return std::min(r, c); });
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
