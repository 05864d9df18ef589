// shading::occluder_thickness: how deep the relight node's shadow march takes each surface to be.

#include "shading/lighting/occluder_thickness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

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
