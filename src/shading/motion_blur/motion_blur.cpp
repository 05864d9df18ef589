// Reconstruction after McGuire et al. 2012 ("A reconstruction filter for plausible motion
// blur") with Guertin et al. 2014's second sampling direction and jittered tile lookup.
// Departure from both: the weights are split into two estimates that add up to the shutter
// time. F = the fraction of the shutter during which something in front of (or level with) the
// pixel covers it, gathered along the neighbour-max direction with a box of each sample's own
// reach; and B = what the pixel's own surface shows along its own motion, a depth-weighted mean.
// Result = sum_F + (1 - F) B. With front/back weights that sum to one (0.5 each at equal depth,
// as in Jimenez 2014), a moving edge over a static background gets exactly 1/2 coverage on
// both sides, and a uniformly moving surface averages along its path.
#include "shading/motion_blur/motion_blur.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

#include "core/hash.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "core/timing.h"
#include "shading/motion_blur/motion_blur_gather.h"
#include "shading/tiles.h"

namespace posthaste::shading {

using namespace motion_blur_detail;

namespace {

/// Whether the vector pack and rows run (Highway, the CPU's best target): not asked for the
/// reference (POSTHASTE_SIMD=scalar), and the frame is small enough for the rows' 32-bit gather
/// offsets.
bool vector_path(const Image &color)
{
    return simd::requested() != simd::Level::Scalar &&
           std::size_t(color.width()) * std::size_t(color.height()) * 4 < (std::size_t(1) << 31);
}

/// The tile max (and, with `want_bounds`, tile bounds) the pack folded in, else tiles.h's from
/// the velocity image.
void packed_tiles(Packed &packed, int tile, bool want_bounds, Image &tiles, Image &bounds)
{
    tiles = std::move(packed.tiles);
    bounds = std::move(packed.bounds);
    if (tiles.empty()) {
        tile_max_bounds(packed.velocity, tile, 0, &tiles, want_bounds ? &bounds : nullptr);
    }
}

/// The lighting split's rest: colour less o.subtract over its rectangle, in the records that
/// the gather and the copies read.
void subtract_from_records(Packed &packed, int w, int h, const MotionBlurOptions &o)
{
    const Image &s = *o.subtract;
    const Rect r =
        Rect{o.subtract_x0, o.subtract_y0, o.subtract_x0 + s.width(), o.subtract_y0 + s.height()}
            .intersect(Rect{0, 0, w, h});
    const int sc = s.channels();
    parallel_for(r.y0, r.y1, [&](int y) {
        const float *src = s.pixel(r.x0 - o.subtract_x0, y - o.subtract_y0);
        const std::size_t row = std::size_t(y) * std::size_t(w);
        float *red = packed.plane(kRed) + row, *green = packed.plane(kGreen) + row,
              *blue = packed.plane(kBlue) + row;
        for (int x = r.x0; x < r.x1; ++x, src += sc) {
            red[x] -= src[0];
            green[x] -= src[1];
            blue[x] -= src[2];
        }
    });
}

}  // namespace

void motion_blur_tiles(const Image &color,
                       const Image &motion,
                       const Image &depth,
                       const MotionBlurOptions &options,
                       Image &tiles,
                       Image &bounds)
{
    MotionBlurOptions o = options;
    o.tile = std::max(o.tile, 1);
    Packed packed = pack(color, motion, depth, o, vector_path(color), true);
    packed_tiles(packed, o.tile, true, tiles, bounds);
}

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
    const bool vector = vector_path(color);
    const bool want_bounds = o.coherence > 0.0f && o.method == BlurMethod::Reconstruct;
    Packed packed = pack(color, motion, depth, o, vector, want_bounds);
    if (o.subtract && color.channels() >= 3) {
        subtract_from_records(packed, w, h, o);
    }
    st.pack_ms = ms_since(t0);
    st.pack_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    Image tiles, bounds;
    packed_tiles(packed, o.tile, want_bounds, tiles, bounds);
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
    // Per tile, only the tiles whose own vectors can reach it (plus the jitter's one tile):
    // slow regions beside fast ones get a short neighbour max (fewer samples, along motion that
    // can actually cover them) and pass the coherence test more often.
    const int margin = o.tile_jitter > 0.0f ? 1 : 0;
    Image nmax, nbounds;
    neighbour_reach(tiles,
                    want_bounds ? &bounds : nullptr,
                    o.tile,
                    margin,
                    std::max(radius, 1),
                    &nmax,
                    want_bounds ? &nbounds : nullptr);
    st.neighbour_max_ms = ms_since(t0);
    st.neighbour_max_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    Image out = Image::uninitialized(w, h, color.channels());
    const Gather g(color, packed, nmax, o, std::min(color.channels(), 4));
    const int nt_x = nmax.width(), nt_y = nmax.height();
    // skip_empty: the tiles no path of the longest vector (and the lookup's jitter) can carry
    // a non-zero value into gather zeros; they are copied.
    std::vector<std::uint8_t> in_reach;
    if (o.skip_empty) {
        const float *const planes[4] = {
            packed.plane(kRed), packed.plane(kGreen), packed.plane(kBlue), packed.plane(kAlpha)};
        in_reach =
            tiles_in_reach(occupied_tiles(planes, w, h, o.tile), nt_x, nt_y, [&](std::size_t) {
                return radius + 1;
            });
    }
    // Per tile: 1 copied, 2 coherent (uniform path), 0 reconstructed.
    std::vector<unsigned char> kind(std::size_t(nt_x) * std::size_t(nt_y), 0);
    // Per band: the 8-pixel groups gathered, and how many of them shared a run.
    std::vector<long> groups(std::size_t(nt_y), 0), shared_groups(std::size_t(nt_y), 0);
    const auto classify = [&](int tx, int ty) -> unsigned char {
        // Copy a tile outright when no lookup its jitter can reach sees half a pixel of motion
        // (the Uniform method reads the tile max, its own pixels' longest).
        bool still = true;
        if (!in_reach.empty() && !in_reach[std::size_t(ty) * std::size_t(nt_x) + std::size_t(tx)]) {
            return 1;
        }
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
            return 1;
        }
        // Coherent tiles: every vector that can reach the tile is within `coherence` x the
        // longest of every other, so depth order cannot change what covers what, and the
        // reconstruction reduces to the average along the pixel's own path (Guertin 2014's
        // fast path; 3x cheaper per sample).
        if (!nbounds.empty()) {
            const float *b = nbounds.pixel(tx, ty);
            const float extent = std::max(b[2] - b[0], b[3] - b[1]);
            if (extent <= o.coherence * std::hypot(nmax.at(tx, ty, 0), nmax.at(tx, ty, 1))) {
                return 2;
            }
        }
        return 0;
    };
    // One band of tiles a task, swept in rows of a few hundred pixels (each tile's row segment
    // by its kind): the rows' records, velocities and output are then read and written in
    // order, which the hardware prefetchers follow; tile by tile, every 8-pixel group began
    // with a cache miss on a new row (measured: a third of the coherent path's time).
    parallel_for(0, nt_y, [&](int ty) {
        unsigned char *band = &kind[std::size_t(ty) * std::size_t(nt_x)];
        for (int tx = 0; tx < nt_x; ++tx) {
            band[tx] = classify(tx, ty);
        }
        const int y0 = ty * o.tile, y1 = std::min(h, y0 + o.tile);
        // Row y of tiles [c0, c1) of the band. Neighbouring tiles of one kind form one row
        // segment when groups of 8 tile them (the groups are the same; longer segments let a
        // row plan ahead).
        const auto sweep = [&](int y, int c0, int c1, bool merge) {
            for (int tx = c0, tn = 1; tx < c1; tx += tn) {
                tn = 1;
                while (merge && tx + tn < c1 && band[tx + tn] == band[tx]) {
                    ++tn;
                }
                const int x0 = tx * o.tile, x1 = std::min(w, (tx + tn) * o.tile);
                if (band[tx] == 1) {
                    if (o.subtract) {  // the records hold colour less the share
                        for (int x = x0; x < x1; ++x) {
                            g.copy_pixel(out, x, y);
                        }
                    } else {
                        std::memcpy(out.pixel(x0, y),
                                    color.pixel(x0, y),
                                    sizeof(float) * std::size_t((x1 - x0) * color.channels()));
                    }
                    continue;
                }
                const bool coherent = band[tx] == 2;
                const bool uniform = o.method == BlurMethod::Uniform || coherent;
                // Groups of 8 from each tile's left edge.
                for (int t = tx; t < tx + tn; ++t) {
                    groups[std::size_t(ty)] += (std::min(w, (t + 1) * o.tile) - t * o.tile + 7) / 8;
                }
                if (vector) {
                    shared_groups[std::size_t(ty)] += uniform
                                                          ? uniform_row(g, out, y, x0, x1, coherent)
                                                          : reconstruct_row(g, out, y, x0, x1);
                } else {
                    shared_groups[std::size_t(ty)] +=
                        uniform ? g.uniform_groups(out, y, x0, x1, coherent)
                                : g.reconstruct_groups(out, y, x0, x1);
                }
            }
        };
        const bool merge = o.tile % 8 == 0;
        // The band is swept in columns of about 256 px, all its rows one column at a time:
        // consecutive rows then read mostly the same sample lines, which stay in L2 (a whole
        // row's samples, about 2 MB on the fast translation, did not). Measured, f6: 16 tiles
        // 33.8 ms, 8 tiles 34.5, 32 tiles 34.8, whole rows 37.2.
        const int chunk = std::max(1, 256 / o.tile);
        for (int c0 = 0; c0 < nt_x; c0 += chunk) {
            const int c1 = std::min(nt_x, c0 + chunk);
            for (int y = y0; y < y1; ++y) {
                sweep(y, c0, c1, merge);
            }
        }
    });
    st.gather_ms = ms_since(t0);
    st.gather_cpu_ms = process_cpu_ms() - c0;
    st.tiles_total = nt_x * nt_y;
    for (unsigned char k : kind) {
        st.tiles_copied += k == 1;
        st.tiles_coherent += k == 2;
    }
    for (int ty = 0; ty < nt_y; ++ty) {
        st.groups += groups[std::size_t(ty)];
        st.groups_shared += shared_groups[std::size_t(ty)];
    }
    if (stats) {
        *stats = st;
    }
    return out;
}

}  // namespace posthaste::shading
