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
#include <limits>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"
#include "shading/tiles.h"

namespace posthaste::shading {
namespace {

/// Per-pixel data read by every sample, packed: blur half-extent (px), depth, its length.
struct Px {
    float vx, vy, z, len;
};

double ms_since(std::chrono::steady_clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
        .count();
}

/// Weight of "Y is in front of X": 1 in front, 0 behind, 0.5 at equal depth, a linear ramp
/// over soft_z x depth between. Sky (+inf) is behind everything finite and level with sky.
inline float front(float zy, float zx, float soft_z)
{
    if (zy == zx) {
        return 0.5f;  // includes sky against sky
    }
    const float zmin = std::min(zx, zy);
    if (std::isinf(zx) || std::isinf(zy)) {
        return zy < zx ? 1.0f : 0.0f;
    }
    return std::clamp(0.5f + (zx - zy) / (soft_z * zmin), 0.0f, 1.0f);
}

/// 1 while the distance t is within the reach `len`, fading to 0 over the next pixel.
inline float reach(float t, float len)
{
    return std::clamp(len + 0.5f - t, 0.0f, 1.0f);
}

/// Channels: blur half-extent x, y (pixels), depth (+inf for sky), half-extent length.
Image pack(const Image &motion, const Image &depth, const MotionBlurOptions &o)
{
    const int w = motion.width(), h = motion.height();
    Image buf = Image::uninitialized(w, h, 4);
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
            float z = depth.empty() ? 1.0f : depth.at(x, y, 0);
            if (std::isnan(z) || z <= 0.0f) {
                z = std::numeric_limits<float>::infinity();
            }
            float *p = buf.pixel(x, y);
            p[0] = vx;
            p[1] = vy;
            p[2] = z;
            p[3] = len;
        }
    });
    return buf;
}

struct Gather {
    const Image &color;
    const Image &buf;
    const Image &nmax;
    const MotionBlurOptions &o;
    int w, h, nc;

    const Px &px(int x, int y) const { return *reinterpret_cast<const Px *>(buf.pixel(x, y)); }

    void copy_pixel(Image &out, int x, int y) const
    {
        std::memcpy(out.pixel(x, y), color.pixel(x, y), sizeof(float) * std::size_t(nc));
    }

    static int sample_count(float len, int most)
    {
        return std::max(1, std::min(most, std::max(2, int(std::ceil(2.0f * len)))));
    }

    void uniform(Image &out, int x, int y) const
    {
        const Px &c = px(x, y);
        if (c.len < 0.5f) {
            copy_pixel(out, x, y);
            return;
        }
        const int n = sample_count(c.len, o.samples);
        const float u = hash_unit(x, y, 0, o.seed);
        float acc[4] = {0, 0, 0, 0};
        for (int i = 0; i < n; ++i) {
            const float t = -1.0f + 2.0f * (float(i) + u) / float(n);
            const int sx = std::clamp(int(std::floor(float(x) + 0.5f + t * c.vx)), 0, w - 1);
            const int sy = std::clamp(int(std::floor(float(y) + 0.5f + t * c.vy)), 0, h - 1);
            const float *p = color.pixel(sx, sy);
            for (int k = 0; k < nc; ++k) {
                acc[k] += p[k];
            }
        }
        float *po = out.pixel(x, y);
        for (int k = 0; k < nc; ++k) {
            po[k] = acc[k] / float(n);
        }
    }

    void reconstruct(Image &out, int x, int y) const
    {
        const int tile = o.tile;
        // Jittered neighbour-max lookup: pixels near a tile border sometimes read the next
        // tile's neighbourhood, which turns seams into noise (Guertin 2014).
        const float jx = (hash_unit(x, y, 1, o.seed) - 0.5f) * 2.0f * o.tile_jitter * tile;
        const float jy = (hash_unit(x, y, 2, o.seed) - 0.5f) * 2.0f * o.tile_jitter * tile;
        const int tx = std::clamp(int(std::floor((float(x) + 0.5f + jx) / float(tile))), 0,
                                  nmax.width() - 1);
        const int ty = std::clamp(int(std::floor((float(y) + 0.5f + jy) / float(tile))), 0,
                                  nmax.height() - 1);
        float nvx = nmax.at(tx, ty, 0), nvy = nmax.at(tx, ty, 1);
        float L = std::sqrt(nvx * nvx + nvy * nvy);
        if (L < 0.5f) {
            copy_pixel(out, x, y);
            return;
        }
        const Px &c = px(x, y);
        float dnx = nvx / L, dny = nvy / L;
        const float u = hash_unit(x, y, 0, o.seed);

        float fg[4] = {0, 0, 0, 0}, bg[4] = {0, 0, 0, 0};
        float F = 0.0f, B = 0.0f;
        const float *cx = color.pixel(x, y);

        // Does the pixel's own path share the neighbour-max samples? Only if it is aligned
        // with them and long enough for their spacing; else it gets samples of its own.
        const bool own_path = c.len >= 0.5f;
        const float dcx = own_path ? c.vx / c.len : 0.0f, dcy = own_path ? c.vy / c.len : 0.0f;
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
                nvx = c.vx;
                nvy = c.vy;
                L = c.len;
            }
        }

        const int n = sample_count(L, o.samples);
        const float delta = 2.0f * L / float(n);  // path length each sample stands for
        for (int i = 0; i < n; ++i) {
            const float t = -1.0f + 2.0f * (float(i) + u) / float(n);
            const int sx = std::clamp(int(std::floor(float(x) + 0.5f + t * nvx)), 0, w - 1);
            const int sy = std::clamp(int(std::floor(float(y) + 0.5f + t * nvy)), 0, h - 1);
            const Px &s = px(sx, sy);
            const float T = std::abs(t) * L;
            const float f = front(s.z, c.z, o.soft_z);
            const float *cs = color.pixel(sx, sy);
            // Coverage of X by Y: Y's reach along the sampled line, time density 1 / (2 |vY|).
            if (f > 0.0f && s.len >= 0.5f) {
                const float along = std::abs(s.vx * dnx + s.vy * dny) / s.len;
                const float wf = f * reach(T, s.len) * along * delta / (2.0f * s.len);
                F += wf;
                for (int k = 0; k < nc; ++k) {
                    fg[k] += wf * cs[k];
                }
            }
            if (shared) {
                const float wb = (1.0f - f) * reach(T, c.len) * delta * inv_own;
                B += wb;
                for (int k = 0; k < nc; ++k) {
                    bg[k] += wb * cs[k];
                }
            }
        }
        // Path length per sample of the pixel's own path (its own samples or the shared ones).
        float own_delta = delta;
        if (own_path && !shared) {
            // Guertin 2014's second direction: the pixel's own motion, for its own surface.
            const int m = std::max(2, std::min(sample_count(c.len, o.samples), (n + 1) / 2));
            const float dm = 2.0f * c.len / float(m);
            own_delta = dm;
            const float u2 = hash_unit(x, y, 3, o.seed);
            for (int i = 0; i < m; ++i) {
                const float t = -1.0f + 2.0f * (float(i) + u2) / float(m);
                const int sx = std::clamp(int(std::floor(float(x) + 0.5f + t * c.vx)), 0, w - 1);
                const int sy = std::clamp(int(std::floor(float(y) + 0.5f + t * c.vy)), 0, h - 1);
                const Px &s = px(sx, sy);
                const float wb = (1.0f - front(s.z, c.z, o.soft_z)) * dm * inv_own;
                const float *cs = color.pixel(sx, sy);
                B += wb;
                for (int k = 0; k < nc; ++k) {
                    bg[k] += wb * cs[k];
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
        for (int k = 0; k < nc; ++k) {
            bg[k] += wc * cx[k];
        }
        const float rest = (1.0f - F) / B;
        for (int k = 0; k < nc; ++k) {
            po[k] = fg[k] + rest * bg[k];
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
    const Image buf = pack(motion, depth, o);
    st.pack_ms = ms_since(t0);

    t0 = std::chrono::steady_clock::now();
    const Image tiles = tile_max(buf, o.tile);
    st.tile_max_ms = ms_since(t0);

    t0 = std::chrono::steady_clock::now();
    float longest = 0.0f;
    for (int ty = 0; ty < tiles.height(); ++ty) {
        for (int tx = 0; tx < tiles.width(); ++tx) {
            longest = std::max(longest, std::hypot(tiles.at(tx, ty, 0), tiles.at(tx, ty, 1)));
        }
    }
    // Reach in tiles of the longest vector, plus one for the jittered lookup.
    const int radius = int(std::ceil(longest / float(o.tile))) + (o.tile_jitter > 0.0f ? 1 : 0);
    const Image nmax = neighbour_max(tiles, std::max(radius, 1));
    st.neighbour_max_ms = ms_since(t0);

    t0 = std::chrono::steady_clock::now();
    Image out = Image::uninitialized(w, h, color.channels());
    const Gather g{color, buf, nmax, o, w, h, color.channels()};
    const int nt_x = nmax.width(), nt_y = nmax.height();
    std::vector<unsigned char> copied(std::size_t(nt_x) * std::size_t(nt_y), 0);
    parallel_for_tiles(
        out.bounds(),
        [&](const Rect &r) {
            const int tx = r.x0 / o.tile, ty = r.y0 / o.tile;
            // Copy a tile outright when no lookup its jitter can reach sees half a pixel of
            // motion (the Uniform method reads the tile max, its own pixels' longest).
            bool still = true;
            if (o.method == BlurMethod::Uniform) {
                still = std::hypot(tiles.at(tx, ty, 0), tiles.at(tx, ty, 1)) < 0.5f;
            }
            else {
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
                    std::memcpy(out.pixel(r.x0, y), color.pixel(r.x0, y),
                                sizeof(float) * std::size_t(r.width() * color.channels()));
                }
                copied[std::size_t(ty) * std::size_t(nt_x) + std::size_t(tx)] = 1;
                return;
            }
            for (int y = r.y0; y < r.y1; ++y) {
                for (int x = r.x0; x < r.x1; ++x) {
                    if (o.method == BlurMethod::Uniform) {
                        g.uniform(out, x, y);
                    }
                    else {
                        g.reconstruct(out, x, y);
                    }
                }
            }
        },
        o.tile);
    st.gather_ms = ms_since(t0);
    st.tiles_total = nt_x * nt_y;
    for (unsigned char c : copied) {
        st.tiles_copied += c;
    }
    if (stats) {
        *stats = st;
    }
    return out;
}

}  // namespace posthaste::shading
