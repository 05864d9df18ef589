// shading::occluder_thickness: how deep the relight node's shadow march takes each surface to be.

#include "shading/lighting/occluder_thickness.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <limits>
#include <string>

namespace posthaste {
namespace {

constexpr int kSize = 16;
constexpr float kFocal = 2.0f;  // NDC per unit of x / z: a pixel is 1 / (16 * 2) wide at depth 1

/// A pinhole looking down +z, camera space = world space: NDC u = 0.5 + f x / z, v likewise.
shading::CameraRays camera()
{
    glm::mat4 m(0.0f);
    m[0][0] = kFocal;
    m[1][1] = kFocal;
    m[2][0] = 0.5f;
    m[2][1] = 0.5f;
    m[2][3] = 1.0f;
    m[3][2] = 1.0f;
    return shading::CameraRays(glm::mat4(1.0f), m);
}

/// A wall at depth 10 facing the camera, with a pole two pixels wide (columns 6-7) at depth 8
/// from row 3 down, and the sky (infinite depth) in row 0.
void scene(Image &depth, Image &normal)
{
    depth = Image(kSize, kSize, 1);
    normal = Image(kSize, kSize, 3);
    for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            const bool pole = (x == 6 || x == 7) && y >= 3;
            depth.at(x, y, 0) = y == 0 ? std::numeric_limits<float>::infinity()
                                : pole ? 8.0f
                                       : 10.0f;
            normal.at(x, y, 2) = -1.0f;  // toward the camera
        }
    }
}

TEST(OccluderThickness, APoleIsAsDeepAsItIsWide)
{
    Image depth, normal;
    scene(depth, normal);
    const float footprint = 1.0f / (kSize * kFocal);
    const Image t = shading::occluder_thickness(depth, normal, camera(), 0.5f);
    // The pole: two columns, down to the image's bottom (its run along the column is open).
    EXPECT_NEAR(t.at(6, 8, 0), 2.0f * footprint * 8.0f, 1e-6f);
    EXPECT_NEAR(t.at(7, 15, 0), 2.0f * footprint * 8.0f, 1e-6f);
    // The wall either side of the pole reaches the image's edges: as deep as the most.
    EXPECT_EQ(t.at(2, 8, 0), 0.5f);
    EXPECT_EQ(t.at(12, 8, 0), 0.5f);
    // Between the sky and the pole's top the wall's column runs are closed: rows 1-2 over
    // columns 6-7 are a run of 2 along the column, as deep as two pixels at depth 10 (0.625),
    // capped at 0.5.
    EXPECT_EQ(t.at(6, 1, 0), 0.5f);
    // The sky occludes nothing.
    EXPECT_EQ(t.at(3, 0, 0), 0.0f);
    // A larger cap: the wall's open runs take it, the pole's closed run does not change.
    const Image big = shading::occluder_thickness(depth, normal, camera(), 4.0f);
    EXPECT_EQ(big.at(2, 8, 0), 4.0f);
    EXPECT_EQ(big.at(6, 8, 0), t.at(6, 8, 0));
    EXPECT_NEAR(big.at(6, 1, 0), 2.0f * footprint * 10.0f, 1e-6f);
}

TEST(OccluderThickness, AGrazingPlaneAndACreaseStayOneSurface)
{
    // A floor seen at a grazing angle: depth grows by a large step from row to row, as its
    // normal says it should; and a crease (two planes meeting at column 8) is continuous. Both
    // are one surface reaching the edges: as deep as the most.
    const shading::CameraRays m = camera();
    Image depth(kSize, kSize, 1), normal(kSize, kSize, 3);
    const float footprint = 1.0f / (kSize * kFocal);
    const float slope = 3.0f;  // depth change per pixel at depth 1 on the floor: tan of 71.6 deg
    for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            // Depth z(y) with dz / z = slope footprint per row, from 5 at the bottom row.
            const float z = 5.0f * std::exp(float(kSize - 1 - y) * slope * footprint);
            depth.at(x, y, 0) = z * (1.0f + 0.002f * std::fabs(float(x) - 8.0f));
            // Normal tilted away from the view ray by atan(slope) about x.
            const float c = 1.0f / std::sqrt(1.0f + slope * slope);
            normal.at(x, y, 1) = -slope * c;
            normal.at(x, y, 2) = -c;
        }
    }
    const Image t = shading::occluder_thickness(depth, normal, m, 0.5f);
    for (int y = 1; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            ASSERT_EQ(t.at(x, y, 0), 0.5f) << x << "," << y;
        }
    }
    // The same depths with normals facing the camera: the steps are silhouettes, each row a
    // surface of its own, one pixel deep.
    Image flat(kSize, kSize, 3);
    for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            flat.at(x, y, 2) = -1.0f;
        }
    }
    const Image rows = shading::occluder_thickness(depth, flat, m, 0.5f);
    EXPECT_NEAR(rows.at(8, 8, 0), footprint * depth.at(8, 8, 0), 1e-5f);
}

TEST(OccluderThickness, NonFiniteAndDegenerateInputGiveBoundedOutput)
{
    Image depth, normal;
    scene(depth, normal);
    depth.at(4, 4, 0) = std::numeric_limits<float>::quiet_NaN();
    depth.at(5, 5, 0) = -1.0f;
    normal.at(9, 9, 0) = std::numeric_limits<float>::infinity();
    normal.at(10, 10, 2) = 0.0f;  // no normal
    const Image t = shading::occluder_thickness(depth, normal, camera(), 0.5f);
    for (int y = 0; y < kSize; ++y) {
        for (int x = 0; x < kSize; ++x) {
            const float v = t.at(x, y, 0);
            ASSERT_TRUE(std::isfinite(v) && v >= 0.0f && v <= 0.5f) << x << "," << y << ": " << v;
        }
    }
    EXPECT_EQ(t.at(4, 4, 0), 0.0f);
    EXPECT_EQ(t.at(5, 5, 0), 0.0f);
    // A degenerate camera: no footprint, every surface as deep as the most.
    const Image s = shading::occluder_thickness(depth, normal, shading::CameraRays(), 0.5f);
    EXPECT_EQ(s.at(6, 8, 0), 0.5f);
}

}  // namespace
}  // namespace posthaste

namespace posthaste {
namespace {

/// The rule occluder_thickness.h states, pixel by pixel: walk each pixel's run along its row
/// and its column while neighbours are joined (a depth step within 1 % of the nearer depth, or
/// within twice the flatter slope's step over a pixel plus 1 %); a run reaching the edge is
/// unbounded.
/// With `stride`, the same over every stride-th pixel (x, y on that grid), and with `widest`
/// the longer of the two runs.
float reference_thickness(const Image &depth,
                          const Image &normal,
                          const shading::CameraRays &rays,
                          float max_thickness,
                          int x,
                          int y,
                          int stride = 1,
                          bool widest = false)
{
    const int fw = depth.width(), fh = depth.height();
    const int w = (fw + stride - 1) / stride, h = (fh + stride - 1) / stride;
    const float footprint =
        0.5f * (glm::length(rays.ray_du()) / float(fw) + glm::length(rays.ray_dv()) / float(fh)) *
        float(stride);
    const auto z_at = [&](int px, int py) {
        const float z = depth.at(px * stride, py * stride, 0);
        return z > 0.0f && std::isfinite(z) ? z : 0.0f;
    };
    const auto tangent = [&](int gx, int gy) {
        const int px = gx * stride, py = gy * stride;
        const glm::vec3 n(normal.at(px, py, 0), normal.at(px, py, 1), normal.at(px, py, 2));
        const glm::vec3 ray =
            rays.depth_ray((float(px) + 0.5f) / float(fw), (float(py) + 0.5f) / float(fh));
        const float nn = glm::length(n) * glm::length(ray);
        if (!(nn > 0.0f) || !std::isfinite(nn)) {
            return 0.0f;
        }
        const float c = std::fabs(glm::dot(n, ray)) / nn;
        const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
        return std::min(s / std::max(c, 0.05f), 20.0f);
    };
    const auto joined = [&](int xa, int ya, int xb, int yb) {
        const float za = z_at(xa, ya), zb = z_at(xb, yb);
        if (za == 0.0f || zb == 0.0f) {
            return false;
        }
        const float z = std::min(za, zb), step = std::fabs(za - zb);
        return step <= 0.01f * z ||
               step <= z * (2.0f * footprint * std::min(tangent(xa, ya), tangent(xb, yb)) + 0.01f);
    };
    const float z = z_at(x, y);
    if (z == 0.0f) {
        return 0.0f;
    }
    const auto run = [&](int dx, int dy) {
        int n = 1;
        bool open = false;
        for (int s = -1; s <= 1; s += 2) {
            int px = x, py = y;
            while (true) {
                const int qx = px + s * dx, qy = py + s * dy;
                if (qx < 0 || qy < 0 || qx >= w || qy >= h) {
                    open = true;
                    break;
                }
                if (!joined(px, py, qx, qy)) {
                    break;
                }
                px = qx;
                py = qy;
                ++n;
            }
        }
        return open ? 1e30f : float(n);
    };
    const float r = widest ? std::max(run(1, 0), run(0, 1)) : std::min(run(1, 0), run(0, 1));
    return std::min(max_thickness, r * footprint * z);
}

TEST(OccluderThickness, EqualsTheRuleWalkedPixelByPixelOnAClutteredFrame)
{
    // Boxes of every size at random depths over a tilted floor, normals tilted at random (some
    // zero, some NaN), sky and bad depths scattered: steps of every kind, joined by depth alone
    // and by slope. The map's row-parallel, branch-free passes must give the walk's bits.
    constexpr int kW = 97, kH = 61;
    Image depth(kW, kH, 1), normal(kW, kH, 3);
    std::uint32_t state = 12345u;
    const auto rnd = [&state] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24);
    };
    for (int y = 0; y < kH; ++y) {
        for (int x = 0; x < kW; ++x) {
            depth.at(x, y, 0) = 4.0f + 40.0f / float(y + 2);  // a floor receding upwards
            const float tilt = rnd();
            normal.at(x, y, 0) = tilt - 0.5f;
            normal.at(x, y, 1) = tilt < 0.1f ? 0.0f : -1.0f;
            normal.at(x, y, 2) = tilt < 0.1f ? 0.0f : -tilt;
            if (tilt > 0.97f) {
                normal.at(x, y, 1) = std::numeric_limits<float>::quiet_NaN();
            }
        }
    }
    for (int b = 0; b < 40; ++b) {
        const int x0 = int(rnd() * kW), y0 = int(rnd() * kH);
        const int bw = 1 + int(rnd() * 12), bh = 1 + int(rnd() * 12);
        const float z = 2.0f + rnd() * 20.0f, slope = (rnd() - 0.5f) * 0.2f;
        for (int y = y0; y < std::min(kH, y0 + bh); ++y) {
            for (int x = x0; x < std::min(kW, x0 + bw); ++x) {
                depth.at(x, y, 0) = z + slope * float(x - x0);
            }
        }
    }
    const float bad[] = {0.0f,
                         -1.0f,
                         std::numeric_limits<float>::infinity(),
                         std::numeric_limits<float>::quiet_NaN()};
    for (int k = 0; k < 60; ++k) {
        depth.at(int(rnd() * kW), int(rnd() * kH), 0) = bad[k % 4];
    }
    // Also over every 2nd and 3rd pixel (an odd size: the last cells hold one pixel), and as
    // deep as the widest run.
    const shading::CameraRays rays = camera();
    for (const float cap : {0.05f, 0.5f, 100.0f}) {
        for (const int stride : {1, 2, 3}) {
            for (const bool widest : {false, true}) {
                const Image t = shading::occluder_thickness(
                    depth,
                    normal,
                    rays,
                    cap,
                    stride,
                    widest ? shading::SurfaceExtent::widest : shading::SurfaceExtent::narrowest);
                const int w = (kW + stride - 1) / stride, h = (kH + stride - 1) / stride;
                ASSERT_EQ(t.width(), w);
                ASSERT_EQ(t.height(), h);
                int mismatches = 0, below_cap = 0;
                for (int y = 0; y < h; ++y) {
                    for (int x = 0; x < w; ++x) {
                        const float want =
                            reference_thickness(depth, normal, rays, cap, x, y, stride, widest);
                        mismatches += t.at(x, y, 0) == want ? 0 : 1;
                        below_cap += want > 0.0f && want < cap ? 1 : 0;
                    }
                }
                const std::string what = "cap " + std::to_string(cap) + ", stride " +
                                         std::to_string(stride) + (widest ? ", widest" : "");
                EXPECT_EQ(mismatches, 0) << what;
                if (cap == 100.0f) {  // every closed run is below this cap
                    EXPECT_GT(below_cap, w * h / (widest ? 100 : 40))
                        << what << ": too few closed runs to test";
                }
            }
        }
    }
}

}  // namespace
}  // namespace posthaste
