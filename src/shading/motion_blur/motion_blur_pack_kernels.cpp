// The motion blur's pack rows (motion_blur_pack.h), one source over Highway's lane types: one
// pixel a lane, the arithmetic of Packer::pixel (the velocity's clamp and its density round the
// same way; log depth is Highway's polynomial, within a few ulp of std::log), and, for a band
// of rows, the fold of the tile max and bounds that tiles.h computes (the squared lengths are
// rounded as there, so the same vector wins: compiled without FMA contraction, CMakeLists.txt).

// Highway's foreach_target.h comes first, then highway.h.
// clang-format off
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "shading/motion_blur/motion_blur_pack_kernels.cpp"
#include <hwy/foreach_target.h>
#include <hwy/highway.h>
#include <hwy/contrib/math/math-inl.h>
// clang-format on

#include <hwy/aligned_allocator.h>

#include <algorithm>
#include <cstdint>
#include <limits>

#include "shading/motion_blur/motion_blur_pack.h"

HWY_BEFORE_NAMESPACE();
namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<float>;
using DI = hn::RebindToSigned<D>;
using V = hn::Vec<D>;
using VI = hn::Vec<DI>;
using M = hn::Mask<D>;
constexpr int kMaxLanes = HWY_MAX_BYTES / sizeof(float);

/// One tile's accumulators in a band, as lanes of tile_max_bounds: the longest vector so far
/// (length^2, x, y, and its scan index in the tile, for ties) and the box. Stored between rows.
enum Acc { kL, kX, kY, kLoX, kLoY, kHiX, kHiY, kIndex, kAccs };

/// Folds vectors (scan indices idx in their tile; lanes outside `ok` ignored) into the
/// accumulators at a (kAccs vectors of lanes floats; the index as int32 bits).
HWY_INLINE void Fold(float *a, V vx, V vy, VI idx, M ok)
{
    const D d;
    const DI di;
    const size_t n = hn::Lanes(d);
    const V l = hn::Add(hn::Mul(vx, vx), hn::Mul(vy, vy));
    const V al = hn::Load(d, a + kL * n);
    const M gt = hn::And(ok, hn::And(hn::Gt(l, al), hn::Lt(l, hn::Set(d, kInf))));
    hn::Store(hn::IfThenElse(gt, l, al), d, a + kL * n);
    hn::Store(hn::IfThenElse(gt, vx, hn::Load(d, a + kX * n)), d, a + kX * n);
    hn::Store(hn::IfThenElse(gt, vy, hn::Load(d, a + kY * n)), d, a + kY * n);
    std::int32_t *ai = reinterpret_cast<std::int32_t *>(a + kIndex * n);
    hn::Store(hn::IfThenElse(hn::RebindMask(di, gt), idx, hn::Load(di, ai)), di, ai);
    const V lox = hn::Load(d, a + kLoX * n), loy = hn::Load(d, a + kLoY * n);
    const V hix = hn::Load(d, a + kHiX * n), hiy = hn::Load(d, a + kHiY * n);
    hn::Store(hn::IfThenElse(ok, hn::Min(lox, vx), lox), d, a + kLoX * n);
    hn::Store(hn::IfThenElse(ok, hn::Min(loy, vy), loy), d, a + kLoY * n);
    hn::Store(hn::IfThenElse(ok, hn::Max(hix, vx), hix), d, a + kHiX * n);
    hn::Store(hn::IfThenElse(ok, hn::Max(hiy, vy), hiy), d, a + kHiY * n);
}

/// Packer::pixels for a whole row, a vector of pixels at a time. With `acc` (a band's tile
/// accumulators, tiles `tile` wide, a multiple of the lanes; row r of the band), also folds the
/// row's vectors into its tiles.
bool PackRow(const Packer &p, int y, float *acc, int r, int tile)
{
    const D d;
    const DI di;
    const int lanes = int(hn::Lanes(d));
    const std::size_t n = std::size_t(lanes);
    bool opaque = p.nc == 4;
    const VI lane = hn::Iota(di, 0);
    const int mc = p.motion.channels(), cc = p.color.channels();
    const V scale = hn::Set(d, p.scale), max_r = hn::Set(d, p.max_r), zero = hn::Zero(d);
    const V one = hn::Set(d, 1.0f);
    int x = 0;
    for (; x + lanes <= p.w; x += lanes) {
        const float *m = p.motion.pixel(x, y);
        V vx, vy;
        if (mc == 2) {
            hn::LoadInterleaved2(d, m, vx, vy);
        } else {
            const VI off = hn::Mul(lane, hn::Set(di, mc));
            vx = hn::GatherIndex(d, m, off);
            vy = hn::GatherIndex(d, m + 1, off);
        }
        vx = hn::Mul(vx, scale);
        vy = hn::Mul(vy, scale);
        const M ok = hn::And(hn::IsFinite(vx), hn::IsFinite(vy));
        vx = hn::IfThenElseZero(ok, vx);
        vy = hn::IfThenElseZero(ok, vy);
        V len = hn::Sqrt(hn::Add(hn::Mul(vx, vx), hn::Mul(vy, vy)));
        const M lok = hn::IsFinite(len);
        vx = hn::IfThenElseZero(lok, vx);
        vy = hn::IfThenElseZero(lok, vy);
        len = hn::IfThenElseZero(lok, len);
        const M over = hn::Gt(len, max_r);
        const V k = hn::IfThenElse(over, hn::Div(max_r, len), one);
        vx = hn::IfThenElse(over, hn::Mul(vx, k), vx);
        vy = hn::IfThenElse(over, hn::Mul(vy, k), vy);
        len = hn::IfThenElse(over, max_r, len);
        V lz = zero;  // log 1: no depth
        if (!p.depth.empty()) {
            const int dc = p.depth.channels();
            const V z =
                dc == 1 ? hn::LoadU(d, p.depth.pixel(x, y))
                        : hn::GatherIndex(d, p.depth.pixel(x, y), hn::Mul(lane, hn::Set(di, dc)));
            // NaN, zero or negative depth is sky.
            const M good = hn::And(hn::Gt(z, zero), hn::IsFinite(z));
            lz = hn::IfThenElse(
                good, hn::Log(d, hn::Max(z, hn::Set(d, 1e-30f))), hn::Set(d, kSkyLogZ));
        }
        const V dens =
            hn::IfThenElseZero(hn::Ge(len, hn::Set(d, 0.5f)),
                               hn::Div(one, hn::Mul(hn::Mul(hn::Set(d, 2.0f), len), len)));
        const std::size_t i0 = std::size_t(y) * std::size_t(p.w) + std::size_t(x);
        const float *c = p.color.pixel(x, y);
        if (cc == 4) {
            V ch[4];
            hn::LoadInterleaved4(d, c, ch[0], ch[1], ch[2], ch[3]);
            for (int k = 0; k < 4; ++k) {
                hn::StoreU(ch[k], d, p.out.plane(kRed + k) + i0);
            }
            opaque = opaque && hn::AllTrue(d, hn::Eq(ch[3], one));
        } else {
            const VI off = hn::Mul(lane, hn::Set(di, cc));
            for (int k = 0; k < 4; ++k) {
                hn::StoreU(k < p.nc ? hn::GatherIndex(d, c + k, off) : zero,
                           d,
                           p.out.plane(kRed + k) + i0);
            }
            opaque = false;
        }
        hn::StoreU(hn::Mul(vx, dens), d, p.out.plane(kWx) + i0);
        hn::StoreU(hn::Mul(vy, dens), d, p.out.plane(kWy) + i0);
        hn::StoreU(lz, d, p.out.plane(kLogZ) + i0);
        hn::StoreU(len, d, p.out.plane(kLen) + i0);
        if (acc) {
            const int tx = x / tile;
            Fold(acc + std::size_t(tx) * kAccs * n,
                 vx,
                 vy,
                 hn::Add(hn::Set(di, r * tile + (x - tx * tile)), lane),
                 hn::FirstN(d, n));
        }
        if (!p.out.velocity.empty()) {
            hn::StoreInterleaved2(vx, vy, d, p.out.velocity.pixel(x, y));
        }
    }
    if (x == p.w) {
        return opaque;
    }
    // The tail through the scalar arithmetic.
    HWY_ALIGN float tvx[kMaxLanes] = {}, tvy[kMaxLanes] = {};
    opaque = p.pixels(y, x, p.w, tvx, tvy) && opaque;
    if (acc) {
        const int tx = x / tile;
        Fold(acc + std::size_t(tx) * kAccs * n,
             hn::Load(d, tvx),
             hn::Load(d, tvy),
             hn::Add(hn::Set(di, r * tile + (x - tx * tile)), lane),
             hn::FirstN(d, std::size_t(p.w - x)));
    }
    return opaque;
}

bool PackRowVector(const Packer &p, int y)
{
    return PackRow(p, y, nullptr, 0, 1);
}

/// The rows of band ty with the fold, then each tile from its lanes: the longest vector (the
/// first in scan order among equals) and the box.
void PackBand(const Packer &p, int ty, int tile, Packed &out)
{
    const D d;
    const std::size_t n = hn::Lanes(d);
    const int tw = out.tiles.width();
    auto acc = hwy::AllocateAligned<float>(std::size_t(tw) * kAccs * n);
    for (int tx = 0; tx < tw; ++tx) {
        float *a = acc.get() + std::size_t(tx) * kAccs * n;
        for (std::size_t j = 0; j < n; ++j) {
            a[kL * n + j] = a[kX * n + j] = a[kY * n + j] = 0.0f;
            a[kLoX * n + j] = a[kLoY * n + j] = kInf;
            a[kHiX * n + j] = a[kHiY * n + j] = -kInf;
            reinterpret_cast<std::int32_t *>(a + kIndex * n)[j] =
                std::numeric_limits<std::int32_t>::max();
        }
    }
    const int y0 = ty * tile, y1 = std::min(p.motion.height(), y0 + tile);
    for (int y = y0; y < y1; ++y) {
        out.opaque_rows[std::size_t(y)] = PackRow(p, y, acc.get(), y - y0, tile);
    }
    for (int tx = 0; tx < tw; ++tx) {
        const float *a = acc.get() + std::size_t(tx) * kAccs * n;
        const float *l = a + kL * n;
        const std::int32_t *idx = reinterpret_cast<const std::int32_t *>(a + kIndex * n);
        std::size_t best = 0;
        for (std::size_t j = 1; j < n; ++j) {
            if (l[j] > l[best] || (l[j] == l[best] && idx[j] < idx[best])) {
                best = j;
            }
        }
        out.tiles.at(tx, ty, 0) = a[kX * n + best];
        out.tiles.at(tx, ty, 1) = a[kY * n + best];
        if (!out.bounds.empty()) {
            float *o = out.bounds.pixel(tx, ty);
            o[0] = *std::min_element(a + kLoX * n, a + kLoX * n + n);
            o[1] = *std::min_element(a + kLoY * n, a + kLoY * n + n);
            o[2] = *std::max_element(a + kHiX * n, a + kHiX * n + n);
            o[3] = *std::max_element(a + kHiY * n, a + kHiY * n + n);
        }
    }
}

int PackLanes()
{
    return int(hn::Lanes(D()));
}

}  // namespace posthaste::shading::motion_blur_detail::HWY_NAMESPACE
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace posthaste::shading::motion_blur_detail {

HWY_EXPORT(PackLanes);
HWY_EXPORT(PackRowVector);
HWY_EXPORT(PackBand);

int pack_lanes()
{
    return HWY_DYNAMIC_DISPATCH(PackLanes)();
}

bool pack_row_vector(const Packer &p, int y)
{
    return HWY_DYNAMIC_DISPATCH(PackRowVector)(p, y);
}

void pack_band_vector(const Packer &p, int ty, int tile, Packed &out)
{
    HWY_DYNAMIC_DISPATCH(PackBand)(p, ty, tile, out);
}

}  // namespace posthaste::shading::motion_blur_detail
#endif
