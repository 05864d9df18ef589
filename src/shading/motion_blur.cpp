// Reconstruction after McGuire et al. 2012 ("A reconstruction filter for plausible motion
// blur") with Guertin et al. 2014's second sampling direction and jittered tile lookup.
// Departure from both: the weights are split into two estimates that add up to the shutter
// time. F = the fraction of the shutter during which something in front of (or level with) the
// pixel covers it, gathered along the neighbour-max direction with a box of each sample's own
// reach; and B = what the pixel's own surface shows along its own motion, a depth-weighted mean.
// Result = sum_F + (1 - F) B. With front/back weights that sum to one (0.5 each at equal depth,
// as in Jimenez 2014), a moving edge over a static background gets exactly 1/2 coverage on
// both sides, and a uniformly moving surface averages along its path.
#include "shading/motion_blur.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <limits>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"
#include "shading/tiles.h"

namespace posthaste::shading {
namespace {

/// Everything a sample reads, in one 32-byte record (two per cache line): color (up to four
/// channels, zero-padded); the blur half-extent scaled to a coverage density, v / (2 |v|^2), so
/// that |dot(wv, d)| = (how far the motion runs along d) / (2 |v|) with no division per
/// sample (zero below half a pixel of motion); log depth (kSkyLogZ for sky); |v|.
struct Px {
    float c[4];
    float wx, wy, lz, len;
};
static_assert(sizeof(Px) == 8 * sizeof(float));

/// Log depth of sky: far beyond any finite depth, finite so that sky - sky = 0.
constexpr float kSkyLogZ = 1e30f;

double ms_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

double process_cpu_ms()
{
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

/// Weight of "Y is in front of X": 1 in front, 0 behind, 0.5 at equal depth, a linear ramp in
/// log depth (relative depth difference) of width soft_z between. Sky is behind everything
/// finite and level with sky.
inline float front(float lzy, float lzx, float inv_soft)
{
    return std::min(std::max(0.5f + (lzx - lzy) * inv_soft, 0.0f), 1.0f);  // minss/maxss, no branch
}

/// 1 while the distance t is within the reach `len`, fading to 0 over the next pixel.
inline float reach(float t, float len)
{
    return std::min(std::max(len + 0.5f - t, 0.0f), 1.0f);
}

/// The records (see Px) and the clamped half-extent vectors (2 channels, for the tile max).
struct Packed {
    std::vector<Px> px;
    Image velocity;
};

Packed pack(const Image &color, const Image &motion, const Image &depth, const MotionBlurOptions &o)
{
    const int w = motion.width(), h = motion.height(), nc = std::min(color.channels(), 4);
    Packed out{std::vector<Px>(std::size_t(w) * std::size_t(h)), Image::uninitialized(w, h, 2)};
    const float scale = 0.5f * o.shutter;
    const float max_r = std::max(o.max_radius, 0.0f);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float *m = motion.pixel(x, y);
            float vx = m[0] * scale, vy = m[1] * scale;
            if (!std::isfinite(vx) || !std::isfinite(vy)) {
                vx = vy = 0.0f;
            }
            float len = std::sqrt(vx * vx + vy * vy);
            if (!std::isfinite(len)) {
                vx = vy = len = 0.0f;
            }
            if (len > max_r) {
                const float k = max_r / len;
                vx *= k;
                vy *= k;
                len = max_r;
            }
            const float z = depth.empty() ? 1.0f : depth.at(x, y, 0);
            // NaN, zero or negative depth is treated as sky.
            const float lz = (z > 0.0f && std::isfinite(z)) ? std::log(z) : kSkyLogZ;
            Px &p = out.px[std::size_t(y) * std::size_t(w) + std::size_t(x)];
            const float *c = color.pixel(x, y);
            for (int k = 0; k < 4; ++k) {
                p.c[k] = k < nc ? c[k] : 0.0f;
            }
            const float density = len >= 0.5f ? 1.0f / (2.0f * len * len) : 0.0f;
            p.wx = vx * density;
            p.wy = vy * density;
            p.lz = lz;
            p.len = len;
            out.velocity.at(x, y, 0) = vx;
            out.velocity.at(x, y, 1) = vy;
        }
    });
    return out;
}

struct Gather {
    const Image &color;
    const Px *px_;
    const Image &velocity;
    const Image &nmax;
    const MotionBlurOptions &o;
    int w, h, nc;
    float inv_soft, inv_tile;

    const Px &px(int x, int y) const
    {
        return px_[std::size_t(y) * std::size_t(w) + std::size_t(x)];
    }

    void copy_pixel(Image &out, int x, int y) const
    {
        std::memcpy(out.pixel(x, y), color.pixel(x, y), sizeof(float) * std::size_t(nc));
    }

    static int sample_count(float len, int most)
    {
        return std::max(1, std::min(most, std::max(2, int(std::ceil(2.0f * len)))));
    }

    /// The record at x + 0.5 + t * (vx, vy), clamped to the frame (edge pixels extend).
    const Px &at(int x, int y, float t, float vx, float vy) const
    {
        // Clamp in float (branch-free minss/maxss), then truncate: the value is >= 0.
        const float fx = std::min(std::max(float(x) + 0.5f + t * vx, 0.0f), float(w) - 0.5f);
        const float fy = std::min(std::max(float(y) + 0.5f + t * vy, 0.0f), float(h) - 0.5f);
        const int sx = int(fx), sy = int(fy);
        return px(sx, sy);
    }

    void uniform(Image &out, int x, int y) const
    {
        const Px &c = px(x, y);
        if (c.len < 0.5f) {
            copy_pixel(out, x, y);
            return;
        }
        const float vx = velocity.at(x, y, 0), vy = velocity.at(x, y, 1);
        const int n = sample_count(c.len, o.samples);
        const float step = 2.0f / float(n);
        const float u = hash_unit(x, y, 0, o.seed);
        float acc[4] = {0, 0, 0, 0};
        for (int i = 0; i < n; ++i) {
            const Px &s = at(x, y, -1.0f + (float(i) + u) * step, vx, vy);
            for (int k = 0; k < 4; ++k) {
                acc[k] += s.c[k];
            }
        }
        float *po = out.pixel(x, y);
        for (int k = 0; k < nc; ++k) {
            po[k] = acc[k] / float(n);
        }
    }

    void reconstruct(Image &out, int x, int y) const
    {
        const float tile = float(o.tile);
        // Jittered neighbour-max lookup: pixels near a tile border sometimes read the next
        // tile's neighbourhood, which turns seams into noise (Guertin 2014).
        const std::uint32_t hj = hash4(std::uint32_t(x), std::uint32_t(y), 1u, o.seed);
        const float jx = (hash_to_unit(hj) - 0.5f) * 2.0f * o.tile_jitter * tile;
        const float jy = (hash_to_unit(pcg_hash(hj)) - 0.5f) * 2.0f * o.tile_jitter * tile;
        const int tx =
            std::min(int(std::max(float(x) + 0.5f + jx, 0.0f) * inv_tile), nmax.width() - 1);
        const int ty =
            std::min(int(std::max(float(y) + 0.5f + jy, 0.0f) * inv_tile), nmax.height() - 1);
        float nvx = nmax.at(tx, ty, 0), nvy = nmax.at(tx, ty, 1);
        float L = std::sqrt(nvx * nvx + nvy * nvy);
        if (L < 0.5f) {
            copy_pixel(out, x, y);
            return;
        }
        const Px &c = px(x, y);
        const float cvx = velocity.at(x, y, 0), cvy = velocity.at(x, y, 1);
        float dnx = nvx / L, dny = nvy / L;
        const std::uint32_t hu = hash4(std::uint32_t(x), std::uint32_t(y), 0u, o.seed);
        const float u = hash_to_unit(hu), u2 = hash_to_unit(pcg_hash(hu));

        float fg[4] = {0, 0, 0, 0}, bg[4] = {0, 0, 0, 0};
        float F = 0.0f, B = 0.0f;

        // Does the pixel's own path share the neighbour-max samples? Only if it is aligned
        // with them and long enough for their spacing; else it gets samples of its own.
        const bool own_path = c.len >= 0.5f;
        const float dcx = own_path ? cvx / c.len : 0.0f, dcy = own_path ? cvy / c.len : 0.0f;
        const bool shared = own_path && std::abs(dcx * dnx + dcy * dny) > 0.9f && c.len >= 0.5f * L;
        const float inv_own = own_path ? 1.0f / (2.0f * c.len) : 0.0f;
        if (shared) {
            // Departure: sample along the pixel's own direction (over the neighbourhood's
            // length). Where everything moves alike (camera turns) the neighbour-max direction
            // is an arbitrary one of many near-equal vectors, degrees off this pixel's path.
            dnx = dcx;
            dny = dcy;
            nvx = dcx * L;
            nvy = dcy * L;
            if (c.len > 0.8f * L) {
                // Nearly the longest around: the pixel's own path, sampled densely.
                nvx = cvx;
                nvy = cvy;
                L = c.len;
            }
        }

        const int n = sample_count(L, o.samples);
        const float step = 2.0f / float(n);
        const float delta = L * step;  // path length each sample stands for
        const float own_w = shared ? delta * inv_own : 0.0f;
        for (int i = 0; i < n; ++i) {
            const float t = -1.0f + (float(i) + u) * step;
            const Px &s = at(x, y, t, nvx, nvy);
            const float T = std::abs(t) * L;
            const float f = front(s.lz, c.lz, inv_soft);
            // Coverage of X by Y: Y's reach along the sampled line, time density along the
            // line |dot(vY, d)| / |vY| / (2 |vY|) (zero for Y slower than half a pixel).
            const float wf = f * reach(T, s.len) * std::abs(s.wx * dnx + s.wy * dny) * delta;
            // X's own surface along its own path (shared samples).
            const float wb = (1.0f - f) * reach(T, c.len) * own_w;
            F += wf;
            B += wb;
            for (int k = 0; k < 4; ++k) {
                fg[k] += wf * s.c[k];
                bg[k] += wb * s.c[k];
            }
        }
        // Path length per sample of the pixel's own path (its own samples or the shared ones).
        float own_delta = delta;
        if (own_path && !shared) {
            // Guertin 2014's second direction: the pixel's own motion, for its own surface.
            const int m = std::max(2, std::min(sample_count(c.len, o.samples), (n + 1) / 2));
            const float mstep = 2.0f / float(m);
            own_delta = c.len * mstep;
            const float wm = own_delta * inv_own;
            for (int i = 0; i < m; ++i) {
                const Px &s = at(x, y, -1.0f + (float(i) + u2) * mstep, cvx, cvy);
                const float wb = (1.0f - front(s.lz, c.lz, inv_soft)) * wm;
                B += wb;
                for (int k = 0; k < 4; ++k) {
                    bg[k] += wb * s.c[k];
                }
            }
        }
        float *po = out.pixel(x, y);
        if (F >= 1.0f) {
            for (int k = 0; k < nc; ++k) {
                po[k] = fg[k] / F;
            }
            return;
        }
        // The pixel itself, so that B > 0. Where the pixel has a path of its own, the samples
        // already cover its centre: a full weight here would sharpen, so it only breaks ties.
        const float wc = own_path ? 1e-3f * own_delta * inv_own : 1.0f;
        B += wc;
        const float rest = (1.0f - F) / B;
        for (int k = 0; k < nc; ++k) {
            po[k] = fg[k] + rest * (bg[k] + wc * c.c[k]);
        }
    }
};

}  // namespace

Image motion_blur(const Image &color,
                  const Image &motion,
                  const Image &depth,
                  const MotionBlurOptions &options,
                  MotionBlurStats *stats)
{
    MotionBlurOptions o = options;
    o.tile = std::max(o.tile, 1);
    o.samples = std::max(o.samples, 1);
    o.soft_z = std::max(o.soft_z, 1e-6f);
    const int w = color.width(), h = color.height();
    MotionBlurStats st;
    auto t0 = std::chrono::steady_clock::now();
    double c0 = process_cpu_ms();
    const Packed packed = pack(color, motion, depth, o);
    st.pack_ms = ms_since(t0);
    st.pack_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    const Image tiles = tile_max(packed.velocity, o.tile);
    st.tile_max_ms = ms_since(t0);
    st.tile_max_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    float longest = 0.0f;
    for (int ty = 0; ty < tiles.height(); ++ty) {
        for (int tx = 0; tx < tiles.width(); ++tx) {
            longest = std::max(longest, std::hypot(tiles.at(tx, ty, 0), tiles.at(tx, ty, 1)));
        }
    }
    // Reach in tiles of the longest vector, plus one for the jittered lookup.
    const int radius = int(std::ceil(longest / float(o.tile))) + (o.tile_jitter > 0.0f ? 1 : 0);
    const Image nmax = neighbour_max(tiles, std::max(radius, 1));
    const Image nbounds =
        o.coherence > 0.0f && o.method == BlurMethod::Reconstruct
            ? neighbour_bounds(tile_bounds(packed.velocity, o.tile), std::max(radius, 1))
            : Image();
    st.neighbour_max_ms = ms_since(t0);
    st.neighbour_max_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    Image out = Image::uninitialized(w, h, color.channels());
    const Gather g{color,
                   packed.px.data(),
                   packed.velocity,
                   nmax,
                   o,
                   w,
                   h,
                   std::min(color.channels(), 4),
                   1.0f / o.soft_z,
                   1.0f / float(o.tile)};
    const int nt_x = nmax.width(), nt_y = nmax.height();
    // Per tile: 1 copied, 2 coherent (uniform path), 0 reconstructed.
    std::vector<unsigned char> kind(std::size_t(nt_x) * std::size_t(nt_y), 0);
    parallel_for_tiles(
        out.bounds(),
        [&](const Rect &r) {
            const int tx = r.x0 / o.tile, ty = r.y0 / o.tile;
            // Copy a tile outright when no lookup its jitter can reach sees half a pixel of
            // motion (the Uniform method reads the tile max, its own pixels' longest).
            bool still = true;
            if (o.method == BlurMethod::Uniform) {
                still = std::hypot(tiles.at(tx, ty, 0), tiles.at(tx, ty, 1)) < 0.5f;
            } else {
                for (int y = std::max(0, ty - 1); y <= std::min(nt_y - 1, ty + 1) && still; ++y) {
                    for (int x = std::max(0, tx - 1); x <= std::min(nt_x - 1, tx + 1); ++x) {
                        if (std::hypot(nmax.at(x, y, 0), nmax.at(x, y, 1)) >= 0.5f) {
                            still = false;
                            break;
                        }
                    }
                }
            }
            if (still) {
                for (int y = r.y0; y < r.y1; ++y) {
                    std::memcpy(out.pixel(r.x0, y),
                                color.pixel(r.x0, y),
                                sizeof(float) * std::size_t(r.width() * color.channels()));
                }
                kind[std::size_t(ty) * std::size_t(nt_x) + std::size_t(tx)] = 1;
                return;
            }
            // Coherent tiles: every vector that can reach the tile is within `coherence` x the
            // longest of every other, so depth order cannot change what covers what, and the
            // reconstruction reduces to the average along the pixel's own path (Guertin 2014's
            // fast path; 3x cheaper per sample).
            bool coherent = false;
            if (!nbounds.empty()) {
                const float *b = nbounds.pixel(tx, ty);
                const float extent = std::max(b[2] - b[0], b[3] - b[1]);
                coherent =
                    extent <= o.coherence * std::hypot(nmax.at(tx, ty, 0), nmax.at(tx, ty, 1));
            }
            if (coherent) {
                kind[std::size_t(ty) * std::size_t(nt_x) + std::size_t(tx)] = 2;
            }
            for (int y = r.y0; y < r.y1; ++y) {
                for (int x = r.x0; x < r.x1; ++x) {
                    if (o.method == BlurMethod::Uniform || coherent) {
                        g.uniform(out, x, y);
                    } else {
                        g.reconstruct(out, x, y);
                    }
                }
            }
        },
        o.tile);
    st.gather_ms = ms_since(t0);
    st.gather_cpu_ms = process_cpu_ms() - c0;
    st.tiles_total = nt_x * nt_y;
    for (unsigned char k : kind) {
        st.tiles_copied += k == 1;
        st.tiles_coherent += k == 2;
    }
    if (stats) {
        *stats = st;
    }
    return out;
}

}  // namespace posthaste::shading
