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
#include "core/simd_avx2.h"
#include "core/timing.h"
#include "shading/tiles.h"

namespace posthaste::shading {
namespace {

/// Everything a sample reads, in one 32-byte record (two per cache line): color (up to four
/// channels, zero-padded); the blur half-extent scaled to a coverage density, v / (2 |v|^2), so
/// that |dot(wv, d)| = (how far the motion runs along d) / (2 |v|) with no division per
/// sample (zero below half a pixel of motion); log depth (kSkyLogZ for sky); |v|.
/// Log depth of sky: far beyond any finite depth, finite so that sky - sky = 0.
constexpr float kSkyLogZ = 1e30f;
constexpr float kInf = std::numeric_limits<float>::infinity();

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

/// Uninitialized storage for n trivial records from the scratch pool (core/memory.h; pack
/// writes every record before it is read).
template <class T>
using Scratch = ScratchArray<T>;
template <class T>
Scratch<T> scratch(std::size_t n)
{
    return scratch_array<T>(n);
}

/// The per-pixel records of a frame, one plane per field (structure of arrays): the eight
/// pixels of a group sample eight adjacent pixels of one row (see Gather), which is one 32-byte
/// load per field, and a sample reads only the fields it uses. Colour: four planes, zero-padded
/// past the image's channels (floats, so the output stays a convex combination of input
/// values). Log depth: kSkyLogZ for sky. The blur half-extent scaled to a coverage density,
/// v / (2 |v|^2), so that |dot(w, d)| = (how far the motion runs along d) / (2 |v|) with no
/// division per sample (zero below half a pixel of motion); and |v|.
enum Field { kRed, kGreen, kBlue, kAlpha, kLogZ, kWx, kWy, kLen, kFields };

/// The planes (allocated uninitialized; pack writes every record) and the clamped half-extent
/// vectors (2 channels, for the tile max).
struct Packed {
    Scratch<float> block;
    std::size_t stride = 0;  ///< floats from one plane to the next (a multiple of 16)
    /// The clamped half-extent vectors (2 channels) for tiles.h's reductions, where the pack
    /// does not fold them itself (scalar path, tiles not a multiple of 8); else empty. The
    /// gather recovers a pixel's vector from its planes: v = w 2|v|^2.
    Image velocity;
    /// Per row: every alpha is exactly 1 (RGBA colour). A frame opaque everywhere blurs to
    /// alpha 1, and the gather does not sum its alpha plane.
    std::vector<unsigned char> opaque_rows;
    /// Tile max and tile bounds of the velocities (tiles.h), when the pack reduced them
    /// (AVX2, tiles a multiple of 8 wide); else empty.
    Image tiles, bounds;

    float *plane(int field) const { return block.get() + std::size_t(field) * stride; }
};

/// Writes the records and velocities of a frame, row by row.
struct Packer {
    const Image &color, &motion, &depth;
    Packed &out;
    int w, nc;
    float scale, max_r;

    /// The record of pixel (x, y); its velocity into (vx_out, vy_out) and the velocity image
    /// (when there is one).
    void pixel(int y, int x, float &vx_out, float &vy_out) const
    {
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
        const std::size_t i = std::size_t(y) * std::size_t(w) + std::size_t(x);
        const float *c = color.pixel(x, y);
        for (int k = 0; k < 4; ++k) {
            out.plane(kRed + k)[i] = k < nc ? c[k] : 0.0f;
        }
        const float density = len >= 0.5f ? 1.0f / (2.0f * len * len) : 0.0f;
        out.plane(kWx)[i] = vx * density;
        out.plane(kWy)[i] = vy * density;
        out.plane(kLogZ)[i] = lz;
        out.plane(kLen)[i] = len;
        if (!out.velocity.empty()) {
            out.velocity.at(x, y, 0) = vx;
            out.velocity.at(x, y, 1) = vy;
        }
        vx_out = vx;
        vy_out = vy;
    }

    /// Pixels [x0, x1) of row y; returns whether their alpha is exactly 1 (RGBA only).
    /// With vx, vy: the velocities into them (x - x0 indexed).
    bool pixels(int y, int x0, int x1, float *vx = nullptr, float *vy = nullptr) const
    {
        bool opaque = nc == 4;
        for (int x = x0; x < x1; ++x) {
            float a, b;
            pixel(y, x, a, b);
            if (vx) {
                vx[x - x0] = a;
                vy[x - x0] = b;
            }
            opaque = opaque && color.pixel(x, y)[3] == 1.0f;
        }
        return opaque;
    }
};

#if POSTHASTE_HAVE_AVX2_TARGET
using simd::v8::set1;
using simd::v8::V;
using simd::v8::VI;

POSTHASTE_AVX2_INLINE V abs8(V x)
{
    return _mm256_andnot_ps(set1(-0.0f), x);
}
POSTHASTE_AVX2_INLINE V finite8(V x)
{
    return _mm256_cmp_ps(abs8(x), set1(std::numeric_limits<float>::infinity()), _CMP_LT_OQ);
}

/// Per tile of a band, eight lanes of tile_max_bounds: the longest vector so far (length^2,
/// x, y, and its scan index in the tile, for ties) and the box.
struct TileAcc8 {
    V l, x, y, lo_x, lo_y, hi_x, hi_y;
    VI i;
};

/// Folds eight vectors (scan indices idx in their tile; lanes outside `ok` ignored) into a
/// tile's accumulators. The squared lengths are rounded as in tile_max_bounds (compiled
/// without FMA): the products are kept from fusing, so the paths pick the same vector.
POSTHASTE_AVX2_INLINE void fold8(TileAcc8 &a, V vx, V vy, VI idx, V ok)
{
    V xx = _mm256_mul_ps(vx, vx), yy = _mm256_mul_ps(vy, vy);
    asm("" : "+x"(xx), "+x"(yy));  // no FMA contraction of the sum below
    const V l = _mm256_add_ps(xx, yy);
    const V gt = _mm256_and_ps(
        _mm256_and_ps(_mm256_cmp_ps(l, a.l, _CMP_GT_OQ), _mm256_cmp_ps(l, set1(kInf), _CMP_LT_OQ)),
        ok);
    a.l = _mm256_blendv_ps(a.l, l, gt);
    a.x = _mm256_blendv_ps(a.x, vx, gt);
    a.y = _mm256_blendv_ps(a.y, vy, gt);
    a.i = _mm256_castps_si256(
        _mm256_blendv_ps(_mm256_castsi256_ps(a.i), _mm256_castsi256_ps(idx), gt));
    a.lo_x = _mm256_blendv_ps(a.lo_x, _mm256_min_ps(a.lo_x, vx), ok);
    a.lo_y = _mm256_blendv_ps(a.lo_y, _mm256_min_ps(a.lo_y, vy), ok);
    a.hi_x = _mm256_blendv_ps(a.hi_x, _mm256_max_ps(a.hi_x, vx), ok);
    a.hi_y = _mm256_blendv_ps(a.hi_y, _mm256_max_ps(a.hi_y, vy), ok);
}

/// Packer::pixels for a whole row, eight pixels at a time (the same arithmetic; log is the
/// polynomial of simd::v8, within 2 ulp of std::log).
/// With `acc` (a band's tile accumulators, tiles `tile` wide, a multiple of 8; row r of the
/// band), also folds the row's vectors into its tiles.
POSTHASTE_AVX2 bool pack_row_avx2(
    const Packer &p, int y, TileAcc8 *acc = nullptr, int r = 0, int tile = 8)
{
    bool opaque = p.nc == 4;
    const V all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const VI mstride = _mm256_mullo_epi32(lane, _mm256_set1_epi32(p.motion.channels()));
    const VI cstride = _mm256_mullo_epi32(lane, _mm256_set1_epi32(p.color.channels()));
    const V scale = set1(p.scale), max_r = set1(p.max_r), zero = _mm256_setzero_ps();
    int x = 0;
    for (; x + 8 <= p.w; x += 8) {
        const float *m = p.motion.pixel(x, y);
        V vx, vy;
        if (p.motion.channels() == 2) {
            const V a = _mm256_loadu_ps(m), b = _mm256_loadu_ps(m + 8);
            vx = _mm256_castpd_ps(_mm256_permute4x64_pd(
                _mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0))),
                _MM_SHUFFLE(3, 1, 2, 0)));
            vy = _mm256_castpd_ps(_mm256_permute4x64_pd(
                _mm256_castps_pd(_mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1))),
                _MM_SHUFFLE(3, 1, 2, 0)));
        } else {
            vx = _mm256_i32gather_ps(m, mstride, 4);
            vy = _mm256_i32gather_ps(m + 1, mstride, 4);
        }
        vx = _mm256_mul_ps(vx, scale);
        vy = _mm256_mul_ps(vy, scale);
        const V ok = _mm256_and_ps(finite8(vx), finite8(vy));
        vx = _mm256_and_ps(vx, ok);
        vy = _mm256_and_ps(vy, ok);
        V len = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(vx, vx), _mm256_mul_ps(vy, vy)));
        const V lok = finite8(len);
        vx = _mm256_and_ps(vx, lok);
        vy = _mm256_and_ps(vy, lok);
        len = _mm256_and_ps(len, lok);
        const V over = _mm256_cmp_ps(len, max_r, _CMP_GT_OQ);
        const V k = _mm256_blendv_ps(set1(1.0f), _mm256_div_ps(max_r, len), over);
        vx = _mm256_blendv_ps(vx, _mm256_mul_ps(vx, k), over);
        vy = _mm256_blendv_ps(vy, _mm256_mul_ps(vy, k), over);
        len = _mm256_blendv_ps(len, max_r, over);
        V lz = set1(0.0f);  // log 1: no depth
        if (!p.depth.empty()) {
            const int dc = p.depth.channels();
            const V z =
                dc == 1
                    ? _mm256_loadu_ps(p.depth.pixel(x, y))
                    : _mm256_i32gather_ps(
                          p.depth.pixel(x, y), _mm256_mullo_epi32(lane, _mm256_set1_epi32(dc)), 4);
            const V good = _mm256_and_ps(_mm256_cmp_ps(z, zero, _CMP_GT_OQ), finite8(z));
            lz = _mm256_blendv_ps(
                set1(kSkyLogZ), simd::v8::log(_mm256_max_ps(z, set1(1e-30f))), good);
        }
        const V dens = _mm256_and_ps(
            _mm256_div_ps(set1(1.0f), _mm256_mul_ps(_mm256_mul_ps(set1(2.0f), len), len)),
            _mm256_cmp_ps(len, set1(0.5f), _CMP_GE_OQ));
        const std::size_t i0 = std::size_t(y) * std::size_t(p.w) + std::size_t(x);
        const float *c = p.color.pixel(x, y);
        if (p.color.channels() == 4) {
            // Eight RGBA pixels: four loads and a 4x4 transpose per 128-bit half.
            const V a0 = _mm256_loadu_ps(c), a1 = _mm256_loadu_ps(c + 8);
            const V a2 = _mm256_loadu_ps(c + 16), a3 = _mm256_loadu_ps(c + 24);
            const V r0 = _mm256_permute2f128_ps(a0, a2, 0x20),
                    r1 = _mm256_permute2f128_ps(a0, a2, 0x31);
            const V r2 = _mm256_permute2f128_ps(a1, a3, 0x20),
                    r3 = _mm256_permute2f128_ps(a1, a3, 0x31);
            // r0 = pixels (0, 4), r1 = (1, 5), r2 = (2, 6), r3 = (3, 7).
            const V t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpacklo_ps(r2, r3);
            const V t2 = _mm256_unpackhi_ps(r0, r1), t3 = _mm256_unpackhi_ps(r2, r3);
            const V ch[4] = {_mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0)),
                             _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2)),
                             _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0)),
                             _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2))};
            for (int k = 0; k < 4; ++k) {
                _mm256_storeu_ps(p.out.plane(kRed + k) + i0, ch[k]);
            }
            opaque =
                opaque && _mm256_movemask_ps(_mm256_cmp_ps(ch[3], set1(1.0f), _CMP_EQ_OQ)) == 0xff;
        } else {
            for (int k = 0; k < 4; ++k) {
                _mm256_storeu_ps(p.out.plane(kRed + k) + i0,
                                 k < p.nc ? _mm256_i32gather_ps(c + k, cstride, 4) : zero);
            }
            opaque = false;
        }
        _mm256_storeu_ps(p.out.plane(kWx) + i0, _mm256_mul_ps(vx, dens));
        _mm256_storeu_ps(p.out.plane(kWy) + i0, _mm256_mul_ps(vy, dens));
        _mm256_storeu_ps(p.out.plane(kLogZ) + i0, lz);
        _mm256_storeu_ps(p.out.plane(kLen) + i0, len);
        if (acc) {
            const int tx = x / tile;
            fold8(acc[tx],
                  vx,
                  vy,
                  _mm256_add_epi32(_mm256_set1_epi32(r * tile + (x - tx * tile)), lane),
                  all);
        }
        if (!p.out.velocity.empty()) {
            // Interleave the velocity: (vx0, vy0, vx1, vy1, ...).
            const V lo = _mm256_unpacklo_ps(vx, vy), hi = _mm256_unpackhi_ps(vx, vy);
            float *vel = p.out.velocity.pixel(x, y);
            _mm256_storeu_ps(vel, _mm256_permute2f128_ps(lo, hi, 0x20));
            _mm256_storeu_ps(vel + 8, _mm256_permute2f128_ps(lo, hi, 0x31));
        }
    }
    if (x == p.w) {
        return opaque;
    }
    // The tail through the scalar arithmetic.
    alignas(32) float tvx[8] = {}, tvy[8] = {};
    opaque = p.pixels(y, x, p.w, tvx, tvy) && opaque;
    if (acc) {
        const int tx = x / tile;
        const V ok = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(p.w - x), lane));
        fold8(acc[tx],
              _mm256_load_ps(tvx),
              _mm256_load_ps(tvy),
              _mm256_add_epi32(_mm256_set1_epi32(r * tile + (x - tx * tile)), lane),
              ok);
    }
    return opaque;
}

/// The band's tiles from their lanes: the longest vector (the first in scan order among equals)
/// and the box.
POSTHASTE_AVX2 void finish_tiles_avx2(
    const TileAcc8 *acc, int tw, int ty, Image &tiles, Image &bounds)
{
    for (int tx = 0; tx < tw; ++tx) {
        alignas(32) float l[8], vx[8], vy[8], b[4][8];
        alignas(32) std::int32_t i[8];
        _mm256_store_ps(l, acc[tx].l);
        _mm256_store_ps(vx, acc[tx].x);
        _mm256_store_ps(vy, acc[tx].y);
        _mm256_store_si256(reinterpret_cast<VI *>(i), acc[tx].i);
        _mm256_store_ps(b[0], acc[tx].lo_x);
        _mm256_store_ps(b[1], acc[tx].lo_y);
        _mm256_store_ps(b[2], acc[tx].hi_x);
        _mm256_store_ps(b[3], acc[tx].hi_y);
        int best = 0;
        for (int j = 1; j < 8; ++j) {
            if (l[j] > l[best] || (l[j] == l[best] && i[j] < i[best])) {
                best = j;
            }
        }
        tiles.at(tx, ty, 0) = vx[best];
        tiles.at(tx, ty, 1) = vy[best];
        if (!bounds.empty()) {
            float *o = bounds.pixel(tx, ty);
            o[0] = *std::min_element(b[0], b[0] + 8);
            o[1] = *std::min_element(b[1], b[1] + 8);
            o[2] = *std::max_element(b[2], b[2] + 8);
            o[3] = *std::max_element(b[3], b[3] + 8);
        }
    }
}

/// pack_row_avx2 for the rows of tile band ty, folding each row into the band's tile max and
/// bounds while it is in cache (instead of a second pass over the velocities).
POSTHASTE_AVX2 void pack_band_avx2(const Packer &p, int ty, int tile, Packed &out)
{
    const int tw = out.tiles.width();
    // 32-byte aligned accumulators (std::vector's storage was found 16-byte aligned here).
    std::vector<unsigned char> storage(std::size_t(tw) * sizeof(TileAcc8) + 32);
    TileAcc8 *const acc = reinterpret_cast<TileAcc8 *>(
        (reinterpret_cast<std::uintptr_t>(storage.data()) + 31) & ~std::uintptr_t(31));
    const V inf = set1(kInf);
    for (int tx = 0; tx < tw; ++tx) {
        TileAcc8 &a = *new (acc + tx) TileAcc8;
        a.l = a.x = a.y = _mm256_setzero_ps();
        a.i = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::max());
        a.lo_x = a.lo_y = inf;
        a.hi_x = a.hi_y = _mm256_sub_ps(_mm256_setzero_ps(), inf);
    }
    const int y0 = ty * tile, y1 = std::min(p.motion.height(), y0 + tile);
    for (int y = y0; y < y1; ++y) {
        out.opaque_rows[std::size_t(y)] = pack_row_avx2(p, y, acc, y - y0, tile);
    }
    finish_tiles_avx2(acc, tw, ty, out.tiles, out.bounds);
}
#endif

/// The records of a frame; with `bounds`, also the tile bounds (else only the tile max).
Packed pack(const Image &color,
            const Image &motion,
            const Image &depth,
            const MotionBlurOptions &o,
            bool vector,
            bool bounds)
{
    const int w = motion.width(), h = motion.height();
    const std::size_t n = std::size_t(w) * std::size_t(h);
    const std::size_t stride = (n + 15) / 16 * 16;
    // The AVX2 pack folds the tile reductions itself where groups of 8 tile the tiles.
    const bool fold = vector && o.tile % 8 == 0 && POSTHASTE_HAVE_AVX2_TARGET;
    Packed out{scratch<float>(stride * kFields),
               stride,
               fold ? Image() : Image::uninitialized(w, h, 2),
               std::vector<unsigned char>(std::size_t(h), 0),
               Image(),
               Image()};
    const Packer p{color,
                   motion,
                   depth,
                   out,
                   w,
                   std::min(color.channels(), 4),
                   0.5f * o.shutter,
                   std::max(o.max_radius, 0.0f)};
#if POSTHASTE_HAVE_AVX2_TARGET
    if (vector && o.tile % 8 == 0) {
        const int tw = (w + o.tile - 1) / o.tile, th = (h + o.tile - 1) / o.tile;
        out.tiles = Image(tw, th, 2);
        if (bounds) {
            out.bounds = Image(tw, th, 4);
        }
        parallel_for(0, th, [&](int ty) { pack_band_avx2(p, ty, o.tile, out); });
        return out;
    }
    if (vector) {
        parallel_for(0, h, [&](int y) { out.opaque_rows[std::size_t(y)] = pack_row_avx2(p, y); });
        return out;
    }
#endif
    parallel_for(0, h, [&](int y) { out.opaque_rows[std::size_t(y)] = p.pixels(y, 0, w); });
    return out;
}

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

/// The gather, shared by the scalar and AVX2 paths. Pixels are processed in groups of eight
/// adjacent pixels of a row (fewer at a tile's right edge), and a group makes one jittered
/// neighbour-max lookup. Where the sampling vectors of a group's pixels all lie within
/// `group_tolerance` px of the middle of their bounding box (95 % of the reconstructed groups of
/// the default scene's fast translation, all of the fast turn's), the group samples along that
/// middle vector with one jitter: the sample positions of its pixels are then the same run of
/// adjacent pixels in one row, shifted, and the AVX2 path reads each field of a sample with one
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

    void copy_pixel(Image &out, int x, int y) const
    {
        std::memcpy(out.pixel(x, y), color.pixel(x, y), sizeof(float) * std::size_t(nc));
    }

    static int sample_count(float len, int most)
    {
        return std::max(1, std::min(most, std::max(2, int(std::ceil(2.0f * len)))));
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
};

#if POSTHASTE_HAVE_AVX2_TARGET
/// pcg_hash on eight lanes.
POSTHASTE_AVX2_INLINE VI pcg8(VI v)
{
    const VI state = _mm256_add_epi32(_mm256_mullo_epi32(v, _mm256_set1_epi32(747796405)),
                                      _mm256_set1_epi32(int(2891336453u)));
    const VI shift = _mm256_add_epi32(_mm256_srli_epi32(state, 28), _mm256_set1_epi32(4));
    const VI word = _mm256_mullo_epi32(_mm256_xor_si256(_mm256_srlv_epi32(state, shift), state),
                                       _mm256_set1_epi32(277803737));
    return _mm256_xor_si256(_mm256_srli_epi32(word, 22), word);
}
/// hash_to_unit on eight lanes.
POSTHASTE_AVX2_INLINE V unit8(VI h)
{
    return _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(h, 8)), set1(1.0f / 16777216.0f));
}
/// Gather::sample_count on eight lanes, as floats.
POSTHASTE_AVX2_INLINE V count8(V len, V most)
{
    const V n =
        _mm256_min_ps(most, _mm256_max_ps(set1(2.0f), _mm256_ceil_ps(_mm256_add_ps(len, len))));
    return _mm256_max_ps(set1(1.0f), n);
}
/// Largest lane, as an int (lanes hold small whole numbers).
POSTHASTE_AVX2_INLINE int max_lane(V x)
{
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_movehdup_ps(m));
    return int(_mm_cvtss_f32(m));
}
/// Smallest lane.
POSTHASTE_AVX2_INLINE float min_lane(V x)
{
    __m128 m = _mm_min_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_min_ps(m, _mm_movehl_ps(m, m));
    m = _mm_min_ss(m, _mm_movehdup_ps(m));
    return _mm_cvtss_f32(m);
}
/// Largest lane.
POSTHASTE_AVX2_INLINE float max_lane_f(V x)
{
    __m128 m = _mm_max_ps(_mm256_castps256_ps128(x), _mm256_extractf128_ps(x, 1));
    m = _mm_max_ps(m, _mm_movehl_ps(m, m));
    m = _mm_max_ss(m, _mm_movehdup_ps(m));
    return _mm_cvtss_f32(m);
}
/// The bounding box of the (vx, vy) lanes in `mask`.
POSTHASTE_AVX2_INLINE Box bounds8(V vx, V vy, V mask)
{
    const V inf = set1(kInf), ninf = set1(-kInf);
    Box b;
    b.lo_x = min_lane(_mm256_blendv_ps(inf, vx, mask));
    b.hi_x = max_lane_f(_mm256_blendv_ps(ninf, vx, mask));
    b.lo_y = min_lane(_mm256_blendv_ps(inf, vy, mask));
    b.hi_y = max_lane_f(_mm256_blendv_ps(ninf, vy, mask));
    return b;
}

/// The pixel index of lane x + 0.5 + t v, clamped to the frame (Gather::at).
struct Frame8 {
    V xf, yf, xmax, ymax;
    VI w;
};
/// Frame8 of row y (xf: set per group with lanes8_at).
POSTHASTE_AVX2_INLINE Frame8 frame8(const Gather &g, int y)
{
    return Frame8{set1(0.0f),
                  set1(float(y) + 0.5f),
                  set1(float(g.w) - 0.5f),
                  set1(float(g.h) - 0.5f),
                  _mm256_set1_epi32(g.w)};
}
/// `f` at the pixel centres of columns xi.
POSTHASTE_AVX2_INLINE Frame8 lanes8_at(Frame8 f, VI xi)
{
    f.xf = _mm256_add_ps(_mm256_cvtepi32_ps(xi), set1(0.5f));
    return f;
}
/// The row's part of the per-pixel hash hash4(x, y, 0, seed) = pcg_hash(x ^ key).
POSTHASTE_AVX2_INLINE VI row_key8(const Gather &g, int y)
{
    return _mm256_set1_epi32(int(pcg_hash(std::uint32_t(y) ^ pcg_hash(0u ^ pcg_hash(g.o.seed)))));
}
POSTHASTE_AVX2_INLINE VI offset8(const Frame8 &f, V t, V vx, V vy)
{
    const V zero = _mm256_setzero_ps();
    const V fx =
        _mm256_min_ps(_mm256_max_ps(_mm256_add_ps(f.xf, _mm256_mul_ps(t, vx)), zero), f.xmax);
    const V fy =
        _mm256_min_ps(_mm256_max_ps(_mm256_add_ps(f.yf, _mm256_mul_ps(t, vy)), zero), f.ymax);
    return _mm256_add_epi32(_mm256_mullo_epi32(_mm256_cvttps_epi32(fy), f.w),
                            _mm256_cvttps_epi32(fx));
}

/// A shared sample of a group (Gather::run_origin): where the run of eight pixels lies inside
/// its row, each field is one load; at the left and right edges, a gather of the clamped
/// columns.
struct RunAt {
    bool inside;
    std::size_t base;
    VI idx;
};
POSTHASTE_AVX2_INLINE RunAt run_at8(const Gather &g, int x0, int y, float t, float vx, float vy)
{
    int bx, by;
    g.run_origin(x0, y, t, vx, vy, bx, by);
    RunAt a{bx >= 0 && bx + 8 <= g.w, g.index(0, by) + std::size_t(std::max(bx, 0)), VI{}};
    if (!a.inside) {
        const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        const VI col = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(bx), lane), _mm256_setzero_si256()),
            _mm256_set1_epi32(g.w - 1));
        a.idx = _mm256_add_epi32(_mm256_set1_epi32(by * g.w), col);
    }
    return a;
}
POSTHASTE_AVX2_INLINE V field8(const Gather &g, int field, const RunAt &a)
{
    return a.inside ? _mm256_loadu_ps(g.f[field] + a.base)
                    : _mm256_i32gather_ps(g.f[field], a.idx, 4);
}
POSTHASTE_AVX2_INLINE V gather8(const Gather &g, int field, VI idx)
{
    return _mm256_i32gather_ps(g.f[field], idx, 4);
}

/// The most samples of a run whose origins a plan tabulates (longer runs compute them as
/// they go).
constexpr int kTabulated = 32;

/// Gather::run_origin for samples t_i = -1 + (i + u) step, i < n <= kTabulated, eight at a
/// time: first columns (unclamped) and row offsets (clamped row x width). Tabulated in the
/// plan, a sample's loads no longer wait on its chain of float-to-int conversions.
POSTHASTE_AVX2_INLINE void origins8(const Gather &g,
                                    int x0,
                                    int y,
                                    float u,
                                    float step,
                                    float vx,
                                    float vy,
                                    int n,
                                    std::int32_t *bx,
                                    std::int32_t *row)
{
    const V lanef = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const V ox = set1(float(x0) + 0.5f), oy = set1(float(y) + 0.5f);
    for (int i = 0; i < n; i += 8) {
        const V t = _mm256_fmadd_ps(
            _mm256_add_ps(_mm256_add_ps(set1(float(i)), lanef), set1(u)), set1(step), set1(-1.0f));
        const VI cx = _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_fmadd_ps(t, set1(vx), ox)));
        VI cy = _mm256_cvttps_epi32(_mm256_floor_ps(_mm256_fmadd_ps(t, set1(vy), oy)));
        cy = _mm256_min_epi32(_mm256_max_epi32(cy, _mm256_setzero_si256()),
                              _mm256_set1_epi32(g.h - 1));
        _mm256_storeu_si256(reinterpret_cast<VI *>(bx + i), cx);
        _mm256_storeu_si256(reinterpret_cast<VI *>(row + i),
                            _mm256_mullo_epi32(cy, _mm256_set1_epi32(g.w)));
    }
}
/// RunAt of a tabulated origin.
POSTHASTE_AVX2_INLINE RunAt run_at8(const Gather &g, std::int32_t bx, std::int32_t row)
{
    RunAt a{bx >= 0 && bx + 8 <= g.w, std::size_t(row) + std::size_t(std::max(bx, 0)), VI{}};
    if (!a.inside) {
        const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        const VI col = _mm256_min_epi32(
            _mm256_max_epi32(_mm256_add_epi32(_mm256_set1_epi32(bx), lane), _mm256_setzero_si256()),
            _mm256_set1_epi32(g.w - 1));
        a.idx = _mm256_add_epi32(_mm256_set1_epi32(row), col);
    }
    return a;
}

/// Gather::own for pixels x .. x + 7 of row y (lanes past the row's end read its last pixel):
/// three loads where the eight lie inside the row.
POSTHASTE_AVX2_INLINE void own8(const Gather &g, int x, int y, VI xc, V &vx, V &vy, V &len)
{
    V wx, wy;
    if (x + 8 <= g.w) {
        const std::size_t i0 = g.index(x, y);
        wx = _mm256_loadu_ps(g.f[kWx] + i0);
        wy = _mm256_loadu_ps(g.f[kWy] + i0);
        len = _mm256_loadu_ps(g.f[kLen] + i0);
    } else {
        const VI ci = _mm256_add_epi32(_mm256_set1_epi32(int(g.index(0, y))), xc);
        wx = _mm256_i32gather_ps(g.f[kWx], ci, 4);
        wy = _mm256_i32gather_ps(g.f[kWy], ci, 4);
        len = _mm256_i32gather_ps(g.f[kLen], ci, 4);
    }
    const V k = _mm256_mul_ps(_mm256_mul_ps(set1(2.0f), len), len);
    vx = _mm256_mul_ps(wx, k);
    vy = _mm256_mul_ps(wy, k);
}

/// Writes the first `lanes` results (SoA, r[channel][lane]) of row y from x, lanes not in
/// `keep` copied from the input.
POSTHASTE_AVX2_INLINE void store8(
    const Gather &g, Image &out, int x, int y, int lanes, const V *r, V keep)
{
    const int mask = _mm256_movemask_ps(keep);
    if (mask == 0xff && lanes == 8 && g.nc == 4 && out.channels() == 4) {
        // RGBA: transpose the four channel vectors into eight pixels, four 32-byte stores.
        const V t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
        const V t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
        const V p0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0));  // pixels 0, 4
        const V p1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));  // 1, 5
        const V p2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0));  // 2, 6
        const V p3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));  // 3, 7
        float *po = out.pixel(x, y);
        _mm256_storeu_ps(po, _mm256_permute2f128_ps(p0, p1, 0x20));
        _mm256_storeu_ps(po + 8, _mm256_permute2f128_ps(p2, p3, 0x20));
        _mm256_storeu_ps(po + 16, _mm256_permute2f128_ps(p0, p1, 0x31));
        _mm256_storeu_ps(po + 24, _mm256_permute2f128_ps(p2, p3, 0x31));
        return;
    }
    alignas(32) float v[4][8];
    for (int k = 0; k < 4; ++k) {
        _mm256_store_ps(v[k], r[k]);
    }
    for (int j = 0; j < lanes; ++j) {
        float *po = out.pixel(x + j, y);
        if (mask & (1 << j)) {
            for (int k = 0; k < g.nc; ++k) {
                po[k] = v[k][j];
            }
        } else {
            g.copy_pixel(out, x + j, y);
        }
    }
}

/// The eight lanes of a group: Gather::Lane, and the pixels' own records.
struct Lanes8 {
    VI xi;  ///< pixel columns
    V valid, cvx, cvy, clen, inv_own, own, shared, vx, vy, len, dx, dy, clz, cc[4];
};

/// Gather::finish on eight lanes; stores the first `lanes`.
POSTHASTE_AVX2_INLINE void finish8(const Gather &g,
                                   Image &out,
                                   int x,
                                   int y,
                                   int lanes,
                                   const Lanes8 &p,
                                   V F,
                                   V B,
                                   const V *fg,
                                   const V *bg,
                                   V own_weight)
{
    const V one = set1(1.0f);
    const V full = _mm256_cmp_ps(F, one, _CMP_GE_OQ);
    const V wc = _mm256_blendv_ps(one, _mm256_mul_ps(set1(1e-3f), own_weight), p.own);
    B = _mm256_add_ps(B, wc);
    const V rest = _mm256_div_ps(_mm256_sub_ps(one, F), B);
    const V inv_f = _mm256_div_ps(one, F);
    V r[4];
    for (int k = 0; k < 4; ++k) {
        const V blend = _mm256_add_ps(
            fg[k], _mm256_mul_ps(rest, _mm256_add_ps(bg[k], _mm256_mul_ps(wc, p.cc[k]))));
        r[k] = _mm256_blendv_ps(blend, _mm256_mul_ps(fg[k], inv_f), full);
    }
    if (g.opaque) {
        r[3] = one;
    }
    store8(g, out, x, y, lanes, r, _mm256_castsi256_ps(_mm256_set1_epi32(-1)));
}

/// Gather::second_lane on the lanes in `second` (n: the front estimate's sample counts);
/// returns the weight of one sample.
POSTHASTE_AVX2_INLINE V
second_lanes8(const Gather &g, const Frame8 &f, const Lanes8 &p, V second, V n, VI hu, V &B, V *bg)
{
    const V one = set1(1.0f), half = set1(0.5f), zero = _mm256_setzero_ps();
    const V inv_soft = set1(g.inv_soft);
    const V half_n = _mm256_floor_ps(_mm256_mul_ps(_mm256_add_ps(n, one), half));
    const V m = _mm256_and_ps(
        _mm256_max_ps(set1(2.0f), _mm256_min_ps(count8(p.clen, set1(float(g.o.samples))), half_n)),
        second);
    const V mstep = _mm256_div_ps(set1(2.0f), _mm256_max_ps(m, one));
    const V wm = _mm256_mul_ps(_mm256_mul_ps(p.clen, mstep), p.inv_own);
    const V u2 = unit8(pcg8(hu));
    const int m_max = max_lane(m);
    for (int i = 0; i < m_max; ++i) {
        const V fi = set1(float(i));
        const V active = _mm256_cmp_ps(fi, m, _CMP_LT_OQ);
        const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u2), mstep));
        const VI idx = offset8(f, t, p.cvx, p.cvy);
        const V fr = simd::v8::clamp(
            _mm256_add_ps(half,
                          _mm256_mul_ps(_mm256_sub_ps(p.clz, gather8(g, kLogZ, idx)), inv_soft)),
            zero,
            one);
        const V wb = _mm256_and_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr), wm), active);
        B = _mm256_add_ps(B, wb);
        for (int k = 0; k < 4; ++k) {
            bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, gather8(g, kRed + k, idx)));
        }
    }
    return wm;
}

/// Gather::reconstruct_lane on eight lanes: each follows its own plan and jitter (lanes past
/// their sample count add nothing).
POSTHASTE_AVX2_INLINE void lanes8(
    const Gather &g, Image &out, int x, int y, int lanes, const Lanes8 &p, const Frame8 &fr, VI ky0)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft);
    const Frame8 f = lanes8_at(fr, p.xi);
    const V n = count8(p.len, set1(float(g.o.samples)));
    const V step = _mm256_div_ps(set1(2.0f), n);
    const V delta = _mm256_mul_ps(p.len, step);
    const V own_w = _mm256_and_ps(_mm256_mul_ps(delta, p.inv_own), p.shared);
    const VI hu = pcg8(_mm256_xor_si256(p.xi, ky0));
    const V u = unit8(hu);
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const int n_max = max_lane(n);
    for (int i = 0; i < n_max; ++i) {
        const V fi = set1(float(i));
        const V active = _mm256_cmp_ps(fi, n, _CMP_LT_OQ);
        const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u), step));
        const VI idx = offset8(f, t, p.vx, p.vy);
        const V T = _mm256_mul_ps(abs8(t), p.len);
        const V fr_w = simd::v8::clamp(
            _mm256_add_ps(half,
                          _mm256_mul_ps(_mm256_sub_ps(p.clz, gather8(g, kLogZ, idx)), inv_soft)),
            zero,
            one);
        const V reach_s = simd::v8::clamp(
            _mm256_sub_ps(_mm256_add_ps(gather8(g, kLen, idx), half), T), zero, one);
        const V reach_c = simd::v8::clamp(_mm256_sub_ps(_mm256_add_ps(p.clen, half), T), zero, one);
        const V along = abs8(_mm256_add_ps(_mm256_mul_ps(gather8(g, kWx, idx), p.dx),
                                           _mm256_mul_ps(gather8(g, kWy, idx), p.dy)));
        const V wf = _mm256_and_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(fr_w, reach_s), along), delta), active);
        const V wb = _mm256_and_ps(
            _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr_w), reach_c), own_w), active);
        F = _mm256_add_ps(F, wf);
        B = _mm256_add_ps(B, wb);
        for (int k = 0; k < 4; ++k) {
            const V c = gather8(g, kRed + k, idx);
            fg[k] = _mm256_add_ps(fg[k], _mm256_mul_ps(wf, c));
            bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, c));
        }
    }
    V own_weight = own_w;
    const V second = _mm256_andnot_ps(p.shared, p.own);
    if (_mm256_movemask_ps(second) != 0) {
        own_weight =
            _mm256_blendv_ps(own_weight, second_lanes8(g, f, p, second, n, hu, B, bg), second);
    }
    finish8(g, out, x, y, lanes, p, F, B, fg, bg, own_weight);
}

/// The front estimate along a shared run (Gather::reconstruct_run's first loop; kBack: also
/// the own-surface sums, needed only where some lane's own path is the shared one). The sums
/// leave out the path length per sample, delta, which the caller multiplies in.
template <bool kBack, int kNc>
POSTHASTE_AVX2_INLINE void front_run8(const Gather &g,
                                      int x,
                                      int y,
                                      const Run &r,
                                      float u,
                                      const std::int32_t *bx,
                                      const std::int32_t *row,
                                      const Lanes8 &p,
                                      V &F,
                                      V &B,
                                      V *fg,
                                      V *bg)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft), dx = set1(r.dx), dy = set1(r.dy);
    const float step = 2.0f / float(r.n);
    for (int i = 0; i < r.n; ++i) {
        const float t = -1.0f + (float(i) + u) * step;
        const V rT = set1(0.5f - std::abs(t) * r.len);
        const RunAt a = bx ? run_at8(g, bx[i], row[i]) : run_at8(g, x, y, t, r.vx, r.vy);
        const V fr = simd::v8::clamp(
            _mm256_fmadd_ps(_mm256_sub_ps(p.clz, field8(g, kLogZ, a)), inv_soft, half), zero, one);
        const V reach_s = simd::v8::clamp(_mm256_add_ps(field8(g, kLen, a), rT), zero, one);
        const V along =
            abs8(_mm256_fmadd_ps(field8(g, kWx, a), dx, _mm256_mul_ps(field8(g, kWy, a), dy)));
        const V wf = _mm256_mul_ps(_mm256_mul_ps(fr, reach_s), along);
        F = _mm256_add_ps(F, wf);
        V c[4];
        for (int k = 0; k < kNc; ++k) {
            c[k] = field8(g, kRed + k, a);
            fg[k] = _mm256_fmadd_ps(wf, c[k], fg[k]);
        }
        if constexpr (kBack) {
            const V reach_c = simd::v8::clamp(_mm256_add_ps(p.clen, rT), zero, one);
            const V wb = _mm256_fnmadd_ps(fr, reach_c, reach_c);  // (1 - fr) reach_c
            B = _mm256_add_ps(B, wb);
            for (int k = 0; k < kNc; ++k) {
                bg[k] = _mm256_fmadd_ps(wb, c[k], bg[k]);
            }
        }
    }
}

/// A group's plan: everything Gather::reconstruct decides before its sample loops. The row
/// plans the next group before it samples this one, so that the plan's chain of latencies
/// (hashes, lookup, square roots, divisions, reductions) overlaps the previous group's loops.
struct Plan8 {
    int x, lanes;
    bool live;
    Lanes8 p;
    Run r;        ///< the shared run (r.ok false: each lane samples on its own)
    Run c;        ///< the second direction's shared run, for the lanes whose path is not shared
    bool second;  ///< some lane needs the second direction
    float u, u2;
    /// Sample origins of the shared runs (front: r.n of them, second: m), when tabulated.
    alignas(32) std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    alignas(32) std::int32_t bx2[kTabulated + 8], row2[kTabulated + 8];
    int m;
};

POSTHASTE_AVX2_INLINE void plan8(const Gather &g, int x, int y, int x1, Plan8 &pl)
{
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const V half = set1(0.5f);
    const VI last = _mm256_set1_epi32(g.w - 1);
    pl.x = x;
    pl.lanes = std::min(8, x1 - x);
    const Lookup l = g.lookup(x, y);
    pl.live = l.len >= 0.5f;
    if (!pl.live) {
        return;
    }
    Lanes8 &p = pl.p;
    p.xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
    // Lanes past the row's end (narrow tiles) compute on the last pixel, unstored.
    const VI xc = _mm256_min_epi32(p.xi, last);
    p.valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(pl.lanes), lane));
    const std::size_t i0 = g.index(x, y);
    if (x + 8 <= g.w) {
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = _mm256_loadu_ps(g.f[kRed + k] + i0);
        }
        p.clz = _mm256_loadu_ps(g.f[kLogZ] + i0);
    } else {
        const VI ci = _mm256_add_epi32(_mm256_set1_epi32(int(g.index(0, y))), xc);
        for (int k = 0; k < 4; ++k) {
            p.cc[k] = gather8(g, kRed + k, ci);
        }
        p.clz = gather8(g, kLogZ, ci);
    }
    own8(g, x, y, xc, p.cvx, p.cvy, p.clen);
    p.own = _mm256_cmp_ps(p.clen, half, _CMP_GE_OQ);
    // One division for the direction and the own weight.
    const V inv_len = _mm256_and_ps(_mm256_div_ps(set1(1.0f), p.clen), p.own);
    const V dcx = _mm256_mul_ps(p.cvx, inv_len), dcy = _mm256_mul_ps(p.cvy, inv_len);
    const V ldx = set1(l.dx), ldy = set1(l.dy), llen = set1(l.len);
    const V cosine = abs8(_mm256_add_ps(_mm256_mul_ps(dcx, ldx), _mm256_mul_ps(dcy, ldy)));
    p.shared = _mm256_and_ps(_mm256_and_ps(p.own, _mm256_cmp_ps(cosine, set1(0.9f), _CMP_GT_OQ)),
                             _mm256_cmp_ps(p.clen, _mm256_mul_ps(half, llen), _CMP_GE_OQ));
    p.inv_own = _mm256_mul_ps(half, inv_len);
    p.dx = _mm256_blendv_ps(ldx, dcx, p.shared);
    p.dy = _mm256_blendv_ps(ldy, dcy, p.shared);
    p.vx = _mm256_blendv_ps(set1(l.vx), _mm256_mul_ps(dcx, llen), p.shared);
    p.vy = _mm256_blendv_ps(set1(l.vy), _mm256_mul_ps(dcy, llen), p.shared);
    const V longer =
        _mm256_and_ps(p.shared, _mm256_cmp_ps(p.clen, _mm256_mul_ps(set1(0.8f), llen), _CMP_GT_OQ));
    p.vx = _mm256_blendv_ps(p.vx, p.cvx, longer);
    p.vy = _mm256_blendv_ps(p.vy, p.cvy, longer);
    p.len = _mm256_blendv_ps(llen, p.clen, longer);
    g.run(bounds8(p.vx, p.vy, p.valid), pl.r);
    pl.c.ok = 0;
    pl.second = false;
    if (pl.r.ok) {
        const std::uint32_t hu = hash4(std::uint32_t(x), std::uint32_t(y), 0u, g.o.seed);
        pl.u = hash_to_unit(hu);
        pl.u2 = hash_to_unit(pcg_hash(hu));
        const V second_valid = _mm256_and_ps(_mm256_andnot_ps(p.shared, p.own), p.valid);
        pl.second = _mm256_movemask_ps(second_valid) != 0;
        if (pl.second) {
            g.run(bounds8(p.cvx, p.cvy, second_valid), pl.c);
        }
        if (pl.r.n <= kTabulated) {
            origins8(g, x, y, pl.u, 2.0f / float(pl.r.n), pl.r.vx, pl.r.vy, pl.r.n, pl.bx, pl.row);
        }
        if (pl.c.ok) {
            pl.m = std::max(2, std::min(pl.c.n, (pl.r.n + 1) / 2));
            if (pl.m <= kTabulated) {
                origins8(
                    g, x, y, pl.u2, 2.0f / float(pl.m), pl.c.vx, pl.c.vy, pl.m, pl.bx2, pl.row2);
            }
        }
    }
}

/// Gather::reconstruct_run on eight lanes (kNc: colour channels summed; 3 for opaque RGBA).
template <int kNc>
POSTHASTE_AVX2_INLINE void run8(
    const Gather &g, Image &out, int y, const Plan8 &pl, const Frame8 &fr)
{
    const V zero = _mm256_setzero_ps(), one = set1(1.0f), half = set1(0.5f);
    const V inv_soft = set1(g.inv_soft);
    const Lanes8 &p = pl.p;
    const Run &r = pl.r;
    const int x = pl.x;
    const float delta = r.len * (2.0f / float(r.n));
    V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
    V F = zero, B = zero;
    const std::int32_t *bx = r.n <= kTabulated ? pl.bx : nullptr;
    if (_mm256_movemask_ps(_mm256_and_ps(p.shared, p.valid)) != 0) {
        front_run8<true, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    } else {
        front_run8<false, kNc>(g, x, y, r, pl.u, bx, pl.row, p, F, B, fg, bg);
    }
    const V vdelta = set1(delta);
    V own_weight = _mm256_and_ps(_mm256_mul_ps(vdelta, p.inv_own), p.shared);
    F = _mm256_mul_ps(F, vdelta);
    B = _mm256_mul_ps(B, own_weight);
    for (int k = 0; k < 4; ++k) {
        fg[k] = _mm256_mul_ps(fg[k], vdelta);
        bg[k] = _mm256_mul_ps(bg[k], own_weight);
    }
    if (pl.second) {
        const V second = _mm256_andnot_ps(p.shared, p.own);
        const Run &c = pl.c;
        if (c.ok) {
            const int m = pl.m;
            const float mstep = 2.0f / float(m);
            const V wm = _mm256_and_ps(set1(1.0f / float(m)), second);
            for (int i = 0; i < m; ++i) {
                const RunAt a =
                    m <= kTabulated
                        ? run_at8(g, pl.bx2[i], pl.row2[i])
                        : run_at8(g, x, y, -1.0f + (float(i) + pl.u2) * mstep, c.vx, c.vy);
                const V f = simd::v8::clamp(
                    _mm256_fmadd_ps(_mm256_sub_ps(p.clz, field8(g, kLogZ, a)), inv_soft, half),
                    zero,
                    one);
                const V wb = _mm256_fnmadd_ps(f, wm, wm);  // (1 - f) wm
                B = _mm256_add_ps(B, wb);
                for (int k = 0; k < kNc; ++k) {
                    bg[k] = _mm256_fmadd_ps(wb, field8(g, kRed + k, a), bg[k]);
                }
            }
            own_weight = _mm256_blendv_ps(own_weight, wm, second);
        } else {
            const VI hv = pcg8(_mm256_xor_si256(p.xi, row_key8(g, y)));
            own_weight = _mm256_blendv_ps(
                own_weight,
                second_lanes8(g, lanes8_at(fr, p.xi), p, second, set1(float(r.n)), hv, B, bg),
                second);
        }
    }
    finish8(g, out, x, y, pl.lanes, p, F, B, fg, bg, own_weight);
}

/// Gather::reconstruct for the groups of pixels [x0, x1) of row y; returns how many shared a
/// run.
POSTHASTE_AVX2 int reconstruct_row_avx2(const Gather &g, Image &out, int y, int x0, int x1)
{
    int shared = 0;
    const Frame8 fr = frame8(g, y);
    const VI ky0 = row_key8(g, y);
    Plan8 plans[2];
    int cur = 0;
    plan8(g, x0, y, x1, plans[0]);
    for (int x = x0; x < x1; x += 8) {
        if (x + 8 < x1) {
            plan8(g, x + 8, y, x1, plans[cur ^ 1]);
        }
        const Plan8 &pl = plans[cur];
        cur ^= 1;
        if (!pl.live) {
            for (int j = 0; j < pl.lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
        } else if (pl.r.ok) {
            ++shared;
            if (g.opaque) {
                run8<3>(g, out, y, pl, fr);
            } else {
                run8<4>(g, out, y, pl, fr);
            }
        } else {
            lanes8(g, out, x, y, pl.lanes, pl.p, fr, ky0);
        }
    }
    return shared;
}

/// The mean colour of eight pixels along a shared run (Gather::uniform's run; kNc channels
/// summed, 3 for opaque RGBA, whose mean alpha of n ones is exactly 1). A template, so the
/// sums stay in registers (a run-time channel count kept them on the stack, each sample
/// waiting on a store-to-load forward).
template <int kNc>
POSTHASTE_AVX2_INLINE void uniform_run8(const Gather &g, int x, int y, const Run &r, V *acc)
{
    const float step = 2.0f / float(r.n);
    const float u = hash_unit(x, y, 0, g.o.seed);
    for (int k = 0; k < 4; ++k) {
        acc[k] = _mm256_setzero_ps();
    }
    alignas(32) std::int32_t bx[kTabulated + 8], row[kTabulated + 8];
    const bool tab = r.n <= kTabulated;
    if (tab) {
        origins8(g, x, y, u, step, r.vx, r.vy, r.n, bx, row);
    }
    for (int i = 0; i < r.n; ++i) {
        const RunAt a = tab ? run_at8(g, bx[i], row[i])
                            : run_at8(g, x, y, -1.0f + (float(i) + u) * step, r.vx, r.vy);
        for (int k = 0; k < kNc; ++k) {
            acc[k] = _mm256_add_ps(acc[k], field8(g, kRed + k, a));
        }
    }
    const V vn = set1(float(r.n));
    for (int k = 0; k < 4; ++k) {
        acc[k] = k < kNc ? _mm256_div_ps(acc[k], vn) : set1(1.0f);
    }
}

/// Gather::uniform for the groups of pixels [x0, x1) of row y; returns how many shared a run.
POSTHASTE_AVX2 int uniform_row_avx2(const Gather &g, Image &out, int y, int x0, int x1, bool runs)
{
    int shared = 0;
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const Frame8 fr = frame8(g, y);
    const VI ky = row_key8(g, y);
    const V most = set1(float(g.o.samples));
    const VI last = _mm256_set1_epi32(g.w - 1);
    const V all = _mm256_castsi256_ps(_mm256_set1_epi32(-1));
    for (int x = x0; x < x1; x += 8) {
        const int lanes = std::min(8, x1 - x);
        const VI xc =
            _mm256_sub_epi32(_mm256_min_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane), last),
                             _mm256_set1_epi32(x));
        V vx, vy, len;
        own8(g, x, y, _mm256_add_epi32(xc, _mm256_set1_epi32(x)), vx, vy, len);
        const V moving = _mm256_cmp_ps(len, set1(0.5f), _CMP_GE_OQ);
        const int live = _mm256_movemask_ps(moving), wanted = (1 << lanes) - 1;
        if (live == 0) {
            for (int j = 0; j < lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
            continue;
        }
        if (runs && (live & wanted) == wanted) {
            const V valid = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(lanes), lane));
            const Run r = g.run(bounds8(vx, vy, valid));
            if (r.ok) {
                V acc[4];
                if (g.opaque) {
                    uniform_run8<3>(g, x, y, r, acc);
                } else {
                    uniform_run8<4>(g, x, y, r, acc);
                }
                store8(g, out, x, y, lanes, acc, all);
                ++shared;
                continue;
            }
        }
        const VI xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
        const Frame8 f = lanes8_at(fr, xi);
        const V n = _mm256_and_ps(count8(len, most), moving);
        const int n_max = max_lane(n);
        const V step = _mm256_div_ps(set1(2.0f), _mm256_max_ps(n, set1(1.0f)));
        const V u = unit8(pcg8(_mm256_xor_si256(xi, ky)));
        V acc[4] = {
            _mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps(), _mm256_setzero_ps()};
        for (int i = 0; i < n_max; ++i) {
            const V fi = set1(float(i));
            const V active = _mm256_cmp_ps(fi, n, _CMP_LT_OQ);
            const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u), step));
            const VI idx = offset8(f, t, vx, vy);
            for (int k = 0; k < 4; ++k) {
                acc[k] = _mm256_add_ps(acc[k], _mm256_and_ps(gather8(g, kRed + k, idx), active));
            }
        }
        for (int k = 0; k < 4; ++k) {
            acc[k] = _mm256_div_ps(acc[k], n);
        }
        store8(g, out, x, y, lanes, acc, moving);
    }
    return shared;
}
#endif

}  // namespace

namespace {

/// Whether the AVX2 path runs: the CPU has it, and the frame is small enough for its 32-bit
/// gather offsets.
bool vector_path(const Image &color)
{
    return simd::avx2() &&
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
    // Per tile: 1 copied, 2 coherent (uniform path), 0 reconstructed.
    std::vector<unsigned char> kind(std::size_t(nt_x) * std::size_t(nt_y), 0);
    // Per band: the 8-pixel groups gathered, and how many of them shared a run.
    std::vector<long> groups(std::size_t(nt_y), 0), shared_groups(std::size_t(nt_y), 0);
    const auto classify = [&](int tx, int ty) -> unsigned char {
        // Copy a tile outright when no lookup its jitter can reach sees half a pixel of motion
        // (the Uniform method reads the tile max, its own pixels' longest).
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
                    std::memcpy(out.pixel(x0, y),
                                color.pixel(x0, y),
                                sizeof(float) * std::size_t((x1 - x0) * color.channels()));
                    continue;
                }
                const bool coherent = band[tx] == 2;
                const bool uniform = o.method == BlurMethod::Uniform || coherent;
                // Groups of 8 from each tile's left edge.
                for (int t = tx; t < tx + tn; ++t) {
                    groups[std::size_t(ty)] += (std::min(w, (t + 1) * o.tile) - t * o.tile + 7) / 8;
                }
#if POSTHASTE_HAVE_AVX2_TARGET
                if (vector) {
                    shared_groups[std::size_t(ty)] +=
                        uniform ? uniform_row_avx2(g, out, y, x0, x1, coherent)
                                : reconstruct_row_avx2(g, out, y, x0, x1);
                    continue;
                }
#endif
                for (int x = x0; x < x1; x += 8) {
                    const int cnt = std::min(8, x1 - x);
                    shared_groups[std::size_t(ty)] += uniform ? g.uniform(out, x, cnt, y, coherent)
                                                              : g.reconstruct(out, x, cnt, y);
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
