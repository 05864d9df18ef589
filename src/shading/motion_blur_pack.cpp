// The motion blur's pack: each pixel's record (colour, log depth, coverage density, |v|) into
// field planes, row by row; the AVX2 path also folds the tile max and bounds of the velocities
// while it packs, for tiles a multiple of 8 wide.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/motion_blur_records.h"
#include "shading/tiles.h"

namespace posthaste::shading::motion_blur_detail {
namespace {

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

}  // namespace

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

}  // namespace posthaste::shading::motion_blur_detail
