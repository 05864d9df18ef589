#include "shading/lighting/occluder_thickness.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <vector>

#include "core/parallel.h"

namespace posthaste::shading {

Image occluder_thickness(const Image &depth,
                         const Image &normal,
                         const CameraRays &rays,
                         float max_thickness)
{
    const int w = depth.width(), h = depth.height();
    Image out = Image::uninitialized(w, h, 1);
    // A pixel's width at depth 1 (a pinhole's footprint grows with depth alone).
    const float footprint =
        0.5f * (glm::length(rays.ray_du()) / float(w) + glm::length(rays.ray_dv()) / float(h));
    const auto z_at = [&](int x, int y) {
        const float z = depth.at(x, y, 0);
        return z > 0.0f && std::isfinite(z) ? z : 0.0f;  // 0: no surface
    };
    if (!(footprint > 0.0f) || !std::isfinite(footprint)) {
        // No footprint (a degenerate camera): every surface as deep as the most.
        parallel_for(0, h, [&](int y) {
            for (int x = 0; x < w; ++x) {
                out.at(x, y, 0) = z_at(x, y) > 0.0f ? max_thickness : 0.0f;
            }
        });
        return out;
    }
    // The tangent of the angle between a pixel's normal and its view ray: how far depth steps
    // from one pixel to the next on a continuous surface (0 without a usable normal: the surface
    // is taken as facing the camera).
    const auto tangent = [&](int x, int y) {
        const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
        const glm::vec3 ray =
            rays.depth_ray((float(x) + 0.5f) / float(w), (float(y) + 0.5f) / float(h));
        const float nn = glm::length(n) * glm::length(ray);
        if (!(nn > 0.0f) || !std::isfinite(nn)) {
            return 0.0f;
        }
        const float c = std::fabs(glm::dot(n, ray)) / nn;
        const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
        return std::min(s / std::max(c, 0.05f), 20.0f);
    };
    // Neighbours a and b lie on one surface when their depths differ by no more than twice what
    // the flatter one's slope gives over a pixel, plus 1 % of the depth (noise, curvature); the
    // slopes are asked for only beside a larger step.
    const auto joined = [&](int xa, int ya, int xb, int yb) {
        const float za = z_at(xa, ya), zb = z_at(xb, yb);
        if (za == 0.0f || zb == 0.0f) {
            return false;
        }
        const float z = std::min(za, zb), step = std::fabs(za - zb);
        if (step <= 0.01f * z) {
            return true;
        }
        return step <= z * (2.0f * footprint * std::min(tangent(xa, ya), tangent(xb, yb)) + 0.01f);
    };
    // The runs of joined pixels along each row, into `out` (in pixels); a run that reaches the
    // image's edge may go on beyond it: unbounded.
    constexpr float kUnbounded = 1e30f;
    parallel_for(0, h, [&](int y) {
        float *row = out.pixel(0, y);
        int start = 0;
        for (int i = 1; i <= w; ++i) {
            if (i < w && joined(i - 1, y, i, y)) {
                continue;
            }
            std::fill(row + start, row + i, start == 0 || i == w ? kUnbounded : float(i - start));
            start = i;
        }
    });
    // Along the columns, in bands of columns swept top down (each pixel's count of joined
    // pixels above it in its run, unbounded where the run starts at the top) and bottom up (the
    // count below, carried per column), so that memory is read row by row; then the shorter run
    // of the two axes, times the footprint at the pixel's depth.
    // (The top-down sweep keeps whether each pixel is joined to the one above it, for the
    // bottom-up one.)
    constexpr int kBand = 64;
    Image above = Image::uninitialized(w, h, 1);
    std::vector<std::uint8_t> up(std::size_t(w) * std::size_t(h));
    const auto index = [w](int x, int y) {
        return std::size_t(y) * std::size_t(w) + std::size_t(x);
    };
    parallel_for(0, (w + kBand - 1) / kBand, [&](int band) {
        const int x0 = band * kBand, x1 = std::min(w, x0 + kBand);
        for (int y = 0; y < h; ++y) {
            for (int x = x0; x < x1; ++x) {
                const bool j = y > 0 && joined(x, y - 1, x, y);
                up[index(x, y)] = j ? 1 : 0;
                above.at(x, y, 0) = j ? above.at(x, y - 1, 0) + 1.0f : y == 0 ? kUnbounded : 0.0f;
            }
        }
        float below[kBand];
        for (int y = h - 1; y >= 0; --y) {
            for (int x = x0; x < x1; ++x) {
                float &b = below[x - x0];
                b = y == h - 1 ? kUnbounded : up[index(x, y + 1)] != 0 ? b + 1.0f : 0.0f;
                const float z = z_at(x, y);
                const float run = std::min(out.at(x, y, 0), above.at(x, y, 0) + b + 1.0f);
                out.at(x, y, 0) = z == 0.0f ? 0.0f : std::min(max_thickness, run * footprint * z);
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
