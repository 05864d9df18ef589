// Tests for the Minecrappy rasterizer: exact data passes on analytic scenes, motion vectors
// against analytic reprojection, watertight edges, a brute-force coverage oracle, thread-count
// independence, determinism, pass requests and ground-truth accumulation.
#include "raster/raster.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "raster/mesh.h"
#include "raster/render.h"

namespace posthaste::raster {
namespace {

const std::set<std::string> kAllPasses = {
    "color", "depth", "normal", "position", "motion", "albedo", "material", "tangent", "id"};

std::string sample(const std::string &name)
{
    return std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/" + name;
}

RenderOptions small(int w, int h, std::set<std::string> passes = kAllPasses)
{
    RenderOptions o;
    o.width = w;
    o.height = h;
    o.passes = std::move(passes);
    return o;
}

// The pinhole ray through pixel centre (x, y), in double, from the camera state alone.
struct Ray {
    glm::dvec3 o, d;
};
Ray pixel_ray(const CameraState &c, int w, int h, int x, int y)
{
    const glm::mat4 m = c.camera_to_world();
    const double sx = double(c.focal_length_mm) / c.sensor_width_mm;
    const double sy = sx * w / h;
    const double u = (x + 0.5) / w, v = (y + 0.5) / h;
    const glm::dvec3 dc((u - 0.5) / sx, (0.5 - v) / sy, 1.0);
    Ray r;
    r.o = glm::dvec3(m[3]);
    r.d = glm::dvec3(m[0]) * dc.x + glm::dvec3(m[1]) * dc.y + glm::dvec3(m[2]) * dc.z;
    return r;
}

void expect_rel(double got, double want, double rel, const std::string &what)
{
    EXPECT_LE(std::abs(got - want), rel * std::max(1.0, std::abs(want))) << what;
}

// Depth, position and normal of an axis-aligned plane hit, checked at every covered pixel.
struct PlaneHit {
    int axis;
    double coord;
    glm::dvec3 normal;
};

void check_planes(const Frame &f,
                  const CameraState &c,
                  const std::vector<PlaneHit> &planes,
                  std::function<int(const glm::dvec3 &)> which)
{
    const Image &depth = f.image("depth"), &pos = f.image("position"), &nrm = f.image("normal");
    const glm::mat4 w2c = *f.camera.world_to_camera;
    int covered = 0;
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            const Ray r = pixel_ray(c, f.width(), f.height(), x, y);
            // Nearest plane whose hit is accepted by `which`.
            double best = std::numeric_limits<double>::infinity();
            int hit = -1;
            for (std::size_t i = 0; i < planes.size(); ++i) {
                const double t = (planes[i].coord - r.o[planes[i].axis]) / r.d[planes[i].axis];
                if (t > 0 && t < best && which(r.o + t * r.d) == int(i)) {
                    best = t;
                    hit = int(i);
                }
            }
            const std::string where = "pixel " + std::to_string(x) + "," + std::to_string(y);
            if (hit < 0) {
                EXPECT_TRUE(std::isinf(depth.at(x, y, 0))) << where;
                continue;
            }
            ++covered;
            const glm::dvec3 p = r.o + best * r.d;
            const double z = double(w2c[0][2]) * p.x + double(w2c[1][2]) * p.y +
                             double(w2c[2][2]) * p.z + double(w2c[3][2]);
            expect_rel(depth.at(x, y, 0), z, 1e-4, where + " Z");
            for (int k = 0; k < 3; ++k) {
                expect_rel(pos.at(x, y, k), p[k], 1e-4, where + " P");
                EXPECT_NEAR(nrm.at(x, y, k), planes[std::size_t(hit)].normal[k], 1e-5) << where;
            }
        }
    }
    EXPECT_GT(covered, 0);
}

// Pixels whose centre ray passes within `margin` of a box edge are ambiguous; the checks below
// skip them by classifying hits with a margin.
bool inside(double v, double lo, double hi, double margin)
{
    return v > lo + margin && v < hi - margin;
}

TEST(RasterAnalytic, CubeExactDepthPositionNormal)
{
    const Scene s = load_scene(sample("cube.json"));
    const Frame f = render_frame(s, 1, small(96, 64, {"depth", "position", "normal"}));
    const CameraState c = s.camera_at(1);
    // Front face z = 20 over [30, 34]^2, 10 m in front of the camera.
    const Image &depth = f.image("depth"), &pos = f.image("position"), &nrm = f.image("normal");
    int covered = 0;
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            const Ray r = pixel_ray(c, f.width(), f.height(), x, y);
            const double t = (20.0 - r.o.z) / r.d.z;
            const glm::dvec3 p = r.o + t * r.d;
            const double m = 1e-3;
            if (inside(p.x, 30, 34, m) && inside(p.y, 30, 34, m)) {
                ++covered;
                expect_rel(depth.at(x, y, 0), 10.0, 1e-4, "Z");
                for (int k = 0; k < 3; ++k) {
                    expect_rel(pos.at(x, y, k), p[k], 1e-4, "P");
                }
                EXPECT_NEAR(nrm.at(x, y, 2), -1.0f, 1e-6);
            } else if (!inside(p.x, 30, 34, -m) || !inside(p.y, 30, 34, -m)) {
                EXPECT_TRUE(std::isinf(depth.at(x, y, 0))) << x << "," << y;
            }
        }
    }
    EXPECT_GT(covered, 100);
}

TEST(RasterAnalytic, PlaneExact)
{
    const Scene s = load_scene(sample("plane.json"));
    const Frame f = render_frame(s, 1, small(80, 60, {"depth", "position", "normal"}));
    check_planes(f, s.camera_at(1), {{1, 1.0, {0, 1, 0}}}, [](const glm::dvec3 &p) {
        return inside(p.x, 0, 64, 1e-3) && inside(p.z, 0, 64, 1e-3) ? 0 : -1;
    });
}

TEST(RasterAnalytic, TwoPlanesExact)
{
    const Scene s = load_scene(sample("two_planes.json"));
    const Frame f = render_frame(s, 1, small(96, 54, {"depth", "position", "normal"}));
    check_planes(
        f, s.camera_at(1), {{2, 20.0, {0, 0, -1}}, {2, 40.0, {0, 0, -1}}}, [](const glm::dvec3 &p) {
            if (std::abs(p.z - 20.0) < 1e-6) {
                return inside(p.x, 0, 32, 1e-3) ? 0 : -1;
            }
            return 1;
        });
}

Scene moving_camera_scene(const std::string &second_key)
{
    return parse_scene(R"({"name": "moving", "world": {"size": [64, 64, 64], "terrain": "none"},
        "materials": [{"id": 1}, {"id": 2}],
        "boxes": [{"min": [0, 0, 40], "max": [64, 64, 41], "material": 1},
                  {"min": [0, 0, 20], "max": [32, 64, 21], "material": 2}],
        "camera": [{"frame": 1, "position": [32, 32, 10], "yaw_deg": 0}, )" +
                           second_key + "]}",
                       "moving.json");
}

void check_motion_against_reprojection(const Scene &s, int frame)
{
    const Frame f = render_frame(s, frame, small(128, 72, {"motion", "position", "depth"}));
    const Image &mv = f.image("motion"), &pos = f.image("position"), &depth = f.image("depth");
    const glm::mat4 cur = *f.camera.world_to_ndc, prev = *f.camera.prev_world_to_ndc;
    double worst = 0.0;
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            if (std::isinf(depth.at(x, y, 0))) {
                continue;
            }
            const glm::vec3 p(pos.at(x, y, 0), pos.at(x, y, 1), pos.at(x, y, 2));
            glm::vec2 a, b;
            ASSERT_TRUE(world_to_pixel(cur, p, f.width(), f.height(), a));
            ASSERT_TRUE(world_to_pixel(prev, p, f.width(), f.height(), b));
            // The current projection is the pixel centre: header and raster agree.
            EXPECT_NEAR(a.x, x + 0.5f, 0.01f);
            EXPECT_NEAR(a.y, y + 0.5f, 0.01f);
            worst = std::max({worst,
                              double(std::abs(mv.at(x, y, 0) - (a.x - b.x))),
                              double(std::abs(mv.at(x, y, 1) - (a.y - b.y)))});
        }
    }
    EXPECT_LE(worst, 0.01);
}

TEST(RasterMotion, CameraTranslation)
{
    const Scene s = moving_camera_scene(R"({"frame": 2, "position": [33.5, 32.4, 10.3]})");
    check_motion_against_reprojection(s, 2);
    // Static camera at frame 1 (clamped keys): no motion at all.
    const Frame f = render_frame(s, 1, small(64, 36, {"motion"}));
    const Image &mv = f.image("motion");
    for (int y = 0; y < 36; ++y) {
        for (int x = 0; x < 64; ++x) {
            EXPECT_EQ(mv.at(x, y, 0), 0.0f);
            EXPECT_EQ(mv.at(x, y, 1), 0.0f);
        }
    }
}

TEST(RasterMotion, CameraRotation)
{
    const Scene s = moving_camera_scene(
        R"({"frame": 2, "position": [32, 32, 10], "yaw_deg": 4, "pitch_deg": 3, "roll_deg": 2})");
    check_motion_against_reprojection(s, 2);
    // Pure yaw to the right: content moves left in the image (negative x motion).
    const Frame f = render_frame(s, 2, small(64, 36, {"motion"}));
    EXPECT_LT(f.image("motion").at(32, 18, 0), -1.0f);
}

TEST(RasterMotion, SkyMovesWithRotationOnly)
{
    const Scene s = parse_scene(R"({"world": {"size": [4, 4, 4], "terrain": "none"},
        "materials": [{"id": 1}],
        "camera": [{"frame": 1, "position": [0, 0, 0]},
                   {"frame": 2, "position": [50, 3, 0], "yaw_deg": 5}]})",
                                "sky.json");
    const Frame f = render_frame(s, 2, small(64, 36, {"motion"}));
    const glm::mat4 cur = *f.camera.world_to_ndc, prev = *f.camera.prev_world_to_ndc;
    const CameraState c = s.camera_at(2);
    for (int y = 0; y < 36; y += 5) {
        for (int x = 0; x < 64; x += 5) {
            const Ray r = pixel_ray(c, 64, 36, x, y);
            const glm::vec4 hc = cur * glm::vec4(glm::vec3(r.d), 0.0f);
            const glm::vec4 hp = prev * glm::vec4(glm::vec3(r.d), 0.0f);
            const float ex = (hc.x / hc.w - hp.x / hp.w) * 64,
                        ey = (hc.y / hc.w - hp.y / hp.w) * 36;
            EXPECT_NEAR(f.image("motion").at(x, y, 0), ex, 0.01f);
            EXPECT_NEAR(f.image("motion").at(x, y, 1), ey, 0.01f);
        }
    }
}

TEST(RasterMotion, ObjectMotion)
{
    // The mover goes +3 m/frame along x; the camera is still.
    const Scene s = load_scene(sample("fast_crossing.json"));
    const Frame f = render_frame(s, 3, small(128, 72, {"motion", "position", "id"}));
    const glm::mat4 cur = *f.camera.world_to_ndc, prev = *f.camera.prev_world_to_ndc;
    int moving = 0;
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            const glm::vec2 m(f.image("motion").at(x, y, 0), f.image("motion").at(x, y, 1));
            if (f.image("id").at(x, y, 0) != 2.0f) {
                EXPECT_EQ(m, glm::vec2(0.0f));
                continue;
            }
            ++moving;
            const glm::vec3 p(f.image("position").at(x, y, 0),
                              f.image("position").at(x, y, 1),
                              f.image("position").at(x, y, 2));
            glm::vec2 a, b;
            ASSERT_TRUE(world_to_pixel(cur, p, f.width(), f.height(), a));
            ASSERT_TRUE(world_to_pixel(prev, p - glm::vec3(3, 0, 0), f.width(), f.height(), b));
            EXPECT_NEAR(m.x, a.x - b.x, 0.01f);
            EXPECT_NEAR(m.y, a.y - b.y, 0.01f);
        }
    }
    EXPECT_GT(moving, 20);
}

// ---- The rasterizer core ------------------------------------------------------------------

// Coverage counts of each triangle rasterized on its own (W = 1 vertices unless given).
std::vector<int> coverage_counts(
    const std::vector<glm::vec4> &v, const std::vector<glm::uvec3> &t, int w, int h, bool cull)
{
    std::vector<int> count(std::size_t(w) * std::size_t(h), 0);
    std::vector<float> keys(count.size());
    std::vector<std::uint32_t> ids(count.size());
    RasterParams rp;
    rp.width = w;
    rp.height = h;
    rp.cull_backfaces = cull;
    for (std::size_t i = 0; i < t.size(); ++i) {
        DrawBatch b{v.data(), &t[i], 1, 0};
        rasterize({b}, rp, {keys.data(), ids.data()});
        for (std::size_t p = 0; p < count.size(); ++p) {
            count[p] += ids[p] == 0 ? 1 : 0;
        }
    }
    return count;
}

TEST(RasterCore, WatertightGridMesh)
{
    // A jittered grid of vertices (sub-pixel coordinates) covering more than the screen: every
    // pixel centre is covered by exactly one triangle.
    const int w = 150, h = 97, nx = 9, ny = 7;
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> jit(-6.0f, 6.0f);
    std::vector<glm::vec4> v;
    for (int j = 0; j <= ny; ++j) {
        for (int i = 0; i <= nx; ++i) {
            float x = -10.0f + (w + 20.0f) * float(i) / nx,
                  y = -10.0f + (h + 20.0f) * float(j) / ny;
            if (i > 0 && i < nx) {
                x += jit(rng);
            }
            if (j > 0 && j < ny) {
                y += jit(rng);
            }
            v.emplace_back(x, y, 1.0f, 1.0f);
        }
    }
    std::vector<glm::uvec3> t;
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
            const unsigned a = unsigned(j * (nx + 1) + i), b = a + 1, c = a + unsigned(nx + 1),
                           d = c + 1;
            // Clockwise in y-up is counter-clockwise on a y-down screen: (a, b, c) has positive
            // area.
            t.emplace_back(a, b, d);
            t.emplace_back(a, d, c);
        }
    }
    const std::vector<int> count = coverage_counts(v, t, w, h, true);
    for (std::size_t p = 0; p < count.size(); ++p) {
        ASSERT_EQ(count[p], 1) << "pixel " << p % w << "," << p / w;
    }
}

TEST(RasterCore, WatertightSphereAroundCamera)
{
    // A closed sphere around a perspective camera, seen from inside: with near-plane clipping
    // and back-face culling, every pixel is covered exactly once.
    Mesh m = mesh_sphere(10.0f, 20, 1);
    for (glm::uvec3 &t : m.triangles) {
        std::swap(t.y, t.z);  // face inward
    }
    CameraState c;
    c.yaw_deg = 23.0f;
    c.pitch_deg = 11.0f;
    c.focal_length_mm = 20.0f;
    const int w = 120, h = 80;
    const CameraMatrices cm = make_camera_matrices(
        c.camera_to_world(), c.focal_length_mm, c.sensor_width_mm, float(w) / h, 0.05f);
    std::vector<glm::vec4> v;
    for (const glm::vec3 &p : m.positions) {
        glm::vec4 q = cm.world_to_ndc * glm::vec4(p, 1.0f);
        v.emplace_back(q.x * w, q.y * h, 1.0f, q.w);
    }
    const std::vector<int> count = coverage_counts(v, m.triangles, w, h, true);
    for (std::size_t p = 0; p < count.size(); ++p) {
        ASSERT_EQ(count[p], 1) << "pixel " << p % w << "," << p / w;
    }
}

// Brute-force oracle: direct edge functions at each pixel centre on the same 8-bit snapped
// coordinates, top-left rule written out as in D3D's rules.
bool oracle_covers(const glm::vec2 *q, int x, int y)
{
    std::int64_t X[3], Y[3];
    for (int i = 0; i < 3; ++i) {
        X[i] = std::llround(double(q[i].x) * 256.0);
        Y[i] = std::llround(double(q[i].y) * 256.0);
    }
    const std::int64_t area = (X[1] - X[0]) * (Y[2] - Y[0]) - (Y[1] - Y[0]) * (X[2] - X[0]);
    if (area == 0) {
        return false;
    }
    if (area < 0) {
        std::swap(X[1], X[2]);
        std::swap(Y[1], Y[2]);
    }
    const std::int64_t px = std::int64_t(x) * 256 + 128, py = std::int64_t(y) * 256 + 128;
    for (int i = 0; i < 3; ++i) {
        const int j = (i + 1) % 3;
        const std::int64_t e = (X[j] - X[i]) * (py - Y[i]) - (Y[j] - Y[i]) * (px - X[i]);
        if (e > 0) {
            continue;
        }
        if (e < 0) {
            return false;
        }
        // On the edge: covered only for a top edge (horizontal, interior below on a y-down
        // screen) or a left edge (interior to its right).
        const bool top = Y[j] == Y[i] && X[j] > X[i];
        const bool left = Y[j] < Y[i];
        if (!top && !left) {
            return false;
        }
    }
    return true;
}

TEST(RasterCore, RandomTrianglesMatchOracle)
{
    const int w = 131, h = 77;
    std::mt19937 rng(1234);
    std::uniform_real_distribution<float> pos(-40.0f, 170.0f);
    std::uniform_int_distribution<int> snap(0, 3);
    std::vector<float> keys(std::size_t(w) * h);
    std::vector<std::uint32_t> ids(keys.size());
    RasterParams rp;
    rp.width = w;
    rp.height = h;
    rp.cull_backfaces = false;
    for (int n = 0; n < 400; ++n) {
        glm::vec2 q[3];
        for (glm::vec2 &p : q) {
            p = glm::vec2(pos(rng), pos(rng) * 0.6f);
            if (snap(rng) == 0) {
                p = glm::round(p) + 0.5f;  // vertices exactly on pixel centres: edge cases
            } else if (snap(rng) == 0) {
                p = glm::round(p);
            }
            p = glm::round(p * 256.0f) / 256.0f;
        }
        if (n % 7 == 0) {
            q[1].y = q[0].y;  // horizontal edges exercise the top rule
        }
        if (n % 11 == 0) {
            q[2].x = q[0].x;  // vertical edges exercise the left rule
        }
        const std::vector<glm::vec4> v = {
            {q[0], 0.5f, 1.0f}, {q[1], 0.5f, 1.0f}, {q[2], 0.5f, 1.0f}};
        const glm::uvec3 t(0, 1, 2);
        rasterize({DrawBatch{v.data(), &t, 1, 0}}, rp, {keys.data(), ids.data()});
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                ASSERT_EQ(ids[std::size_t(y) * w + x] == 0, oracle_covers(q, x, y))
                    << "triangle " << n << " pixel " << x << "," << y;
            }
        }
    }
}

TEST(RasterCore, DepthTestKeepsNearest)
{
    const int w = 64, h = 64;
    std::vector<float> keys(std::size_t(w) * h);
    std::vector<std::uint32_t> ids(keys.size());
    // Two full-screen quads: the far one (key 0.1) submitted after the near one (key 0.5).
    const std::vector<glm::vec4> v = {{-1, -1, 0.5f, 1},
                                      {200, -1, 0.5f, 1},
                                      {-1, 200, 0.5f, 1},
                                      {-1, -1, 0.1f, 1},
                                      {200, -1, 0.1f, 1},
                                      {-1, 200, 0.1f, 1}};
    const std::vector<glm::uvec3> t = {{0, 1, 2}, {3, 4, 5}};
    RasterParams rp;
    rp.width = w;
    rp.height = h;
    rasterize({DrawBatch{v.data(), t.data(), 2, 10}}, rp, {keys.data(), ids.data()});
    for (std::size_t p = 0; p < ids.size(); ++p) {
        ASSERT_EQ(ids[p], 10u);
        ASSERT_FLOAT_EQ(keys[p], 0.5f);
    }
}

TEST(RasterMesh, SphereWindsOutwardAndBoxIsClosed)
{
    const Mesh s = mesh_sphere(2.0f, 16, 1);
    for (const glm::uvec3 &t : s.triangles) {
        const glm::vec3 a = s.positions[t.x], b = s.positions[t.y], c = s.positions[t.z];
        EXPECT_GT(glm::dot(glm::cross(b - a, c - a), a + b + c), 0.0f);
    }
    const Mesh b = mesh_box(glm::vec3(1, 2, 3), glm::vec3(1, 1, 1), 1);
    EXPECT_EQ(b.triangle_count(), 12u);
    for (std::size_t i = 0; i < b.triangles.size(); ++i) {
        const glm::uvec3 t = b.triangles[i];
        const glm::vec3 e =
            glm::cross(b.positions[t.y] - b.positions[t.x], b.positions[t.z] - b.positions[t.x]);
        EXPECT_GT(glm::dot(e, b.normals[t.x]), 0.0f);
    }
}

TEST(RasterMesh, ChunksOnlyExposedFacesAndGreedyKeepsArea)
{
    VoxelGrid g;
    g.nx = g.ny = g.nz = 20;
    g.cells.assign(8000, 0);
    for (int z = 2; z < 18; ++z) {
        for (int x = 2; x < 18; ++x) {
            for (int y = 0; y < 3; ++y) {
                g.set(x, y, z, std::uint8_t(1 + (x > 9)));
            }
        }
    }
    auto area = [](const std::vector<Mesh> &ms) {
        double a = 0;
        std::size_t n = 0;
        for (const Mesh &m : ms) {
            for (const glm::uvec3 &t : m.triangles) {
                a += 0.5 * glm::length(glm::cross(m.positions[t.y] - m.positions[t.x],
                                                  m.positions[t.z] - m.positions[t.x]));
            }
            n += m.triangle_count();
        }
        return std::pair(a, n);
    };
    const auto [a0, n0] = area(mesh_chunks(g, false));
    const auto [a1, n1] = area(mesh_chunks(g, true));
    // 16 x 16 x 3 slab: surface 2 * 256 + 4 * 48 = 704 square metres, whatever the merging.
    EXPECT_NEAR(a0, 704.0, 1e-6);
    EXPECT_NEAR(a1, 704.0, 1e-6);
    EXPECT_EQ(n0, 704u * 2u);
    EXPECT_LT(n1, n0 / 10);
}

// ---- Whole frames ------------------------------------------------------------------------

TEST(RasterFrame, OnlyRequestedPassesAndHeader)
{
    const Scene s = load_scene(sample("cube.json"));
    Frame f = render_frame(s, 1, small(32, 16, {"depth"}));
    EXPECT_EQ(f.pass_names(), std::vector<std::string>{"depth"});
    f = render_frame(s, 1, small(32, 16, {"color", "motion"}));
    EXPECT_EQ(f.pass_names(), (std::vector<std::string>{"color", "motion"}));
    EXPECT_EQ(f.number, 1);
    EXPECT_TRUE(f.camera.world_to_camera && f.camera.world_to_ndc && f.camera.prev_world_to_ndc &&
                f.camera.prev_world_to_camera && f.camera.fstop && f.camera.focus_distance &&
                f.camera.focal_length_mm && f.camera.shutter && f.camera.near_clip);
    EXPECT_EQ(f.attributes.get_string("posthaste:scene"), "cube");
    EXPECT_THROW(render_frame(s, 1, small(32, 16, {"bogus"})), Error);
    RenderOptions bad = small(32, 16);
    bad.supersample = 3;
    EXPECT_THROW(render_frame(s, 1, bad), Error);
    // Color: alpha 1 everywhere, finite.
    const Image &c = f.image("color");
    for (int y = 0; y < 16; ++y) {
        for (int x = 0; x < 32; ++x) {
            EXPECT_EQ(c.at(x, y, 3), 1.0f);
            EXPECT_TRUE(std::isfinite(c.at(x, y, 0)));
        }
    }
}

void expect_frames_equal(const Frame &a, const Frame &b)
{
    ASSERT_EQ(a.pass_names(), b.pass_names());
    for (const std::string &p : a.pass_names()) {
        EXPECT_TRUE(a.image(p).bit_equal(b.image(p))) << p;
    }
}

TEST(RasterFrame, ThreadCountIndependentAndDeterministic)
{
    const Scene s = load_scene(sample("minecrappy.json"));
    RenderOptions o = small(200, 112);
    o.supersample = 2;
    set_thread_count(1);
    const Frame one = render_frame(s, 20, o);
    set_thread_count(7);
    const Frame many = render_frame(s, 20, o);
    set_thread_count(0);
    const Frame again = render_frame(s, 20, o);
    expect_frames_equal(one, many);
    expect_frames_equal(one, again);
}

// The AVX2 beauty (8-lane BRDF and sky light, 4-wide sky LUT) against the scalar shade() on a real
// frame: data passes are shared code and must be the same bits; colour differs by float rounding
// only (and the sky LUT's horizon seam, where one rounding can pick the other half of the table).
TEST(RasterFrame, VectorBeautyMatchesScalar)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    const Scene s = load_scene(sample("minecrappy.json"));
    for (const int ss : {1, 2}) {
        RenderOptions o = small(320, 180);
        o.supersample = ss;
        const Frame vec = render_frame(s, 20, o);
        Frame scalar;
        {
            simd::ScopedLevel level(simd::Level::Scalar);
            scalar = render_frame(s, 20, o);
        }
        for (const std::string &p : vec.pass_names()) {
            if (p != "color") {
                EXPECT_TRUE(vec.image(p).bit_equal(scalar.image(p))) << p;
            }
        }
        const Image &a = vec.image("color"), &b = scalar.image("color");
        double sq = 0.0, ref = 0.0, worst = 0.0;
        int far = 0;
        for (int y = 0; y < a.height(); ++y) {
            for (int x = 0; x < a.width(); ++x) {
                for (int c = 0; c < 4; ++c) {
                    const double d = std::abs(double(a.at(x, y, c)) - double(b.at(x, y, c)));
                    const double rel = d / std::max(1e-3, std::abs(double(b.at(x, y, c))));
                    sq += d * d;
                    ref += double(b.at(x, y, c)) * double(b.at(x, y, c));
                    worst = std::max(worst, rel);
                    far += rel > 1e-5 ? 1 : 0;
                }
            }
        }
        const double rel_rmse = std::sqrt(sq / ref);
        EXPECT_LE(rel_rmse, 1e-6) << "supersample " << ss;
        EXPECT_LE(far, 4) << "supersample " << ss << ": values off by > 1e-5 relative";
        std::printf("supersample %d: relative rmse %.3g, worst relative %.3g, %d over 1e-5\n",
                    ss,
                    rel_rmse,
                    worst,
                    far);
    }
}

// The depth and motion rows are one Highway source compiled without contraction: the CPU's best
// target gives the same bits as the portable one-lane target, also for a width that leaves a
// partial vector at the end of each tile row, and with only one of the two passes.
TEST(RasterFrame, VectorDepthMotionMatchScalar)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    const Scene s = load_scene(sample("minecrappy.json"));
    for (const std::set<std::string> &passes :
         {kAllPasses, std::set<std::string>{"depth"}, std::set<std::string>{"motion"}}) {
        for (const int frame : {7, 20}) {
            const RenderOptions o = small(301, 173, passes);
            const Frame vec = render_frame(s, frame, o);
            Frame scalar;
            {
                simd::ScopedLevel level(simd::Level::Scalar);
                scalar = render_frame(s, frame, o);
            }
            for (const std::string &p : vec.pass_names()) {
                if (p != "color") {
                    EXPECT_TRUE(vec.image(p).bit_equal(scalar.image(p))) << p << " frame " << frame;
                }
            }
        }
    }
}

TEST(RasterFrame, SupersampleAffectsOnlyColor)
{
    const Scene s = load_scene(sample("two_planes.json"));
    RenderOptions o = small(48, 32);
    const Frame a = render_frame(s, 1, o);
    o.supersample = 4;
    const Frame b = render_frame(s, 1, o);
    for (const std::string &p : a.pass_names()) {
        if (p != "color") {
            EXPECT_TRUE(a.image(p).bit_equal(b.image(p))) << p;
        }
    }
    EXPECT_FALSE(a.image("color").bit_equal(b.image("color")));
}

TEST(RasterTruth, ZeroShutterEqualsFrameAndIsDeterministic)
{
    Scene s = load_scene(sample("fast_crossing.json"));
    for (CameraKey &k : s.camera_keys) {
        k.shutter = 0.0f;
    }
    const RenderOptions o = small(64, 36, {"color"});
    TruthOptions t;
    t.samples = 4;
    const Frame truth = render_truth(s, 3, o, t);
    EXPECT_TRUE(truth.image("color").bit_equal(render_frame(s, 3, o).image("color")));
    // With a shutter, the mover smears: different from the still frame, same for any threads.
    for (CameraKey &k : s.camera_keys) {
        k.shutter = 0.5f;
    }
    t.samples = 8;
    t.dof = true;
    set_thread_count(1);
    const Frame a = render_truth(s, 3, o, t);
    set_thread_count(0);
    const Frame b = render_truth(s, 3, o, t);
    EXPECT_TRUE(a.image("color").bit_equal(b.image("color")));
    EXPECT_FALSE(a.image("color").bit_equal(render_frame(s, 3, o).image("color")));
    EXPECT_TRUE(a.camera == render_frame(s, 3, o).camera);
}

TEST(RasterTruth, DofKeepsFocusPlaneSharpAndBlursTheRest)
{
    // Camera 2 m from the near wall (z = 20, left half) and 22 m from the far wall (z = 40),
    // focused on the far wall with a wide aperture: far-wall pixels away from the edge match the
    // pinhole render (only the specular view direction changes), while the near wall's edge
    // (image centre) spreads over about 3 pixels.
    Scene s = load_scene(sample("two_planes.json"));
    for (CameraKey &k : s.camera_keys) {
        k.position = glm::vec3(32.0f, 32.0f, 18.0f);
        k.focus_distance = 22.0f;
        k.fstop = 1.0f;
        k.focal_length_mm = 50.0f;
    }
    RenderOptions o = small(192, 108, {"color"});
    o.shadows = false;
    TruthOptions t;
    t.motion = false;
    t.dof = true;
    t.samples = 64;
    const Image a = render_truth(s, 1, o, t).image("color");
    const Image b = render_frame(s, 1, o).image("color");
    for (int y = 10; y < 98; ++y) {
        for (int x = 110; x < 190; ++x) {
            for (int c = 0; c < 3; ++c) {
                ASSERT_NEAR(a.at(x, y, c), b.at(x, y, c), 0.02f * b.at(x, y, c) + 1e-4f)
                    << x << "," << y;
            }
        }
    }
    float worst = 0.0f;
    for (int x = 90; x < 102; ++x) {
        worst = std::max(worst, std::abs(a.at(x, 54, 0) - b.at(x, 54, 0)));
    }
    EXPECT_GT(worst, 0.05f);
}

TEST(RasterFrame, FramesInParallelShareTheCache)
{
    // Frames rendered concurrently (as a CLI would) build the cached meshes and shadow map once,
    // without deadlocking inside nested parallel loops, and match sequential renders.
    const Scene s = load_scene(sample("minecrappy.json"));
    const RenderOptions o = small(64, 36, {"color", "depth"});
    std::vector<Frame> frames(6);
    parallel_for(0, 6, [&](int i) { frames[std::size_t(i)] = render_frame(s, 1 + i * 8, o); });
    for (int i = 0; i < 6; ++i) {
        expect_frames_equal(frames[std::size_t(i)], render_frame(s, 1 + i * 8, o));
    }
}

}  // namespace
}  // namespace posthaste::raster
