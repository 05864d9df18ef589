// Ambient occlusion: the exact ray caster (voxels, spheres, moving blocks), the ground truth at
// the foot of a wall against its closed form, GTAO on an analytic floor-and-wall G-buffer (an open
// plane gives 1, the corner its closed form within the screen-space method's error), and the
// node's refusals (no normals, no camera); the ray-traced method on the same G-buffers (the plane,
// the corner, a foreground plate that rays pass behind), its same bits on any thread count.

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "raster/ray_cast.h"
#include "shading/ao/ao_trace.h"
#include "shading/ao/gtao.h"
#include "shading/camera_rays.h"
#include "shading/lighting/occluder_thickness.h"
#include "test_util.h"

namespace posthaste {
namespace {

constexpr float kPi = 3.14159265358979f;

/// A floor (the voxel layer y = 0, its top at y = 1) and a wall filling x >= 20, in a 40^3 grid.
raster::Scene floor_and_wall()
{
    raster::Scene s;
    s.world.nx = s.world.ny = s.world.nz = 40;
    s.world.cells.assign(40 * 40 * 40, 0);
    for (int z = 0; z < 40; ++z) {
        for (int x = 0; x < 40; ++x) {
            s.world.set(x, 0, z, 1);
            for (int y = 0; y < 40; ++y) {
                if (x >= 20) {
                    s.world.set(x, y, z, 1);
                }
            }
        }
    }
    return s;
}

/// Cosine-weighted visibility of a floor point at distance d from an infinite wall, radius r:
/// the directions that reach the wall within r are those whose disc coordinate toward it is at
/// least d / r (Malley's method: cosine-weighted directions project uniformly onto the disc).
double corner_ao(double d, double r)
{
    const double c = std::min(1.0, d / r);
    return 1.0 - (std::acos(c) - c * std::sqrt(1.0 - c * c)) / kPi;
}

TEST(Ao, RayCasterHitsVoxelsSpheresAndBlocks)
{
    raster::Scene s = floor_and_wall();
    raster::Ball ball;
    ball.center = glm::vec3(10.0f, 3.0f, 10.0f);
    ball.radius = 1.0f;
    s.balls.push_back(ball);
    raster::Mover block;
    block.min = glm::vec3(5.0f, 1.0f, 30.0f);
    block.size = glm::vec3(1.0f);
    s.movers.push_back(block);
    const raster::RayScene rays(s, 1.0);
    const glm::vec3 up(0, 1, 0), east(1, 0, 0);
    EXPECT_FALSE(rays.occluded({10.0f, 1.001f, 20.0f}, up, 100.0f));  // open sky
    EXPECT_TRUE(rays.occluded({19.5f, 1.5f, 5.0f}, east, 1.0f));      // the wall at 0.5
    EXPECT_FALSE(rays.occluded({18.5f, 1.5f, 5.0f}, east, 1.0f));     // beyond the radius
    EXPECT_TRUE(rays.occluded({10.0f, 1.001f, 10.0f}, up, 2.0f));     // the ball at 1
    EXPECT_FALSE(rays.occluded({10.0f, 4.0f, 10.0f}, up, 10.0f));     // leaving the ball
    EXPECT_TRUE(rays.occluded({3.0f, 1.5f, 30.5f}, east, 2.5f));      // the block at 2
    EXPECT_FALSE(rays.occluded({6.0f, 1.5f, 30.5f}, east, 10.0f));    // leaving the block
    EXPECT_TRUE(rays.occluded({10.0f, 5.0f, 10.0f}, -up, 10.0f));     // down onto the ball
    EXPECT_TRUE(rays.occluded({-5.0f, 0.5f, 5.0f}, east, 10.0f));     // entering the grid
}

TEST(Ao, TruthAtTheFootOfAWallMatchesTheClosedForm)
{
    const raster::Scene s = floor_and_wall();
    const raster::RayScene rays(s, 1.0);
    for (const double d : {0.1, 0.3, 0.6, 1.5}) {
        double sum = 0.0;
        const int points = 16;
        for (int i = 0; i < points; ++i) {
            sum += raster::ao_truth_at(rays,
                                       glm::vec3(20.0f - float(d), 1.0f, 5.0f + 0.5f * float(i)),
                                       glm::vec3(0, 1, 0),
                                       1.0f,
                                       256,
                                       i,
                                       0,
                                       7);
        }
        EXPECT_NEAR(sum / points, corner_ao(d, 1.0), 0.01) << "d = " << d;
    }
}

/// A G-buffer of the floor y = 0 and the wall x = wall_x seen by a camera at (wall_x - 4, 3, 0)
/// looking along +x and down: depth, world normals and the camera's rays. With `plate`, a thin
/// plate x = 1, 1.8 <= y <= 2.6, |z| <= plate_half_width (facing the camera) hangs between the
/// camera and the floor.
struct AnalyticGBuffer {
    Image depth, normal;
    shading::CameraRays rays;
};

AnalyticGBuffer floor_wall_gbuffer(int w,
                                   int h,
                                   bool wall,
                                   bool plate = false,
                                   bool pole = false,
                                   float plate_half_width = std::numeric_limits<float>::infinity())
{
    const float wall_x = 4.0f;
    glm::mat4 to_world(1.0f);
    // Camera space +Z forward: look along +x, pitched 35 degrees down.
    const float pitch = glm::radians(35.0f);
    const glm::vec3 fwd(std::cos(pitch), -std::sin(pitch), 0.0f);
    const glm::vec3 right(0.0f, 0.0f, -1.0f);
    const glm::vec3 up = glm::cross(fwd, right);
    to_world[0] = glm::vec4(right, 0.0f);
    to_world[1] = glm::vec4(up, 0.0f);
    to_world[2] = glm::vec4(fwd, 0.0f);
    to_world[3] = glm::vec4(0.0f, 3.0f, 0.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(to_world, 24.0f, 36.0f, float(w) / h, 0.1f);
    AnalyticGBuffer g{
        Image(w, h, 1), Image(w, h, 3), shading::CameraRays(m.world_to_camera, m.world_to_ndc)};
    const glm::vec3 cam = g.rays.position();
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec3 r = g.rays.depth_ray((x + 0.5f) / w, (y + 0.5f) / h);  // per unit z
            float best = std::numeric_limits<float>::infinity();
            glm::vec3 n(0.0f);
            if (r.y < 0.0f) {
                best = -cam.y / r.y;
                n = glm::vec3(0, 1, 0);
            }
            if (wall && r.x > 0.0f) {
                const float t = (wall_x - cam.x) / r.x;
                if (t < best) {
                    best = t;
                    n = glm::vec3(-1, 0, 0);
                }
            }
            if (plate && r.x > 0.0f) {
                const float t = (1.0f - cam.x) / r.x, py = cam.y + t * r.y, pz = cam.z + t * r.z;
                if (t < best && py >= 1.8f && py <= 2.6f && std::abs(pz) <= plate_half_width) {
                    best = t;
                    n = glm::vec3(-1, 0, 0);
                }
            }
            if (pole && r.x > 0.0f) {
                const float t = (1.0f - cam.x) / r.x, py = cam.y + t * r.y, pz = cam.z + t * r.z;
                if (t < best && py >= 0.0f && py <= 2.6f && std::abs(pz) <= 0.04f) {
                    best = t;
                    n = glm::vec3(-1, 0, 0);
                }
            }
            g.depth.at(x, y, 0) = best;
            for (int c = 0; c < 3; ++c) {
                g.normal.at(x, y, c) = n[c];
            }
        }
    }
    return g;
}

/// The node's pipeline on an analytic G-buffer: the estimate, the denoise, the upsample.
Image gtao_denoised(const AnalyticGBuffer &g, const shading::GtaoParams &p)
{
    const Image ao_depth = shading::gtao_depth(g.depth, p.stride);
    const Image ao = shading::gtao_denoise(shading::gtao(g.depth, g.normal, g.rays, p), ao_depth);
    return shading::gtao_upsample(ao, ao_depth, g.depth, p.stride);
}

/// The node's pipeline with the ray-traced method.
Image trace_denoised(const AnalyticGBuffer &g, const shading::AoTraceParams &p)
{
    const Image ao_depth = shading::gtao_depth(g.depth, p.stride);
    const Image ao =
        shading::gtao_denoise(shading::ao_trace(g.depth, g.normal, g.rays, p), ao_depth);
    return shading::gtao_upsample(ao, ao_depth, g.depth, p.stride);
}

/// GTAO's mean over the open floor of floor_wall_gbuffer (the slices' spread on the screen; see
/// GtaoIsOneOnAnOpenPlaneAndFollowsTheCorner).
constexpr double kOpenPlaneMean = 1.013;

/// Mean AO of the lower half of the frame (the open floor, seen from above).
double floor_mean(const Image &ao)
{
    double sum = 0.0;
    int n = 0;
    for (int y = ao.height() / 2; y < ao.height(); ++y) {
        for (int x = 0; x < ao.width(); ++x) {
            EXPECT_TRUE(std::isfinite(ao.at(x, y, 0)));
            sum += ao.at(x, y, 0);
            ++n;
        }
    }
    return sum / n;
}

/// Floor pixels (the middle half of the columns) at distance [d0, d1) from the wall's foot:
/// their mean AO against the mean of the closed form (the estimate is noisy per pixel; the
/// depth buffer sees the whole wall). Expects enough pixels in the band.
void expect_corner_band(const AnalyticGBuffer &g, const Image &ao, double d0, double d1)
{
    const int w = ao.width(), h = ao.height();
    const glm::vec3 cam = g.rays.position();
    double got = 0.0, want = 0.0;
    int count = 0;
    for (int y = 0; y < h; ++y) {
        for (int x = w / 4; x < 3 * w / 4; ++x) {
            if (g.normal.at(x, y, 1) != 1.0f) {
                continue;
            }
            const glm::vec3 pt =
                cam + g.depth.at(x, y, 0) * g.rays.depth_ray((x + 0.5f) / w, (y + 0.5f) / h);
            const double d = 4.0 - pt.x;
            if (d >= d0 && d < d1) {
                got += ao.at(x, y, 0);
                want += corner_ao(d, 1.0);
                ++count;
            }
        }
    }
    ASSERT_GT(count, 50) << d0;
    EXPECT_NEAR(got / count, want / count, 0.06) << "band from " << d0 << " m";
}

TEST(Ao, GtaoIsOneOnAnOpenPlaneAndFollowsTheCorner)
{
    shading::GtaoParams p;
    p.radius = 1.0f;
    p.slices = 4;
    p.steps = 16;
    // No occluder: the estimate's mean is 1 but for the slices' spread. They are spread evenly
    // on the screen, which away from the image's centre is not even about the view vector: on
    // this wide lens (73 degrees) the open floor's mean is 1.013 before the node's clamp. Spread
    // evenly about the view vector it is 1.000, but that measured worse on every bench scene
    // (docs/ACCURACY.md); the per-pixel rule is GtaoNeighboursOnTheTangentPlaneHideNothing.
    EXPECT_NEAR(
        floor_mean(gtao_denoised(floor_wall_gbuffer(320, 240, false), p)), kOpenPlaneMean, 0.003);
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, true);
    const Image ao = gtao_denoised(g, p);
    for (const double d0 : {0.0, 0.25, 0.5, 0.75}) {
        expect_corner_band(g, ao, d0, d0 + 0.25);
    }
}

// A neighbour on the same plane hides nothing, whichever way the pixel grid rounds it off the
// slice: each pixel's AO on the open floor equals its AO with no neighbour at all (the horizons
// then stay at the tangent plane). Pixels 32 apart with a search of at most 12 pixels see none
// of each other. Before samples kept their elevation, a pixel here came out up to 0.047 below its
// open value with one slice and 0.003 with two.
TEST(Ao, GtaoNeighboursOnTheTangentPlaneHideNothing)
{
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, false);
    AnalyticGBuffer alone = g;
    alone.depth = Image(320, 240, 1);
    for (int y = 0; y < 240; ++y) {
        for (int x = 0; x < 320; ++x) {
            alone.depth.at(x, y, 0) = x % 32 == 16 && y % 32 == 16
                                          ? g.depth.at(x, y, 0)
                                          : std::numeric_limits<float>::infinity();
        }
    }
    for (const int slices : {1, 2}) {
        shading::GtaoParams p;
        p.slices = slices;
        p.steps = 8;
        p.max_radius_px = 12.0f;
        const Image ao = shading::gtao(g.depth, g.normal, g.rays, p);
        const Image open = shading::gtao(alone.depth, alone.normal, alone.rays, p);
        int n = 0;
        float worst = 0.0f;
        for (int y = 16; y < 240; y += 32) {
            for (int x = 16; x < 320; x += 32) {
                if (std::isfinite(g.depth.at(x, y, 0))) {
                    ASSERT_NE(open.at(x, y, 0), 1.0f) << "the pixel was not estimated";
                    worst = std::max(worst, std::abs(ao.at(x, y, 0) - open.at(x, y, 0)));
                    ++n;
                }
            }
        }
        ASSERT_GT(n, 30);
        EXPECT_LT(worst, 1e-4f) << slices << " slice(s)";
    }
}

// The bitmask's sectors: on the open plane nothing is hidden; at the foot of the wall (its face
// visible, the wall solid behind it) a thickness of 1 m hides what the horizons hide; a thickness
// of 0.1 mm hides almost nothing, so the floor by the wall reads nearly open.
TEST(Ao, BitmaskIsOneOnAnOpenPlaneAndFollowsTheCornerWithThickness)
{
    shading::GtaoParams p;
    p.slices = 4;
    p.steps = 16;
    p.thickness = 1.0f;
    EXPECT_NEAR(floor_mean(gtao_denoised(floor_wall_gbuffer(320, 240, false), p)), 1.0, 0.01);
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, true);
    const Image ao = gtao_denoised(g, p);
    for (const double d0 : {0.0, 0.25, 0.5, 0.75}) {
        expect_corner_band(g, ao, d0, d0 + 0.25);
    }
    p.thickness = 1e-4f;
    const Image thin = gtao_denoised(g, p);
    double sum = 0.0;
    int n = 0;
    for (int y = 0; y < 240; ++y) {
        for (int x = 80; x < 240; ++x) {
            const glm::vec3 pt =
                g.rays.position() +
                g.depth.at(x, y, 0) * g.rays.depth_ray((x + 0.5f) / 320, (y + 0.5f) / 240);
            if (g.normal.at(x, y, 1) == 1.0f && pt.x > 3.75f) {
                sum += thin.at(x, y, 0);
                ++n;
            }
        }
    }
    ASSERT_GT(n, 50);
    EXPECT_GT(sum / n, 0.95) << "closed form there about " << corner_ao(0.125, 1.0);
}

TEST(Ao, HalfResolutionKeepsThePlaneAndTheCorner)
{
    shading::GtaoParams p;
    p.slices = 4;
    p.steps = 16;
    p.stride = 2;
    const AnalyticGBuffer open = floor_wall_gbuffer(320, 240, false);
    const Image low = shading::gtao(open.depth, open.normal, open.rays, p);
    EXPECT_EQ(low.width(), 160);
    EXPECT_EQ(low.height(), 120);
    const Image up = gtao_denoised(open, p);
    ASSERT_EQ(up.width(), 320);
    EXPECT_NEAR(floor_mean(up), kOpenPlaneMean, 0.003);
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, true);
    expect_corner_band(g, gtao_denoised(g, p), 0.25, 0.5);
}

TEST(Ao, TraceIsOneOnAnOpenPlaneAndFollowsTheCorner)
{
    shading::AoTraceParams p;
    p.rays = 64;
    p.steps = 32;
    // No occluder: every ray stays open, the pixel's own plane never occludes it.
    const AnalyticGBuffer open = floor_wall_gbuffer(320, 240, false);
    const Image flat = shading::ao_trace(open.depth, open.normal, open.rays, p);
    for (int y = 0; y < flat.height(); ++y) {
        for (int x = 0; x < flat.width(); ++x) {
            ASSERT_EQ(flat.at(x, y, 0), 1.0f) << x << ", " << y;
        }
    }
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, true);
    const Image ao = trace_denoised(g, p);
    for (const double d0 : {0.0, 0.25, 0.5, 0.75}) {
        expect_corner_band(g, ao, d0, d0 + 0.25);
    }
    p.stride = 2;
    expect_corner_band(g, trace_denoised(g, p), 0.25, 0.5);
}

/// The mean AO over the floor pixels with world x in [1.6, 2.4) (beyond a plate or pole at x = 1)
/// and |z| < z_max, each of them finite; at least `min_pixels` of them.
double floor_band(const AnalyticGBuffer &g, const Image &ao, float z_max, int min_pixels)
{
    const int w = g.depth.width(), h = g.depth.height();
    double sum = 0.0;
    int n = 0;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const glm::vec3 pt =
                g.rays.position() +
                g.depth.at(x, y, 0) * g.rays.depth_ray((x + 0.5f) / w, (y + 0.5f) / h);
            if (g.normal.at(x, y, 1) == 1.0f && pt.x >= 1.6f && pt.x < 2.4f &&
                std::abs(pt.z) < z_max) {
                EXPECT_TRUE(std::isfinite(ao.at(x, y, 0)));
                sum += ao.at(x, y, 0);
                ++n;
            }
        }
    }
    EXPECT_GT(n, min_pixels);
    return sum / std::max(n, 1);
}

// Floor pixels seen below a hanging plate, more than the radius from it (1.9 m at least): nothing
// occludes them. Rays rising from them pass behind the plate on screen; with a thickness below
// their depth behind it they stay open (AO 1, as the truth), with an unbounded one the plate's
// shadow appears on the floor (the halo of the depth buffer's infinite-thickness reading).
TEST(Ao, TraceThicknessLetsRaysPassBehindAForegroundPlate)
{
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, false, true);
    const auto floor_ao = [&](const Image &ao) { return floor_band(g, ao, 1e30f, 200); };
    shading::AoTraceParams p;
    p.rays = 36;
    p.steps = 32;
    p.thickness = 0.3f;
    EXPECT_GT(floor_ao(shading::ao_trace(g.depth, g.normal, g.rays, p)), 0.995);
    p.thickness = 1e6f;
    EXPECT_LT(floor_ao(shading::ao_trace(g.depth, g.normal, g.rays, p)), 0.95);
}

// A pole 8 cm wide standing on the floor at x = 1 (the plate's plane), seen face-on. Floor
// pixels beside and behind it, more than 0.6 m away: it hides little of their sky, but rays
// rising from them pass behind it on screen. With every surface 1 m deep they find it in their
// way; with the pole as deep as it is wide on screen (shading::occluder_thickness) only the rays
// that meet it do.
TEST(Ao, TraceWithOccludersAsDeepAsWideLetsRaysPassBehindAPole)
{
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, false, false, true);
    const auto floor_ao = [&](const Image &ao) { return floor_band(g, ao, 0.5f, 100); };
    shading::AoTraceParams p;
    p.rays = 36;
    p.steps = 32;
    p.thickness = 1.0f;
    const double constant = floor_ao(shading::ao_trace(g.depth, g.normal, g.rays, p));
    const Image occluder = shading::occluder_thickness(g.depth, g.normal, g.rays, p.thickness);
    p.occluder = &occluder;
    const double extent = floor_ao(shading::ao_trace(g.depth, g.normal, g.rays, p));
    std::printf("floor behind a pole: AO %.4f with every surface 1 m deep, %.4f as deep as wide\n",
                constant,
                extent);
    // Measured: 0.9497 and 1.0000 (the few rays that truly meet the pole step over its 8 cm).
    EXPECT_LT(constant, 0.96);
    EXPECT_GT(extent, 0.99);
}

// The bitmask reads a thickness map at each sample's pixel: a map holding the constant everywhere
// gives the constant's bits (on every Highway target), and the pole's own thickness opens the
// floor behind it.
TEST(Ao, BitmaskReadsEachSamplesThicknessFromAMap)
{
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, true, false, true);
    shading::GtaoParams p;
    p.slices = 4;
    p.steps = 16;
    p.thickness = 1.0f;
    Image same(320, 240, 1);
    same.fill(1.0f);
    test::for_each_highway_target([&](const char *target) {
        const Image constant = shading::gtao(g.depth, g.normal, g.rays, p);
        p.thickness_map = &same;
        EXPECT_TRUE(shading::gtao(g.depth, g.normal, g.rays, p).bit_equal(constant)) << target;
        p.thickness_map = nullptr;
    });
    const Image occluder = shading::occluder_thickness(g.depth, g.normal, g.rays, 1.0f);
    const Image constant = shading::gtao(g.depth, g.normal, g.rays, p);
    p.thickness_map = &occluder;
    const Image extent = shading::gtao(g.depth, g.normal, g.rays, p);
    // Floor pixels 0.6-1.4 m behind the pole and within 0.5 m of its plane.
    const double near_c = floor_band(g, constant, 0.5f, 100),
                 near_e = floor_band(g, extent, 0.5f, 100);
    std::printf(
        "bitmask, floor behind a pole: AO %.4f with every surface 1 m deep, %.4f as deep "
        "as wide\n",
        near_c,
        near_e);
    EXPECT_GT(near_e, near_c + 0.02);
}

// Reachable crossings. At the foot of the wall the wall reaches back as far as any crossing
// needs: the closed form's bands as before. Below the hanging plate (0.8 m square, more than the
// radius above the floor) a sample on the floor and the next one on the plate are within twice
// the radius, and the straight surface between them, which is not there, darkened the floor; the
// plate, reaching back no farther than it is wide, does not reach the floor's depth, so with
// reachable crossings the floor under it reads open.
TEST(Ao, ReachableCrossingsKeepTheCornerAndDropTheJumpToAPlateAbove)
{
    shading::GtaoParams p;
    p.radius = 1.0f;
    p.slices = 4;
    p.steps = 16;
    const auto reach = [](const AnalyticGBuffer &g) {
        return shading::occluder_thickness(
            g.depth, g.normal, g.rays, 2.0f, 1, shading::SurfaceExtent::widest);
    };
    const AnalyticGBuffer wall = floor_wall_gbuffer(320, 240, true);
    const Image wall_map = reach(wall);
    p.reach_map = &wall_map;
    const Image corner = gtao_denoised(wall, p);
    for (const double d0 : {0.0, 0.25, 0.5, 0.75}) {
        expect_corner_band(wall, corner, d0, d0 + 0.25);
    }
    const AnalyticGBuffer g = floor_wall_gbuffer(320, 240, false, true, false, 0.4f);
    const Image plate_map = reach(g);
    p.reach_map = &plate_map;
    const Image reachable = gtao_denoised(g, p);
    p.reach_map = nullptr;
    const Image all = gtao_denoised(g, p);
    const double under_all = floor_band(g, all, 0.3f, 200),
                 under_reachable = floor_band(g, reachable, 0.3f, 200);
    std::printf("floor under a plate: AO %.4f with every crossing, %.4f with reachable ones\n",
                under_all,
                under_reachable);
    EXPECT_GT(under_reachable, under_all + 0.01);
    EXPECT_GT(under_reachable, 0.98);
    // A map of another grid than map_stride's is refused.
    p.reach_map = &plate_map;
    p.map_stride = 2;
    EXPECT_THROW(shading::gtao(g.depth, g.normal, g.rays, p), Error);
}

// The farm's CPUs (AVX2 and AVX-512 nodes) give the same bits: GTAO's horizons, the bitmask and
// the gated crossings. (SSE4 and the one-lane target have no FMA: their MulAdd rounds twice.)
TEST(Ao, GtaoGivesTheSameBitsOnAvx2AndAvx512)
{
    // An odd size, so that the half-resolution maps' last cells hold one pixel and samples at
    // the last column and row round to them (mode 3, the node's default at half resolution).
    const AnalyticGBuffer g = floor_wall_gbuffer(161, 121, true, true, true);
    const Image map = shading::occluder_thickness(g.depth, g.normal, g.rays, 2.0f);
    const Image half = shading::occluder_thickness(
        g.depth, g.normal, g.rays, 2.0f, 2, shading::SurfaceExtent::widest);
    for (const int mode : {0, 1, 2, 3}) {
        shading::GtaoParams p;
        p.thickness = mode == 1 ? 1.0f : 0.0f;
        p.thickness_map = mode == 1 ? &map : nullptr;
        p.reach_map = mode == 2 ? &map : mode == 3 ? &half : nullptr;
        p.stride = mode == 3 ? 2 : 1;
        p.map_stride = mode == 3 ? 2 : 1;
        std::vector<std::pair<std::string, Image>> out;
        test::for_each_highway_target([&](const char *target) {
            const std::string t = target;
            if (t == "AVX2" || t == "AVX-512") {
                out.emplace_back(t, shading::gtao(g.depth, g.normal, g.rays, p));
            }
        });
        if (out.size() == 2) {
            EXPECT_TRUE(out[0].second.bit_equal(out[1].second)) << "mode " << mode;
        }
    }
}

TEST(Ao, TraceGivesTheSameBitsOnAnyThreadCount)
{
    const AnalyticGBuffer g = floor_wall_gbuffer(97, 61, true, true);
    shading::AoTraceParams p;
    p.rays = 9;
    const int before = thread_count();
    set_thread_count(1);
    const Image one = shading::ao_trace(g.depth, g.normal, g.rays, p);
    set_thread_count(2);
    const Image two = shading::ao_trace(g.depth, g.normal, g.rays, p);
    set_thread_count(before);
    EXPECT_TRUE(one.bit_equal(two));
}

// The upsample is one Highway source compiled without contraction: the CPU's best target and
// the portable one-lane target give the same bits (odd widths leave a partial vector, stride 3
// uneven bilinear weights, sky and NaN depths take their own branches), and a pixel between two
// reduced pixels on the same surface is their bilinear blend, computed by hand.
TEST(Ao, UpsampleIsTheSameOnEveryTargetAndBlendsByHand)
{
    for (const int stride : {2, 3}) {
        const AnalyticGBuffer g = floor_wall_gbuffer(161, 37, true);
        Image depth = g.depth;
        depth.at(5, 3, 0) = std::numeric_limits<float>::quiet_NaN();
        depth.at(160, 36, 0) = std::numeric_limits<float>::infinity();
        const Image ao_depth = shading::gtao_depth(depth, stride);
        Image ao(ao_depth.width(), ao_depth.height(), 1);
        for (int y = 0; y < ao.height(); ++y) {
            for (int x = 0; x < ao.width(); ++x) {
                ao.at(x, y, 0) = 0.3f + 0.01f * float((x * 7 + y * 13) % 50);
            }
        }
        const Image best = shading::gtao_upsample(ao, ao_depth, depth, stride);
        Image portable;
        {
            simd::ScopedLevel level(simd::Level::Scalar);
            portable = shading::gtao_upsample(ao, ao_depth, depth, stride);
        }
        EXPECT_TRUE(best.bit_equal(portable)) << "stride " << stride;
        EXPECT_EQ(best.at(5, 3, 0), 1.0f);     // NaN depth: no surface
        EXPECT_EQ(best.at(160, 36, 0), 1.0f);  // sky
    }
    // Hand check on a flat depth (every tap on the surface, tent weight 1): pixel (1, 0) at
    // stride 2 lies halfway between reduced pixels 0 and 1 of row 0: (a0 + a1) / 2.
    Image depth(8, 4, 1), ao_depth(4, 2, 1), ao(4, 2, 1);
    depth.fill(2.0f);
    ao_depth.fill(2.0f);
    for (int x = 0; x < 4; ++x) {
        ao.at(x, 0, 0) = 0.2f * float(x + 1);
        ao.at(x, 1, 0) = 0.9f;
    }
    const Image up = shading::gtao_upsample(ao, ao_depth, depth, 2);
    EXPECT_FLOAT_EQ(up.at(1, 0, 0), 0.5f * (0.2f + 0.4f));
    EXPECT_FLOAT_EQ(up.at(0, 0, 0), 0.2f);
    EXPECT_FLOAT_EQ(up.at(0, 1, 0), 0.5f * (0.2f + 0.9f));
}

TEST(Ao, NodeNamesWhatIsMissing)
{
    Frame f = test::make_sample_frame(32, 24, 1);
    const Frame out = test::run_node("ao", f, "{}");
    ASSERT_TRUE(out.has("ao"));
    EXPECT_EQ(out.pass("color").image, f.pass("color").image);  // apply: none
    const Frame dark = test::run_node("ao", f, R"({"apply": "multiply"})");
    EXPECT_NE(dark.pass("color").image, f.pass("color").image);
    Frame no_normal = f;
    no_normal.erase("normal");
    try {
        test::run_node("ao", no_normal, "{}");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("normal"), std::string::npos) << e.what();
    }
    Frame no_camera = f;
    no_camera.camera = Camera{};
    try {
        test::run_node("ao", no_camera, "{}");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("worldTo"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace posthaste
