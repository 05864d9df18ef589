#pragma once
// The motion blur's gather (internal to src/shading/motion_blur*.cpp): the reconstruction and
// the uniform blur of a group of pixels, one pixel at a time; the reference the vector rows
// (motion_blur_gather_kernels.cpp) follow, and the path where the CPU's vectors are narrower than
// a group.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/hash.h"
#include "core/simd.h"
#include "shading/motion_blur/motion_blur_records.h"

namespace posthaste::shading::motion_blur_detail {

/// The neighbour-max vector a group reads, and its length and direction.
struct Lookup {
    float vx, vy, len, dx, dy;
};

/// The sampling vector a group of pixels shares (see Gather): the middle of their vectors'
/// bounding box, with its length, direction and sample count.
struct Run {
    float vx, vy, len, dx, dy;
    int n;
    int ok;  ///< the vectors agree within the tolerance and the run is at least half a pixel
};

/// The bounding box of a group's vectors (what Gather::run decides on).
struct Box {
    float lo_x = kInf, hi_x = -kInf, lo_y = kInf, hi_y = -kInf;
    void add(float x, float y)
    {
        lo_x = std::min(lo_x, x);
        hi_x = std::max(hi_x, x);
        lo_y = std::min(lo_y, y);
        hi_y = std::max(hi_y, y);
    }
};

/// The per-pixel plan of the reconstruction: the pixel's own motion, whether its own path shares
/// the neighbour-max samples, and the vector (vx, vy), length and direction it samples along.
struct Lane {
    float cvx, cvy, clen, inv_own;
    bool own, shared;
    float vx, vy, len, dx, dy;
};

/// The gather, shared by the reference and the vector rows. Pixels are processed in groups of eight
/// adjacent pixels of a row (fewer at a tile's right edge), and a group makes one jittered
/// neighbour-max lookup. Where the sampling vectors of a group's pixels all lie within
/// `group_tolerance` px of the middle of their bounding box (95 % of the reconstructed groups of
/// the default scene's fast translation, all of the fast turn's), the group samples along that
/// middle vector with one jitter: the sample positions of its pixels are then the same run of
/// adjacent pixels in one row, shifted, and the vector rows read each field of a sample with one
/// load instead of eight. Sample positions move by at most the tolerance (at the ends of the
/// path); the pixels keep their own depth, motion and weights. Other groups sample per pixel.
struct Gather {
    const Image &color;
    const float *f[kFields];
    const Image &nmax;
    const MotionBlurOptions &o;
    int w, h, nc;
    float inv_soft, tolerance;
    bool opaque;  ///< RGBA with alpha 1 everywhere: alpha is not summed, and blurs to 1
    /// Per neighbour-max tile: its vector, length and direction (computed once a frame).
    std::vector<Lookup> tiles;
    /// The lookup jitter's full width in 1/256 px, and the seed's part of its hash.
    std::int64_t jitter_q;
    std::uint32_t seed1;

    Gather(const Image &color_,
           const Packed &packed,
           const Image &nmax_,
           const MotionBlurOptions &o_,
           int nc_)
        : color(color_),
          f{},
          nmax(nmax_),
          o(o_),
          w(color_.width()),
          h(color_.height()),
          nc(nc_),
          inv_soft(1.0f / o_.soft_z),
          tolerance(o_.group_tolerance),
          opaque(nc_ == 4 && std::all_of(packed.opaque_rows.begin(),
                                         packed.opaque_rows.end(),
                                         [](unsigned char r) { return r != 0; })),
          tiles(std::size_t(nmax_.width()) * std::size_t(nmax_.height())),
          // At most one tile either way: the neighbour max's margin (NaN or negative: none).
          jitter_q(o_.tile_jitter > 0.0f ? std::int64_t(std::min(2.0f * o_.tile_jitter, 2.0f) *
                                                        float(o_.tile) * 256.0f)
                                         : 0),
          seed1(pcg_hash(1u ^ pcg_hash(o_.seed)))
    {
        for (int k = 0; k < kFields; ++k) {
            f[k] = packed.plane(k);
        }
        for (int ty = 0; ty < nmax.height(); ++ty) {
            for (int tx = 0; tx < nmax.width(); ++tx) {
                Lookup &l = tiles[std::size_t(ty) * std::size_t(nmax.width()) + std::size_t(tx)];
                l = Lookup{nmax.at(tx, ty, 0), nmax.at(tx, ty, 1), 0.0f, 0.0f, 0.0f};
                l.len = std::sqrt(l.vx * l.vx + l.vy * l.vy);
                if (l.len >= 0.5f) {
                    l.dx = l.vx / l.len;
                    l.dy = l.vy / l.len;
                }
            }
        }
    }

    std::size_t index(int x, int y) const
    {
        return std::size_t(y) * std::size_t(w) + std::size_t(x);
    }

    /// The clamped half-extent vector of record i and its length, from the planes (v = w 2|v|^2;
    /// zero below half a pixel, where no path uses it).
    void own(std::size_t i, float &vx, float &vy, float &len) const
    {
        len = f[kLen][i];
        const float k = 2.0f * len * len;
        vx = f[kWx][i] * k;
        vy = f[kWy][i] * k;
    }

    /// The pixel's colour as packed (the input's bits, less MotionBlurOptions::subtract).
    void copy_pixel(Image &out, int x, int y) const
    {
        const std::size_t i = index(x, y);
        float *q = out.pixel(x, y);
        for (int k = 0; k < nc; ++k) {
            q[k] = f[kRed + k][i];
        }
    }

    /// Samples per pixel of a path's half-length `len`: two per pixel of the path. One per pixel
    /// (2 here, before 2026-11-29) left a short blur to a few nearest-pixel taps with a jittered
    /// start: the Cycles close-up's 5.4 px pan at shutter 1 kept 3 taps and 49 % of its error;
    /// two per pixel take it to 61 %, and the rasterizer's bench from 0.0184 to 0.0174 RMSE
    /// (docs/ACCURACY.md, "Against Cycles").
    static constexpr float kSamplesPerHalfLength = 4.0f;
    static int sample_count(float len, int most)
    {
        return std::max(1,
                        std::min(most, std::max(2, int(std::ceil(kSamplesPerHalfLength * len)))));
    }

    /// The record index at x + 0.5 + t * (vx, vy), clamped to the frame (edge pixels extend).
    std::size_t at(int x, int y, float t, float vx, float vy) const
    {
        // Clamp in float (branch-free minss/maxss), then truncate: the value is >= 0.
        const float fx = std::min(std::max(float(x) + 0.5f + t * vx, 0.0f), float(w) - 0.5f);
        const float fy = std::min(std::max(float(y) + 0.5f + t * vy, 0.0f), float(h) - 0.5f);
        return index(int(fx), int(fy));
    }

    /// A shared sample of the group starting at x0: the column of its first pixel (unclamped)
    /// and its row (clamped). Pixel j of the group reads column clamp(bx + j, 0, w - 1), which
    /// is at() for x0 + j.
    void run_origin(int x0, int y, float t, float vx, float vy, int &bx, int &by) const
    {
        bx = int(std::floor(float(x0) + 0.5f + t * vx));
        by = std::min(std::max(int(std::floor(float(y) + 0.5f + t * vy)), 0), h - 1);
    }
    std::size_t run_at(int bx, int j, int by) const
    {
        return index(std::min(std::max(bx + j, 0), w - 1), by);
    }

    /// One jittered neighbour-max lookup for the group at (x0, y): pixels near a tile border
    /// sometimes read the next tile's neighbourhood, which turns seams into noise (Guertin
    /// 2014). The jitter is a whole number of 1/256 px, so both paths find the same tile.
    const Lookup &lookup(int x0, int y) const
    {
        const std::uint32_t hj = pcg_hash(std::uint32_t(x0) ^ pcg_hash(std::uint32_t(y) ^ seed1));
        const std::int64_t jx = ((std::int64_t(hj >> 8) * jitter_q) >> 24) - jitter_q / 2;
        const std::int64_t jy = ((std::int64_t(pcg_hash(hj) >> 8) * jitter_q) >> 24) - jitter_q / 2;
        const std::int64_t span = std::int64_t(o.tile) * 256;
        const std::int64_t px = (std::int64_t(x0) + 4) * 256 + jx;
        const std::int64_t py = std::int64_t(y) * 256 + 128 + jy;
        const int tx = px <= 0 ? 0 : int(std::min<std::int64_t>(px / span, nmax.width() - 1));
        const int ty = py <= 0 ? 0 : int(std::min<std::int64_t>(py / span, nmax.height() - 1));
        return tiles[std::size_t(ty) * std::size_t(nmax.width()) + std::size_t(tx)];
    }

    /// The shared run of the vectors in box b.
    Run run(const Box &b) const
    {
        Run r;
        run(b, r);
        return r;
    }
    /// run() into `r`, field by field (a plan's runs are written in place: building the struct
    /// and copying it stalled on store forwarding).
    void run(const Box &b, Run &r) const
    {
        const float vx = 0.5f * (b.lo_x + b.hi_x), vy = 0.5f * (b.lo_y + b.hi_y);
        const float len = std::sqrt(vx * vx + vy * vy);
        const bool ok = tolerance > 0.0f && b.hi_x - b.lo_x <= 2.0f * tolerance &&
                        b.hi_y - b.lo_y <= 2.0f * tolerance && len >= 0.5f;
        r.vx = vx;
        r.vy = vy;
        r.len = len;
        r.ok = ok;
        r.dx = ok ? vx / len : 0.0f;
        r.dy = ok ? vy / len : 0.0f;
        r.n = ok ? sample_count(len, o.samples) : 1;
    }

    /// The plan of pixel (x, y) under the neighbour-max vector `l`.
    Lane lane(int x, int y, const Lookup &l) const
    {
        Lane p{};
        own(index(x, y), p.cvx, p.cvy, p.clen);
        p.own = p.clen >= 0.5f;
        // One division for the direction and the own weight.
        const float inv_len = p.own ? 1.0f / p.clen : 0.0f;
        const float dcx = p.cvx * inv_len, dcy = p.cvy * inv_len;
        // Does the pixel's own path share the neighbour-max samples? Only if it is aligned
        // with them and long enough for their spacing; else it gets samples of its own.
        p.shared = p.own && std::abs(dcx * l.dx + dcy * l.dy) > 0.9f && p.clen >= 0.5f * l.len;
        p.inv_own = 0.5f * inv_len;
        p.vx = l.vx;
        p.vy = l.vy;
        p.len = l.len;
        p.dx = l.dx;
        p.dy = l.dy;
        if (p.shared) {
            // Departure: sample along the pixel's own direction (over the neighbourhood's
            // length). Where everything moves alike (camera turns) the neighbour-max direction
            // is an arbitrary one of many near-equal vectors, degrees off this pixel's path.
            p.dx = dcx;
            p.dy = dcy;
            p.vx = dcx * l.len;
            p.vy = dcy * l.len;
            if (p.clen > 0.8f * l.len) {
                // Nearly the longest around: the pixel's own path, sampled densely.
                p.vx = p.cvx;
                p.vy = p.cvy;
                p.len = p.clen;
            }
        }
        return p;
    }

    /// The result of a pixel from its sums: F, fg = the front estimate (coverage and colour),
    /// B, bg = its own surface's, own_weight the weight of one of its own samples; c = its own
    /// colour.
    void finish(Image &out,
                int x,
                int y,
                const Lane &p,
                float F,
                float B,
                const float *fg,
                const float *bg,
                float own_weight) const
    {
        float *po = out.pixel(x, y);
        if (F >= 1.0f) {
            const float inv_f = 1.0f / F;
            for (int k = 0; k < nc; ++k) {
                po[k] = fg[k] * inv_f;
            }
            if (opaque) {
                po[3] = 1.0f;
            }
            return;
        }
        // The pixel itself, so that B > 0. Where the pixel has a path of its own, the samples
        // already cover its centre: a full weight here would sharpen, so it only breaks ties.
        const float wc = p.own ? 1e-3f * own_weight : 1.0f;
        B += wc;
        const float rest = (1.0f - F) / B;
        const std::size_t i = index(x, y);
        for (int k = 0; k < nc; ++k) {
            po[k] = fg[k] + rest * (bg[k] + wc * f[kRed + k][i]);
        }
        if (opaque) {
            po[3] = 1.0f;
        }
    }

    /// Guertin 2014's second direction for one pixel: its own motion, for its own surface, over
    /// m samples (up to half the front estimate's n) with its own jitter. Returns the weight of
    /// one sample.
    float second_lane(int x, int y, const Lane &p, int n, float clz, float &B, float *bg) const
    {
        const int m = std::max(2, std::min(sample_count(p.clen, o.samples), (n + 1) / 2));
        const float mstep = 2.0f / float(m);
        const float wm = p.clen * mstep * p.inv_own;
        const float u2 =
            hash_to_unit(pcg_hash(hash4(std::uint32_t(x), std::uint32_t(y), 0u, o.seed)));
        for (int i = 0; i < m; ++i) {
            const std::size_t s = at(x, y, -1.0f + (float(i) + u2) * mstep, p.cvx, p.cvy);
            const float wb = (1.0f - front(f[kLogZ][s], clz, inv_soft)) * wm;
            B += wb;
            for (int k = 0; k < 4; ++k) {
                bg[k] += wb * f[kRed + k][s];
            }
        }
        return wm;
    }

    /// One pixel sampled along its own plan (groups whose vectors disagree).
    void reconstruct_lane(Image &out, int x, int y, const Lane &p) const
    {
        const std::size_t ci = index(x, y);
        const float clz = f[kLogZ][ci];
        const std::uint32_t hu = hash4(std::uint32_t(x), std::uint32_t(y), 0u, o.seed);
        const float u = hash_to_unit(hu);
        float fg[4] = {0, 0, 0, 0}, bg[4] = {0, 0, 0, 0};
        float F = 0.0f, B = 0.0f;
        const int n = sample_count(p.len, o.samples);
        const float step = 2.0f / float(n);
        const float delta = p.len * step;  // path length each sample stands for
        const float own_w = p.shared ? delta * p.inv_own : 0.0f;
        for (int i = 0; i < n; ++i) {
            const float t = -1.0f + (float(i) + u) * step;
            const std::size_t s = at(x, y, t, p.vx, p.vy);
            const float T = std::abs(t) * p.len;
            const float fr = front(f[kLogZ][s], clz, inv_soft);
            // Coverage of X by Y: Y's reach along the sampled line, time density along the
            // line |dot(vY, d)| / |vY| / (2 |vY|) (zero for Y slower than half a pixel).
            const float wf =
                fr * reach(T, f[kLen][s]) * std::abs(f[kWx][s] * p.dx + f[kWy][s] * p.dy) * delta;
            // X's own surface along its own path (shared samples).
            const float wb = (1.0f - fr) * reach(T, p.clen) * own_w;
            F += wf;
            B += wb;
            for (int k = 0; k < 4; ++k) {
                fg[k] += wf * f[kRed + k][s];
                bg[k] += wb * f[kRed + k][s];
            }
        }
        float own_weight = own_w;
        if (p.own && !p.shared) {
            own_weight = second_lane(x, y, p, n, clz, B, bg);
        }
        finish(out, x, y, p, F, B, fg, bg, own_weight);
    }

    /// A group whose sampling vectors agree: every pixel samples along r with the group's
    /// jitter; the pixels' own surfaces keep theirs, or share a run of their own where their
    /// motions agree too.
    void reconstruct_run(Image &out, int x0, int cnt, int y, const Lane *p, const Run &r) const
    {
        const std::uint32_t hu = hash4(std::uint32_t(x0), std::uint32_t(y), 0u, o.seed);
        const float u = hash_to_unit(hu), u2 = hash_to_unit(pcg_hash(hu));
        const float step = 2.0f / float(r.n), delta = r.len * step;
        const int kc = opaque ? 3 : 4;  // colour channels summed
        float F[8] = {}, B[8] = {}, fg[8][4] = {}, bg[8][4] = {}, clz[8];
        for (int j = 0; j < cnt; ++j) {
            clz[j] = f[kLogZ][index(x0 + j, y)];
        }
        for (int i = 0; i < r.n; ++i) {
            const float t = -1.0f + (float(i) + u) * step;
            const float T = std::abs(t) * r.len;
            int bx, by;
            run_origin(x0, y, t, r.vx, r.vy, bx, by);
            for (int j = 0; j < cnt; ++j) {
                const std::size_t s = run_at(bx, j, by);
                const float fr = front(f[kLogZ][s], clz[j], inv_soft);
                const float wf =
                    fr * reach(T, f[kLen][s]) * std::abs(f[kWx][s] * r.dx + f[kWy][s] * r.dy);
                const float wb = (1.0f - fr) * reach(T, p[j].clen);
                F[j] += wf;
                B[j] += wb;
                for (int k = 0; k < kc; ++k) {
                    fg[j][k] += wf * f[kRed + k][s];
                    bg[j][k] += wb * f[kRed + k][s];
                }
            }
        }
        // The path length each sample stands for, and the own-surface weights (zero where the
        // pixel's own path is not the shared one).
        float own_weight[8];
        Box own_box;
        bool second = false;
        for (int j = 0; j < cnt; ++j) {
            own_weight[j] = p[j].shared ? delta * p[j].inv_own : 0.0f;
            F[j] *= delta;
            B[j] *= own_weight[j];
            for (int k = 0; k < kc; ++k) {
                fg[j][k] *= delta;
                bg[j][k] *= own_weight[j];
            }
            if (p[j].own && !p[j].shared) {
                second = true;
                own_box.add(p[j].cvx, p[j].cvy);
            }
        }
        if (second) {
            // Guertin's second direction for the pixels whose own path is not shared: one run
            // where their motions agree, else each its own.
            const Run c = run(own_box);
            if (c.ok) {
                const int m = std::max(2, std::min(c.n, (r.n + 1) / 2));
                const float mstep = 2.0f / float(m), wm = 1.0f / float(m);
                for (int i = 0; i < m; ++i) {
                    int bx, by;
                    run_origin(x0, y, -1.0f + (float(i) + u2) * mstep, c.vx, c.vy, bx, by);
                    for (int j = 0; j < cnt; ++j) {
                        if (p[j].own && !p[j].shared) {
                            const std::size_t s = run_at(bx, j, by);
                            const float wb = (1.0f - front(f[kLogZ][s], clz[j], inv_soft)) * wm;
                            B[j] += wb;
                            for (int k = 0; k < kc; ++k) {
                                bg[j][k] += wb * f[kRed + k][s];
                            }
                        }
                    }
                }
                for (int j = 0; j < cnt; ++j) {
                    if (p[j].own && !p[j].shared) {
                        own_weight[j] = wm;
                    }
                }
            } else {
                for (int j = 0; j < cnt; ++j) {
                    if (p[j].own && !p[j].shared) {
                        own_weight[j] = second_lane(x0 + j, y, p[j], r.n, clz[j], B[j], bg[j]);
                    }
                }
            }
        }
        for (int j = 0; j < cnt; ++j) {
            finish(out, x0 + j, y, p[j], F[j], B[j], fg[j], bg[j], own_weight[j]);
        }
    }

    /// The reconstruction of the group of cnt pixels from (x0, y).
    /// Returns whether the group shared a run.
    bool reconstruct(Image &out, int x0, int cnt, int y) const
    {
        const Lookup l = lookup(x0, y);
        if (l.len < 0.5f) {
            for (int j = 0; j < cnt; ++j) {
                copy_pixel(out, x0 + j, y);
            }
            return false;
        }
        Lane p[8];
        Box box;
        for (int j = 0; j < cnt; ++j) {
            p[j] = lane(x0 + j, y, l);
            box.add(p[j].vx, p[j].vy);
        }
        const Run r = run(box);
        if (r.ok) {
            reconstruct_run(out, x0, cnt, y, p, r);
            return true;
        }
        for (int j = 0; j < cnt; ++j) {
            reconstruct_lane(out, x0 + j, y, p[j]);
        }
        return false;
    }

    /// The uniform blur along the pixel's own motion.
    void uniform_lane(Image &out, int x, int y) const
    {
        float vx, vy, len;
        own(index(x, y), vx, vy, len);
        if (len < 0.5f) {
            copy_pixel(out, x, y);
            return;
        }
        const int n = sample_count(len, o.samples);
        const float step = 2.0f / float(n);
        const float u = hash_unit(x, y, 0, o.seed);
        float acc[4] = {0, 0, 0, 0};
        for (int i = 0; i < n; ++i) {
            const std::size_t s = at(x, y, -1.0f + (float(i) + u) * step, vx, vy);
            for (int k = 0; k < 4; ++k) {
                acc[k] += f[kRed + k][s];
            }
        }
        float *po = out.pixel(x, y);
        for (int k = 0; k < nc; ++k) {
            po[k] = acc[k] / float(n);
        }
    }

    /// The uniform blur of the group of cnt pixels from (x0, y); `runs`: where their motions
    /// agree, one shared run (the coherent tiles of the reconstruction; the Uniform method,
    /// the seeds' baseline, samples per pixel). Returns whether the group shared a run.
    bool uniform(Image &out, int x0, int cnt, int y, bool runs) const
    {
        Box box;
        float shortest = kInf;
        for (int j = 0; j < cnt && runs; ++j) {
            float vx, vy, len;
            own(index(x0 + j, y), vx, vy, len);
            shortest = std::min(shortest, len);
            box.add(vx, vy);
        }
        const Run r = runs && shortest >= 0.5f ? run(box) : Run{0, 0, 0, 0, 0, 1, 0};
        if (!r.ok) {
            for (int j = 0; j < cnt; ++j) {
                uniform_lane(out, x0 + j, y);
            }
            return false;
        }
        const float step = 2.0f / float(r.n);
        const float u = hash_unit(x0, y, 0, o.seed);
        float acc[8][4] = {};
        for (int i = 0; i < r.n; ++i) {
            int bx, by;
            run_origin(x0, y, -1.0f + (float(i) + u) * step, r.vx, r.vy, bx, by);
            for (int j = 0; j < cnt; ++j) {
                const std::size_t s = run_at(bx, j, by);
                for (int k = 0; k < 4; ++k) {
                    acc[j][k] += f[kRed + k][s];
                }
            }
        }
        for (int j = 0; j < cnt; ++j) {
            float *po = out.pixel(x0 + j, y);
            for (int k = 0; k < nc; ++k) {
                po[k] = acc[j][k] / float(r.n);
            }
        }
        return true;
    }

    /// Gather::reconstruct for the groups of pixels [x0, x1) of row y, eight at a time; returns
    /// how many shared a run.
    int reconstruct_groups(Image &out, int y, int x0, int x1) const
    {
        int shared = 0;
        for (int x = x0; x < x1; x += 8) {
            shared += reconstruct(out, x, std::min(8, x1 - x), y);
        }
        return shared;
    }

    /// Gather::uniform for the groups of pixels [x0, x1) of row y; returns how many shared a run.
    int uniform_groups(Image &out, int y, int x0, int x1, bool runs) const
    {
        int shared = 0;
        for (int x = x0; x < x1; x += 8) {
            shared += uniform(out, x, std::min(8, x1 - x), y, runs);
        }
        return shared;
    }
};

/// The vector rows (motion_blur_gather_kernels.cpp, Highway): reconstruct_groups and
/// uniform_groups with a group's eight pixels in the lanes of one vector, on the CPU's best
/// target that holds eight floats; where the best target holds fewer, the reference itself.
/// The frame must be under 2^29 pixels (32-bit gather offsets).
int reconstruct_row(const Gather &g, Image &out, int y, int x0, int x1);
int uniform_row(const Gather &g, Image &out, int y, int x0, int x1, bool runs);
/// Whether the rows run on vectors (the best target holds a group) rather than the reference.
bool group_lanes();

}  // namespace posthaste::shading::motion_blur_detail
