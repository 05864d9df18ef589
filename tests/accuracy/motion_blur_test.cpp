// motion_blur: hand-checkable cases against an analytic moving edge, the failure cases (finite,
// bounded output and their error), bit-exact zero motion, thread-count independence, camera
// reprojection against the rasterizer's motion pass; and (MotionBlurAccuracySlow) RMSE / PSNR
// against accumulated ground truth beside doing nothing and the seeds' uniform camera blur.

#include "shading/motion_blur/motion_blur.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "core/hash.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "graph/graph.h"
#include "metrics/metrics.h"
#include "nodes/registry.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/motion_blur/motion_blur_gather.h"
#include "shading/motion_blur/reproject.h"
#include "shading/tiles.h"
#include "test_util.h"

namespace posthaste {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

// A block [bx0, bx1) x all rows, depth 5, moving `speed` px/frame in x, over a static uniform
// background at depth 10 (or sky when bg_sky). Colors: block (1, 0.2, 0.1, 1), bg (0.2, 0.3,
// 0.4, 1).
struct Scene1D {
    Image color, motion, depth;
};

const float kBlock[4] = {1.0f, 0.2f, 0.1f, 1.0f};
const float kBg[4] = {0.2f, 0.3f, 0.4f, 1.0f};

Scene1D moving_block(int w, int h, int bx0, int bx1, float speed, bool bg_sky = false)
{
    Scene1D s{Image(w, h, 4), Image(w, h, 2), Image(w, h, 1)};
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const bool in = x >= bx0 && x < bx1;
            for (int c = 0; c < 4; ++c) {
                s.color.at(x, y, c) = in ? kBlock[c] : kBg[c];
            }
            s.motion.at(x, y, 0) = in ? speed : 0.0f;
            s.depth.at(x, y, 0) = in ? 5.0f : (bg_sky ? kInf : 10.0f);
        }
    }
    return s;
}

// The exact time average over a centred shutter: the block covers pixel centre xc while
// bx0 + tau <= xc < bx1 + tau, tau uniform in [-L, L], L = speed * shutter / 2.
Image moving_block_truth(int w, int h, int bx0, int bx1, float speed, float shutter)
{
    Image out(w, h, 4);
    const double L = double(speed) * shutter / 2.0;
    for (int x = 0; x < w; ++x) {
        const double xc = x + 0.5;
        double cov;
        if (L <= 0.0) {
            cov = (xc >= bx0 && xc < bx1) ? 1.0 : 0.0;
        } else {
            const double lo = std::max(-L, xc - bx1), hi = std::min(L, xc - bx0);
            cov = std::max(0.0, hi - lo) / (2.0 * L);
        }
        for (int y = 0; y < h; ++y) {
            for (int c = 0; c < 4; ++c) {
                out.at(x, y, c) = float(cov * kBlock[c] + (1.0 - cov) * kBg[c]);
            }
        }
    }
    return out;
}

double rmse(const Image &a, const Image &b)
{
    return metrics::compare(a, b).all.rms_error;
}

// Every value finite and within the input's range per channel (a convex combination of input
// pixels), with float slack.
void expect_bounded(const Image &in, const Image &out, const std::string &what)
{
    ASSERT_EQ(in.channels(), out.channels());
    for (int c = 0; c < in.channels(); ++c) {
        float lo = kInf, hi = -kInf;
        for (int y = 0; y < in.height(); ++y) {
            for (int x = 0; x < in.width(); ++x) {
                lo = std::min(lo, in.at(x, y, c));
                hi = std::max(hi, in.at(x, y, c));
            }
        }
        int bad = 0;
        for (int y = 0; y < out.height(); ++y) {
            for (int x = 0; x < out.width(); ++x) {
                const float v = out.at(x, y, c);
                const float slack = 1e-5f * std::max(1.0f, std::abs(v));
                if (!std::isfinite(v) || v < lo - slack || v > hi + slack) {
                    if (bad++ == 0) {
                        ADD_FAILURE() << what << ": channel " << c << " at (" << x << ", " << y
                                      << ") = " << v << " outside [" << lo << ", " << hi << "]";
                    }
                }
            }
        }
        EXPECT_EQ(bad, 0) << what;
    }
}

// The share of pixels of `a` with a channel off from `ref` by more than 1e-3 (relative above 1):
// how the vector rows and the reference are compared.
double fraction_off(const Image &a, const Image &ref)
{
    int off = 0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int c = 0; c < a.channels(); ++c) {
                const float v = ref.at(x, y, c);
                if (std::abs(a.at(x, y, c) - v) > 1e-3f * std::max(1.0f, std::abs(v))) {
                    ++off;
                    break;
                }
            }
        }
    }
    return double(off) / (double(a.width()) * a.height());
}

TEST(MotionBlurTiles, TileAndNeighbourMaxKeepTheLongestVector)
{
    Image f(8, 4, 2);
    f.at(1, 1, 0) = 3.0f;   // tile (0, 0), length 3
    f.at(2, 0, 1) = -2.0f;  // tile (0, 0), shorter
    f.at(6, 3, 0) = kNaN;   // tile (1, 0): ignored
    f.at(5, 2, 1) = 1.0f;
    const Image t = shading::tile_max(f, 4);
    ASSERT_EQ(t.width(), 2);
    ASSERT_EQ(t.height(), 1);
    EXPECT_EQ(t.at(0, 0, 0), 3.0f);
    EXPECT_EQ(t.at(0, 0, 1), 0.0f);
    EXPECT_EQ(t.at(1, 0, 0), 0.0f);
    EXPECT_EQ(t.at(1, 0, 1), 1.0f);
    const Image n = shading::neighbour_max(t, 1);
    EXPECT_EQ(n.at(1, 0, 0), 3.0f);
    const Image n0 = shading::neighbour_max(t, 0);
    EXPECT_EQ(n0.at(1, 0, 1), 1.0f);
}

TEST(MotionBlurTiles, ReachLimitedNeighbourMaxKeepsOnlyVectorsThatCanReach)
{
    // Tile 0 moves 40 px (reaches 3 tiles of 16 px), tile 5 moves 4 px (reaches 1).
    Image tiles(6, 1, 2);
    tiles.at(0, 0, 0) = 40.0f;
    tiles.at(5, 0, 0) = 4.0f;
    const Image reach = shading::neighbour_max_reach(tiles, 16, 0, 5);
    const Image all = shading::neighbour_max(tiles, 5);
    for (int x = 0; x < 6; ++x) {
        EXPECT_EQ(all.at(x, 0, 0), 40.0f) << x;
        EXPECT_EQ(reach.at(x, 0, 0), x <= 3 ? 40.0f : 4.0f) << x;
    }
    // One tile of margin (the jittered lookup) lets tile 0 count at tile 4 too.
    EXPECT_EQ(shading::neighbour_max_reach(tiles, 16, 1, 5).at(4, 0, 0), 40.0f);
    Image bounds(6, 1, 4);
    for (int x = 0; x < 6; ++x) {
        const float v = tiles.at(x, 0, 0);
        bounds.at(x, 0, 0) = bounds.at(x, 0, 2) = v;
    }
    const Image nb = shading::neighbour_bounds_reach(bounds, tiles, 16, 0, 5);
    EXPECT_EQ(nb.at(3, 0, 2), 40.0f);  // max x
    EXPECT_EQ(nb.at(4, 0, 2), 4.0f);
    EXPECT_EQ(nb.at(4, 0, 0), 0.0f);  // min x: tiles 1-3 are still
}

TEST(MotionBlur, ZeroMotionGivesTheInputBitForBit)
{
    Scene1D s = moving_block(97, 13, 30, 50, 0.0f);
    s.color.at(3, 3, 0) = 1e30f;  // odd values survive untouched
    shading::MotionBlurOptions o;
    EXPECT_TRUE(shading::motion_blur(s.color, s.motion, s.depth, o).bit_equal(s.color));
    // Moving pixels with a zero shutter, or a zero max radius, are zero motion too.
    s = moving_block(97, 13, 30, 50, 40.0f);
    o.shutter = 0.0f;
    EXPECT_TRUE(shading::motion_blur(s.color, s.motion, s.depth, o).bit_equal(s.color));
    o.shutter = 0.5f;
    o.max_radius = 0.0f;
    EXPECT_TRUE(shading::motion_blur(s.color, s.motion, s.depth, o).bit_equal(s.color));
    o.method = shading::BlurMethod::Uniform;
    o.max_radius = 64.0f;
    o.shutter = 0.0f;
    EXPECT_TRUE(shading::motion_blur(s.color, s.motion, s.depth, o).bit_equal(s.color));
}

TEST(MotionBlur, MovingEdgeOverStaticBackgroundMatchesTheExactAverage)
{
    // Block 40 px wide moving 32 px/frame, shutter 1: each edge ramps over 32 px. Uniform blur
    // along each pixel's own motion leaves the background ahead of and behind the block sharp
    // (it does not move); the reconstruction smears the block over it.
    const int w = 160, h = 8;
    const Scene1D s = moving_block(w, h, 60, 100, 32.0f);
    const Image truth = moving_block_truth(w, h, 60, 100, 32.0f, 1.0f);
    shading::MotionBlurOptions o;
    o.shutter = 1.0f;
    o.samples = 32;
    const Image rec = shading::motion_blur(s.color, s.motion, s.depth, o);
    o.method = shading::BlurMethod::Uniform;
    const Image uni = shading::motion_blur(s.color, s.motion, s.depth, o);
    const double e_none = rmse(s.color, truth), e_rec = rmse(rec, truth), e_uni = rmse(uni, truth);
    std::printf(
        "moving edge: rmse none %.4f uniform %.4f reconstruct %.4f\n", e_none, e_uni, e_rec);
    EXPECT_LT(e_rec, 0.25 * e_none);
    EXPECT_LT(e_rec, 0.5 * e_uni);
    // Half coverage just outside either edge of the block at the frame time.
    for (int x : {59, 100}) {
        EXPECT_NEAR(rec.at(x, 4, 0), truth.at(x, 4, 0), 0.08) << x;
    }
    expect_bounded(s.color, rec, "moving edge");
}

TEST(MotionBlur, MotionLongerThanATile)
{
    // 120 px/frame with shutter 1: a 60 px half-extent over 8 px tiles.
    const int w = 240, h = 16;
    const Scene1D s = moving_block(w, h, 100, 130, 120.0f);
    const Image truth = moving_block_truth(w, h, 100, 130, 120.0f, 1.0f);
    shading::MotionBlurOptions o;
    o.shutter = 1.0f;
    o.samples = 64;
    o.tile = 8;
    o.max_radius = 100.0f;
    const Image rec = shading::motion_blur(s.color, s.motion, s.depth, o);
    const double e_none = rmse(s.color, truth), e_rec = rmse(rec, truth);
    std::printf("motion longer than a tile: rmse none %.4f reconstruct %.4f\n", e_none, e_rec);
    EXPECT_LT(e_rec, 0.35 * e_none);
    expect_bounded(s.color, rec, "long motion");
}

TEST(MotionBlur, FastObjectOverSkyAndDisocclusion)
{
    // Block over sky (depth +inf); the background behind the block's trailing edge is hidden
    // at the frame time and must be filled from the neighbouring background.
    const int w = 160, h = 8;
    const Scene1D s = moving_block(w, h, 60, 100, 48.0f, true);
    const Image truth = moving_block_truth(w, h, 60, 100, 48.0f, 1.0f);
    shading::MotionBlurOptions o;
    o.shutter = 1.0f;
    const Image rec = shading::motion_blur(s.color, s.motion, s.depth, o);
    const double e_none = rmse(s.color, truth), e_rec = rmse(rec, truth);
    std::printf("block over sky: rmse none %.4f reconstruct %.4f\n", e_none, e_rec);
    EXPECT_LT(e_rec, 0.3 * e_none);
    expect_bounded(s.color, rec, "sky");
}

TEST(MotionBlur, NonFiniteMotionAndDepthGiveFiniteBoundedOutput)
{
    Scene1D s = moving_block(128, 32, 40, 70, 30.0f);
    for (int y = 0; y < 32; ++y) {
        s.motion.at(50, y, 0) = y % 2 ? kNaN : kInf;
        s.motion.at(20, y, 1) = -kInf;
        s.depth.at(55, y, 0) = y % 3 == 0 ? kNaN : (y % 3 == 1 ? -kInf : 0.0f);
        s.depth.at(10, y, 0) = kInf;
    }
    s.motion.at(5, 5, 0) = 1e30f;  // finite but absurd: clamped to max_radius
    for (const shading::BlurMethod m :
         {shading::BlurMethod::Reconstruct, shading::BlurMethod::Uniform}) {
        shading::MotionBlurOptions o;
        o.method = m;
        expect_bounded(s.color, shading::motion_blur(s.color, s.motion, s.depth, o), "non-finite");
    }
}

TEST(MotionBlur, ExtremeParametersStayFiniteAndBounded)
{
    const Scene1D s = moving_block(100, 20, 30, 60, 50.0f);
    const Image truth = moving_block_truth(100, 20, 30, 60, 50.0f, 0.5f);
    struct P {
        const char *name;
        int samples;
        float max_radius;
        int tile;
        float shutter;
    };
    const P cases[] = {{"samples 1", 1, 64, 16, 0.5f},
                       {"max radius huge", 16, 4096, 16, 0.5f},
                       {"max radius 0", 16, 0, 16, 0.5f},
                       {"shutter 0", 16, 64, 16, 0.0f},
                       {"tile 2", 16, 64, 2, 0.5f},
                       {"tile 256", 16, 64, 256, 0.5f},
                       {"shutter 2", 256, 64, 16, 2.0f}};
    for (const P &p : cases) {
        shading::MotionBlurOptions o;
        o.samples = p.samples;
        o.max_radius = p.max_radius;
        o.tile = p.tile;
        o.shutter = p.shutter;
        const Image out = shading::motion_blur(s.color, s.motion, s.depth, o);
        expect_bounded(s.color, out, p.name);
        std::printf("extreme %-16s rmse vs shutter-0.5 truth %.4f\n", p.name, rmse(out, truth));
    }
}

TEST(MotionBlur, SameBitsForAnyThreadCount)
{
    const Scene1D s = moving_block(301, 67, 100, 180, 37.0f);
    shading::MotionBlurOptions o;
    set_thread_count(1);
    const Image one = shading::motion_blur(s.color, s.motion, s.depth, o);
    set_thread_count(3);
    const Image three = shading::motion_blur(s.color, s.motion, s.depth, o);
    set_thread_count(0);
    const Image all = shading::motion_blur(s.color, s.motion, s.depth, o);
    EXPECT_TRUE(one.bit_equal(three));
    EXPECT_TRUE(one.bit_equal(all));
}

// The scratch records are kept between calls (ScratchPool): a frame after another of the same
// size reuses the same blocks, stale contents included, and must give the same bits as alone.
TEST(MotionBlur, ScratchReusedBetweenFramesGivesTheSameBits)
{
    const Scene1D a = moving_block(301, 67, 20, 90, -23.0f, true);
    const Scene1D b = moving_block(301, 67, 100, 180, 37.0f);
    shading::MotionBlurOptions o;
    for (const bool scalar : {false, true}) {
        // Both paths, each taking the pool's blocks back.
        const simd::ScopedLevel level(scalar ? simd::Level::Scalar : simd::active());
        const Image first = shading::motion_blur(b.color, b.motion, b.depth, o);
        const Image other = shading::motion_blur(a.color, a.motion, a.depth, o);
        const Image again = shading::motion_blur(b.color, b.motion, b.depth, o);
        EXPECT_TRUE(first.bit_equal(again)) << (scalar ? "scalar" : "default");
        EXPECT_FALSE(first.bit_equal(other));
    }
}

// The tile max and bounds the vector pack folds in while packing equal tiles.h's, bit for bit,
// on an odd-sized field with ties (equal lengths in several directions: the first in scan
// order wins), non-finite vectors (zero) and tiles cut by the frame's edges.
TEST(MotionBlurTiles, PackFoldsTheSameTileMaxAndBounds)
{
    const int w = 133, h = 37;
    Image color(w, h, 4), motion(w, h, 2), depth(w, h, 1);
    const float ties[4][2] = {{3, 4}, {4, 3}, {-5, 0}, {0, -5}};
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::uint32_t r = hash4(std::uint32_t(x), std::uint32_t(y), 7u, 0u);
            const float *t = ties[r % 4];
            const bool tie = (r >> 8) % 3 == 0;
            motion.at(x, y, 0) = tie ? t[0] : hash_to_unit(r) * 8.0f - 4.0f;
            motion.at(x, y, 1) = tie ? t[1] : hash_to_unit(pcg_hash(r)) * 8.0f - 4.0f;
            depth.at(x, y, 0) = 5.0f;
            color.at(x, y, 3) = 1.0f;
        }
    }
    motion.at(20, 3, 0) = kNaN;
    motion.at(40, 30, 1) = kInf;
    motion.at(132, 36, 0) = -kInf;
    shading::MotionBlurOptions o;
    o.shutter = 2.0f;  // half-extent = motion
    o.max_radius = 1e6f;
    // The vector pack folds where the tile is a multiple of its lanes: on every target this CPU
    // has (16 lanes on AVX-512, 8 on AVX2, 4 on SSE4), and the scalar rows.
    for (const int tile : {8, 12, 16}) {
        o.tile = tile;
        Image want_max, want_bounds;
        shading::tile_max_bounds(motion, tile, 0, &want_max, &want_bounds);
        test::for_each_highway_target([&](const char *target) {
            for (const bool scalar : {false, true}) {
                const simd::ScopedLevel level(scalar ? simd::Level::Scalar : simd::active());
                Image tiles, bounds;
                shading::motion_blur_tiles(color, motion, depth, o, tiles, bounds);
                EXPECT_TRUE(tiles.bit_equal(want_max))
                    << "tile " << tile << " " << target << (scalar ? " scalar" : "");
                EXPECT_TRUE(bounds.bit_equal(want_bounds))
                    << "tile " << tile << " " << target << (scalar ? " scalar" : "");
            }
        });
    }
}

// A texture translated diagonally, every pixel alike: every 8-pixel group shares one run of
// sample positions, and the result is the time average along the path (computed here from
// 4096 positions per pixel, on the filter's own model: the nearest pixel). Sharing the run
// costs no accuracy against each pixel sampling on its own (group_tolerance 0).
TEST(MotionBlur, SharedRunsAverageAlongThePath)
{
    const int w = 256, h = 64;
    const float vx = 37.3f, vy = 15.7f;  // shutter 1: half-extent (18.65, 7.85), 20.2 px
    Image color(w, h, 4), motion(w, h, 2), depth(w, h, 1);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            color.at(x, y, 0) = 0.5f + 0.5f * std::sin(0.31f * float(x) + 0.17f * float(y));
            color.at(x, y, 1) = 0.5f + 0.5f * std::sin(0.11f * float(x) - 0.23f * float(y));
            color.at(x, y, 2) = float((x / 5 + y / 3) % 2);
            color.at(x, y, 3) = 1.0f;
            motion.at(x, y, 0) = vx;
            motion.at(x, y, 1) = vy;
            depth.at(x, y, 0) = 10.0f;
        }
    }
    Image truth(w, h, 4);
    const int K = 4096;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            double acc[3] = {0, 0, 0};
            for (int k = 0; k < K; ++k) {
                const float t = -1.0f + (float(k) + 0.5f) * (2.0f / float(K));
                const int sx =
                    std::clamp(int(std::floor(float(x) + 0.5f + t * 0.5f * vx)), 0, w - 1);
                const int sy =
                    std::clamp(int(std::floor(float(y) + 0.5f + t * 0.5f * vy)), 0, h - 1);
                for (int c = 0; c < 3; ++c) {
                    acc[c] += color.at(sx, sy, c);
                }
            }
            for (int c = 0; c < 3; ++c) {
                truth.at(x, y, c) = float(acc[c] / K);
            }
            truth.at(x, y, 3) = 1.0f;
        }
    }
    shading::MotionBlurOptions o;
    o.shutter = 1.0f;
    for (const bool scalar : {false, true}) {
        const simd::ScopedLevel level(scalar ? simd::Level::Scalar : simd::active());
        shading::MotionBlurStats st;
        const Image shared = shading::motion_blur(color, motion, depth, o, &st);
        EXPECT_GT(st.groups, 0);
        EXPECT_EQ(st.groups_shared, st.groups);
        shading::MotionBlurOptions each = o;
        each.group_tolerance = 0.0f;
        shading::MotionBlurStats st0;
        const Image own = shading::motion_blur(color, motion, depth, each, &st0);
        EXPECT_EQ(st0.groups_shared, 0);
        const double e_none = rmse(color, truth), e_shared = rmse(shared, truth),
                     e_own = rmse(own, truth);
        std::printf("diagonal translation (%s): rmse none %.4f, per pixel %.4f, shared runs %.4f\n",
                    scalar ? "scalar" : "default",
                    e_none,
                    e_own,
                    e_shared);
        EXPECT_LT(e_shared, 0.25 * e_none);
        EXPECT_LT(e_shared, 1.1 * e_own);
        expect_bounded(color, shared, "diagonal translation");
    }
}

// Alpha exactly 1 everywhere blurs to exactly 1 (the sums skip it); any other alpha blurs with
// the colour's weights: here alpha = red, so the two stay equal bit for bit.
TEST(MotionBlur, OpaqueAlphaStaysOneAndOtherAlphaBlursLikeColour)
{
    Scene1D s = moving_block(203, 19, 60, 100, 44.0f, true);
    for (const bool scalar : {false, true}) {
        const simd::ScopedLevel level(scalar ? simd::Level::Scalar : simd::active());
        for (const auto method : {shading::BlurMethod::Reconstruct, shading::BlurMethod::Uniform}) {
            shading::MotionBlurOptions o;
            o.method = method;
            o.shutter = 1.0f;
            Image out = shading::motion_blur(s.color, s.motion, s.depth, o);
            int off = 0;
            for (int y = 0; y < out.height(); ++y) {
                for (int x = 0; x < out.width(); ++x) {
                    off += out.at(x, y, 3) != 1.0f;
                }
            }
            EXPECT_EQ(off, 0) << (scalar ? "scalar" : "default");
            Scene1D t = s;
            for (int y = 0; y < t.color.height(); ++y) {
                for (int x = 0; x < t.color.width(); ++x) {
                    t.color.at(x, y, 3) = t.color.at(x, y, 0);
                }
            }
            out = shading::motion_blur(t.color, t.motion, t.depth, o);
            off = 0;
            for (int y = 0; y < out.height(); ++y) {
                for (int x = 0; x < out.width(); ++x) {
                    off += out.at(x, y, 3) != out.at(x, y, 0);
                }
            }
            EXPECT_EQ(off, 0) << (scalar ? "scalar" : "default");
            EXPECT_FALSE(out.bit_equal(t.color));  // it did blur
        }
    }
}

std::string scene_path(const std::string &name)
{
    return std::string(POSTHASTE_TEST_DIR) + "/../samples/scenes/" + name;
}

TEST(MotionBlur, CameraReprojectionMatchesTheRasterizerOnAStaticWorld)
{
    // thin_sky has no moving objects: the rasterizer's motion pass is camera motion, sky
    // included (rotation only).
    const raster::Scene scene = raster::load_scene(scene_path("thin_sky.json"));
    raster::RenderOptions ro;
    ro.width = 160;
    ro.height = 90;
    ro.passes = {"depth", "motion"};
    const Frame f = raster::render_frame(scene, 4, ro);
    const Image cam = shading::camera_motion(f.image("depth"), f.camera, "test");
    const metrics::CompareStats st = metrics::compare(cam, f.image("motion"));
    std::printf("camera reprojection vs motion pass: rms %.3g max %.3g px\n",
                st.all.rms_error,
                st.all.max_error);
    EXPECT_LT(st.all.max_error, 0.02);
    double longest = 0;
    for (int y = 0; y < 90; ++y) {
        for (int x = 0; x < 160; ++x) {
            longest = std::max(
                longest,
                double(std::hypot(f.image("motion").at(x, y, 0), f.image("motion").at(x, y, 1))));
        }
    }
    EXPECT_GT(longest, 0.1);  // the test is not comparing zeros
}

// The vector rows against the reference on rendered frames of the default scene (fast
// translation and fast turn; both methods), on every Highway target this CPU has. The
// reconstruction rounds differently (Highway's log polynomial in the pack's depth, fused
// weights in the shared runs), so a weight now and then differs in its last bits: RMSE under
// 2e-7, no value off by more than 2e-5 (measured 2.7e-8 and 1e-6). Every sample position is
// rounded as the reference rounds it (the product, then the sum), so both methods read the
// same pixels, and the uniform method, which only sums them in order, gives the reference's
// bits (until 2026-11-29 its rows took fused steps, and a sample landed on the next pixel now
// and then: up to 0.036 on one pixel in 10^5 at 32 samples). The targets whose vectors hold a
// group (AVX-512, AVX2) give the same bits.
TEST(MotionBlur, VectorRowsMatchTheReference)
{
    const raster::Scene scene = raster::load_scene(scene_path("minecrappy.json"));
    raster::RenderOptions ro;
    ro.width = 480;
    ro.height = 270;
    ro.passes = {"color", "depth", "motion"};
    int vector_targets = 0;
    for (const int frame : {6, 20}) {
        const Frame f = raster::render_frame(scene, frame, ro);
        for (const auto method : {shading::BlurMethod::Reconstruct, shading::BlurMethod::Uniform}) {
            const char *name = method == shading::BlurMethod::Uniform ? "uniform" : "reconstruct";
            shading::MotionBlurOptions o;
            o.method = method;
            o.shutter = f.camera.shutter.value_or(0.5f);
            // max_radius 16 at this size is the default's 64 px at 1920x1080.
            o.max_radius = 16.0f;
            Image ref;
            {
                simd::ScopedLevel level(simd::Level::Scalar);
                ref =
                    shading::motion_blur(f.image("color"), f.image("motion"), f.image("depth"), o);
            }
            Image grouped;  // the first target whose vectors hold a group
            test::for_each_highway_target([&](const char *target) {
                const Image vec =
                    shading::motion_blur(f.image("color"), f.image("motion"), f.image("depth"), o);
                const metrics::CompareStats st = metrics::compare(vec, ref);
                const double frac = fraction_off(vec, ref);
                const bool lanes = shading::motion_blur_detail::group_lanes();
                std::printf(
                    "%s (%s) vs reference f%d %s: rms %.3g max %.3g, %.4f %% of pixels off by > "
                    "1e-3 (relative above 1)\n",
                    target,
                    lanes ? "vector rows" : "reference rows",
                    frame,
                    name,
                    st.all.rms_error,
                    st.all.max_error,
                    100.0 * frac);
                if (method == shading::BlurMethod::Uniform) {
                    EXPECT_TRUE(vec.bit_equal(ref)) << frame << " " << name << " " << target;
                }
                EXPECT_LT(st.all.rms_error, 2e-7) << frame << " " << name << " " << target;
                EXPECT_LT(st.all.max_error, 2e-5) << frame << " " << name << " " << target;
                EXPECT_EQ(frac, 0.0) << frame << " " << name << " " << target;
                if (lanes) {
                    ++vector_targets;
                    if (grouped.empty()) {
                        grouped = vec;
                    } else {
                        EXPECT_TRUE(vec.bit_equal(grouped))
                            << frame << " " << name << " " << target;
                    }
                }
            });
        }
    }
    if (vector_targets == 0) {
        std::printf("no target with eight float lanes on this CPU: only the reference rows ran\n");
    }
}

// The vector rows and the reference on odd sizes and layouts (tolerances as above): a width that
// is not a multiple of 8 (groups cut by the frame's edge), tiles that are not (no merged
// segments, no pack-time tile reduction), RGB colour (no alpha) and three-channel motion
// (gathered in the pack). Also: most
// groups of the fast translation share a run, none with group_tolerance 0.
TEST(MotionBlur, VectorRowsMatchTheReferenceAtOddSizesAndLayouts)
{
    const raster::Scene scene = raster::load_scene(scene_path("minecrappy.json"));
    raster::RenderOptions ro;
    ro.width = 475;
    ro.height = 267;
    ro.passes = {"color", "depth", "motion"};
    const Frame f = raster::render_frame(scene, 6, ro);
    Image rgb(ro.width, ro.height, 3), motion3(ro.width, ro.height, 3);
    for (int y = 0; y < ro.height; ++y) {
        for (int x = 0; x < ro.width; ++x) {
            for (int c = 0; c < 3; ++c) {
                rgb.at(x, y, c) = f.image("color").at(x, y, c);
            }
            motion3.at(x, y, 0) = f.image("motion").at(x, y, 0);
            motion3.at(x, y, 1) = f.image("motion").at(x, y, 1);
            motion3.at(x, y, 2) = 7.0f;
        }
    }
    struct Case {
        const char *name;
        const Image &color, &motion;
        int tile;
    };
    const Case cases[] = {{"rgba tile 16", f.image("color"), f.image("motion"), 16},
                          {"rgba tile 12", f.image("color"), f.image("motion"), 12},
                          {"rgb tile 8", rgb, f.image("motion"), 8},
                          {"motion xyz tile 16", f.image("color"), motion3, 16}};
    for (const Case &c : cases) {
        shading::MotionBlurOptions o;
        o.shutter = f.camera.shutter.value_or(0.5f);
        o.max_radius = 16.0f;
        o.tile = c.tile;
        Image ref;
        {
            simd::ScopedLevel level(simd::Level::Scalar);
            ref = shading::motion_blur(c.color, c.motion, f.image("depth"), o);
        }
        test::for_each_highway_target([&](const char *target) {
            shading::MotionBlurStats st;
            const Image vec = shading::motion_blur(c.color, c.motion, f.image("depth"), o, &st);
            const metrics::CompareStats cs = metrics::compare(vec, ref);
            const double frac = fraction_off(vec, ref);
            std::printf(
                "%s vs reference, %s: rms %.3g max %.3g, %.4f %% of pixels off by > 1e-3; %ld of "
                "%ld groups shared a run\n",
                target,
                c.name,
                cs.all.rms_error,
                cs.all.max_error,
                100.0 * frac,
                st.groups_shared,
                st.groups);
            EXPECT_LT(cs.all.rms_error, 2e-7) << c.name << " " << target;
            EXPECT_LT(cs.all.max_error, 2e-5) << c.name << " " << target;
            EXPECT_EQ(frac, 0.0) << c.name << " " << target;
            EXPECT_GT(double(st.groups_shared), 0.9 * double(st.groups)) << c.name << " " << target;
            expect_bounded(c.color, vec, c.name);
        });
    }
    shading::MotionBlurOptions o;
    o.shutter = f.camera.shutter.value_or(0.5f);
    o.group_tolerance = 0.0f;
    shading::MotionBlurStats st;
    shading::motion_blur(f.image("color"), f.image("motion"), f.image("depth"), o, &st);
    EXPECT_EQ(st.groups_shared, 0);
    EXPECT_GT(st.groups, 0);
}

Frame run_node(const std::string &scene, int frame, int w, int h, const std::string &params)
{
    const std::string dir = test::scratch_dir("motion_blur_node");
    const std::string graph = R"({"nodes": [
        {"id": "src", "type": "render", "params": {"scene": ")" +
                              scene_path(scene) + R"(", "width": )" + std::to_string(w) +
                              R"(, "height": )" + std::to_string(h) + R"(}},
        {"id": "mb", "type": "motion_blur", "inputs": {"image": "src"}, "params": {)" +
                              params +
                              R"(}},
        {"id": "o", "type": "write", "inputs": {"image": "mb"},
         "params": {"path": ")" +
                              dir + R"(/o.exr", "passes": "color"}}]})";
    Graph g = Graph::parse(graph, "g.json", nodes::catalog());
    g.set_capture("mb");
    return g.evaluate(frame);
}

TEST(MotionBlurNode, ZeroShutterAndThreadCountThroughTheGraph)
{
    raster::RenderOptions ro;
    ro.width = 96;
    ro.height = 54;
    ro.passes = {"color"};
    const Frame in =
        raster::render_frame(raster::load_scene(scene_path("fast_crossing.json")), 3, ro);
    EXPECT_TRUE(run_node("fast_crossing.json", 3, 96, 54, R"("shutter": 0)")
                    .image("color")
                    .bit_equal(in.image("color")));
    set_thread_count(1);
    const Frame one = run_node("fast_crossing.json", 3, 96, 54, "");
    set_thread_count(0);
    const Frame many = run_node("fast_crossing.json", 3, 96, 54, "");
    EXPECT_TRUE(one.image("color").bit_equal(many.image("color")));
    EXPECT_FALSE(one.image("color").bit_equal(in.image("color")));  // it did blur
    // Camera-only mode runs from depth and the header (the block's own motion is lost).
    const Frame cam = run_node("fast_crossing.json", 3, 96, 54, R"("source": "camera")");
    expect_bounded(in.image("color"), cam.image("color"), "camera source");
}

// Ground truth (render truth=motion) against the node with default parameters, doing nothing,
// and the seeds' method (uniform blur along camera-reprojected motion: method uniform, source
// camera). Truth at N and 2N samples shows the truth has converged well below the errors.
struct AccuracyCase {
    const char *label;
    const char *scene;
    int frame;
    double max_node_over_none;    ///< asserted ceiling of RMSE(node) / RMSE(nothing)
    double max_node_over_simple;  ///< asserted ceiling of RMSE(node) / RMSE(simple method)
};

constexpr int kAccW = 960, kAccH = 540, kTruthSamples = 64;

void run_accuracy(const AccuracyCase &c)
{
    const raster::Scene scene = raster::load_scene(scene_path(c.scene));
    raster::RenderOptions ro;
    ro.width = kAccW;
    ro.height = kAccH;
    ro.passes = {"color"};
    const Frame in = raster::render_frame(scene, c.frame, ro);
    raster::TruthOptions t;
    t.samples = kTruthSamples;
    t.seed = 1;
    const Image truth = raster::render_truth(scene, c.frame, ro, t).image("color");
    t.samples = 2 * kTruthSamples;
    t.seed = 2;
    const Image truth2 = raster::render_truth(scene, c.frame, ro, t).image("color");
    const Image node = run_node(c.scene, c.frame, kAccW, kAccH, "").image("color");
    const Image simple =
        run_node(c.scene, c.frame, kAccW, kAccH, R"("method": "uniform", "source": "camera")")
            .image("color");
    const metrics::CompareStats none_st = metrics::compare(in.image("color"), truth2);
    const metrics::CompareStats node_st = metrics::compare(node, truth2);
    const metrics::CompareStats simple_st = metrics::compare(simple, truth2);
    const double conv = rmse(truth, truth2);
    const double removed = 1.0 - node_st.all.rms_error / none_st.all.rms_error;
    // PSNR with peak 1 (idiff's peak is max(1, largest value), which differs per pair on HDR
    // frames and would make the columns incomparable).
    auto psnr = [](double rms) { return 20.0 * std::log10(1.0 / rms); };
    std::printf(
        "| %s | %.5f (%.2f dB) | %.5f (%.2f dB) | %.5f (%.2f dB) | %.0f %% | %.3f | "
        "%.5f |\n",
        c.label,
        none_st.all.rms_error,
        psnr(none_st.all.rms_error),
        simple_st.all.rms_error,
        psnr(simple_st.all.rms_error),
        node_st.all.rms_error,
        psnr(node_st.all.rms_error),
        100.0 * removed,
        node_st.all.rms_error / simple_st.all.rms_error,
        conv);
    EXPECT_LT(node_st.all.rms_error, c.max_node_over_simple * simple_st.all.rms_error) << c.label;
    EXPECT_LT(node_st.all.rms_error, c.max_node_over_none * none_st.all.rms_error) << c.label;
    EXPECT_LT(conv, 0.5 * node_st.all.rms_error) << c.label << ": truth not converged";
    expect_bounded(in.image("color"), node, c.label);
}

TEST(MotionBlurAccuracySlow, DefaultSceneFastTranslation)
{
    run_accuracy({"minecrappy f6 translation", "minecrappy.json", 6, 0.40, 0.90});
}

TEST(MotionBlurAccuracySlow, DefaultSceneFastTurn)
{
    // A pure camera turn over a static world: the uniform blur along camera motion is already
    // the right answer there, so the node can only tie it (measured 0.995).
    run_accuracy({"minecrappy f20 turn", "minecrappy.json", 20, 0.25, 1.02});
}

TEST(MotionBlurAccuracySlow, FastCrossing)
{
    run_accuracy({"fast_crossing f4", "fast_crossing.json", 4, 0.35, 0.35});
}

TEST(MotionBlurAccuracySlow, ThinSky)
{
    run_accuracy({"thin_sky f4", "thin_sky.json", 4, 0.30, 0.70});
}

}  // namespace
}  // namespace posthaste
