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
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <limits>
#include <memory>
#include <mutex>
#include <new>
#include <vector>

#include "core/hash.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
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

/// The AVX2 path's records, two arrays (24 bytes a pixel instead of 32, six gathers a sample
/// instead of eight): colour, four floats (zero-padded; floats, so the output stays a convex
/// combination of input values), and Geo: the density (wx, wy) as two half floats and log
/// depth as a float (halves would quantise the depth ramp). |v| = 1 / (2 |w|) where it is used.
struct Geo {
    std::uint32_t w;
    float lz;
};
static_assert(sizeof(Geo) == 2 * sizeof(float));

/// Scratch blocks kept between calls: the records are tens of megabytes written once per
/// frame, and fresh memory costs the kernel a page clear (and a fault) per page on first touch
/// (perf, f6: clear_page_erms about 5 % of the node). A released block goes back here; a call
/// takes a block of the same size if one is free. At most kPoolBytes are kept; the contents of
/// a reused block are stale, which is fine: pack writes every record before it is read.
class ScratchPool {
   public:
    static ScratchPool &instance()
    {
        static ScratchPool pool;
        return pool;
    }

    void *take(std::size_t bytes)
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            for (std::size_t i = 0; i < free_.size(); ++i) {
                if (free_[i].bytes == bytes) {
                    void *p = free_[i].p;
                    kept_ -= bytes;
                    free_.erase(free_.begin() + std::ptrdiff_t(i));
                    return p;
                }
            }
        }
        constexpr std::size_t kHuge = std::size_t(2) << 20;
        void *p = std::aligned_alloc(kHuge, bytes);
        if (!p) {
            throw std::bad_alloc();
        }
        advise_huge_pages(p, bytes);
        return p;
    }

    void give(void *p, std::size_t bytes)
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            if (kept_ + bytes <= kPoolBytes) {
                free_.push_back({p, bytes});
                kept_ += bytes;
                return;
            }
        }
        std::free(p);
    }

    ~ScratchPool()
    {
        for (const Block &b : free_) {
            std::free(b.p);
        }
    }

   private:
    static constexpr std::size_t kPoolBytes = std::size_t(256) << 20;
    struct Block {
        void *p;
        std::size_t bytes;
    };
    std::mutex mutex_;
    std::vector<Block> free_;
    std::size_t kept_ = 0;
};

struct PoolDeleter {
    std::size_t bytes = 0;
    void operator()(void *p) const { ScratchPool::instance().give(p, bytes); }
};
/// Uninitialized storage for n trivial records (pack writes every one).
template <class T>
using Scratch = std::unique_ptr<T[], PoolDeleter>;

/// Scratch<T> in 2 MiB-aligned blocks with huge pages advised (core/memory.h): tens of
/// megabytes of fresh memory otherwise cost one page fault per 4 KiB on first touch (measured:
/// kernel page-fault handling was a quarter of the AVX2 gather's time), reused between calls
/// through ScratchPool.
template <class T>
Scratch<T> scratch(std::size_t n)
{
    constexpr std::size_t kHuge = std::size_t(2) << 20;
    const std::size_t bytes = std::max<std::size_t>((n * sizeof(T) + kHuge - 1) / kHuge, 1) * kHuge;
    return Scratch<T>(static_cast<T *>(ScratchPool::instance().take(bytes)), PoolDeleter{bytes});
}

/// The records (Px for the scalar path; colour and Geo for the AVX2 path; allocated
/// uninitialized, pack writes every one) and the clamped half-extent vectors (2 channels, for
/// the tile max).
struct Packed {
    Scratch<Px> px;
    Scratch<float> col;
    Scratch<Geo> geo;
    Image velocity;
};

/// Writes the records and velocities of a frame, row by row.
struct Packer {
    const Image &color, &motion, &depth;
    Packed &out;
    int w, nc;
    float scale, max_r;

    /// The record of pixel (x, y) into `p`; writes its velocity.
    void pixel(int y, int x, Px &p) const
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

    /// The colour records (AVX2 path) of pixels [x0, x1) of row y.
    void colors(int y, int x0, int x1) const
    {
        float *o = &out.col[(std::size_t(y) * std::size_t(w) + std::size_t(x0)) * 4];
        const float *c = color.pixel(x0, y);
        for (int x = x0; x < x1; ++x, o += 4, c += color.channels()) {
            for (int k = 0; k < 4; ++k) {
                o[k] = k < nc ? c[k] : 0.0f;
            }
        }
    }

    /// Pixels [x0, x1) of row y.
    void pixels(int y, int x0, int x1) const
    {
        for (int x = x0; x < x1; ++x) {
            pixel(y, x, out.px[std::size_t(y) * std::size_t(w) + std::size_t(x)]);
        }
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

/// Packer::pixels for a whole row, eight pixels at a time (the same arithmetic; log is the
/// polynomial of simd::v8, within 2 ulp of std::log).
POSTHASTE_AVX2 void pack_row_avx2(const Packer &p, int y)
{
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const VI mstride = _mm256_mullo_epi32(lane, _mm256_set1_epi32(p.motion.channels()));
    const V scale = set1(p.scale), max_r = set1(p.max_r), zero = _mm256_setzero_ps();
    int x = 0;
    for (; x + 8 <= p.w; x += 8) {
        const float *m = p.motion.pixel(x, y);
        V vx = _mm256_mul_ps(_mm256_i32gather_ps(m, mstride, 4), scale);
        V vy = _mm256_mul_ps(_mm256_i32gather_ps(m + 1, mstride, 4), scale);
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
        const int round = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;
        const __m128i hx = _mm256_cvtps_ph(_mm256_mul_ps(vx, dens), round);
        const __m128i hy = _mm256_cvtps_ph(_mm256_mul_ps(vy, dens), round);
        alignas(32) std::uint32_t words[8];
        alignas(32) float lzs[8];
        _mm_store_si128(reinterpret_cast<__m128i *>(words), _mm_unpacklo_epi16(hx, hy));
        _mm_store_si128(reinterpret_cast<__m128i *>(words + 4), _mm_unpackhi_epi16(hx, hy));
        _mm256_store_ps(lzs, lz);
        // Interleave the velocity: (vx0, vy0, vx1, vy1, ...).
        const V lo = _mm256_unpacklo_ps(vx, vy), hi = _mm256_unpackhi_ps(vx, vy);
        float *vel = p.out.velocity.pixel(x, y);
        _mm256_storeu_ps(vel, _mm256_permute2f128_ps(lo, hi, 0x20));
        _mm256_storeu_ps(vel + 8, _mm256_permute2f128_ps(lo, hi, 0x31));
        const std::size_t i0 = std::size_t(y) * std::size_t(p.w) + std::size_t(x);
        for (int j = 0; j < 8; ++j) {
            p.out.geo[i0 + std::size_t(j)] = Geo{words[j], lzs[j]};
        }
        p.colors(y, x, x + 8);
    }
    for (; x < p.w; ++x) {
        // The tail: one pixel through the scalar arithmetic, converted.
        Px one;
        p.pixel(y, x, one);
        alignas(16) std::uint16_t hv[8];
        _mm_store_si128(reinterpret_cast<__m128i *>(hv),
                        _mm256_cvtps_ph(_mm256_setr_ps(one.wx, one.wy, 0, 0, 0, 0, 0, 0),
                                        _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
        p.out.geo[std::size_t(y) * std::size_t(p.w) + std::size_t(x)] =
            Geo{std::uint32_t(hv[0]) | std::uint32_t(hv[1]) << 16, one.lz};
        p.colors(y, x, x + 1);
    }
}
#endif

Packed pack(const Image &color,
            const Image &motion,
            const Image &depth,
            const MotionBlurOptions &o,
            bool vector)
{
    const int w = motion.width(), h = motion.height();
    const std::size_t n = std::size_t(w) * std::size_t(h);
    Packed out{vector ? nullptr : scratch<Px>(n),
               vector ? scratch<float>(4 * n) : nullptr,
               vector ? scratch<Geo>(n) : nullptr,
               Image::uninitialized(w, h, 2)};
    const Packer p{color,
                   motion,
                   depth,
                   out,
                   w,
                   std::min(color.channels(), 4),
                   0.5f * o.shutter,
                   std::max(o.max_radius, 0.0f)};
#if POSTHASTE_HAVE_AVX2_TARGET
    if (vector) {
        parallel_for(0, h, [&](int y) { pack_row_avx2(p, y); });
        return out;
    }
#endif
    parallel_for(0, h, [&](int y) { p.pixels(y, 0, w); });
    return out;
}

struct Gather {
    const Image &color;
    const Px *px_;      ///< scalar path
    const float *col_;  ///< AVX2 path: colour records
    const Geo *geo_;    ///< AVX2 path
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
/// The pixel index of lane x + 0.5 + t v, clamped to the frame (Gather::at).
struct Frame8 {
    V xf, yf, xmax, ymax;
    VI w;
};
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
template <int Field>
POSTHASTE_AVX2_INLINE V field8(const float *base, VI off)
{
    return _mm256_i32gather_ps(base + Field, off, 4);
}
/// The two half floats of each 32-bit lane (low, high) as two float vectors.
POSTHASTE_AVX2_INLINE void halves8(V words, V &lo, V &hi)
{
    // Per 128-bit half: low halves to bytes 0-7, high halves to bytes 8-15; then the quadwords
    // in the order (lo 0-3, lo 4-7, hi 0-3, hi 4-7).
    const VI order = _mm256_setr_epi8(0,
                                      1,
                                      4,
                                      5,
                                      8,
                                      9,
                                      12,
                                      13,
                                      2,
                                      3,
                                      6,
                                      7,
                                      10,
                                      11,
                                      14,
                                      15,
                                      0,
                                      1,
                                      4,
                                      5,
                                      8,
                                      9,
                                      12,
                                      13,
                                      2,
                                      3,
                                      6,
                                      7,
                                      10,
                                      11,
                                      14,
                                      15);
    const VI s = _mm256_permute4x64_epi64(_mm256_shuffle_epi8(_mm256_castps_si256(words), order),
                                          _MM_SHUFFLE(3, 1, 2, 0));
    lo = _mm256_cvtph_ps(_mm256_castsi256_si128(s));
    hi = _mm256_cvtph_ps(_mm256_extracti128_si256(s, 1));
}
/// Colour records a and b in the low and high halves.
POSTHASTE_AVX2_INLINE V pair8(const float *col, std::int32_t a, std::int32_t b)
{
    return _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(col + 4 * std::ptrdiff_t(a))),
                                _mm_loadu_ps(col + 4 * std::ptrdiff_t(b)),
                                1);
}
/// The four colour channels of the colour records of pixels i[0..7]: eight 16-byte loads and a
/// 4x4 transpose per 128-bit half, cheaper than four gathers of the same lines.
POSTHASTE_AVX2_INLINE void color8(const float *col, const std::int32_t *i, V *c)
{
    const V r0 = pair8(col, i[0], i[4]), r1 = pair8(col, i[1], i[5]);
    const V r2 = pair8(col, i[2], i[6]), r3 = pair8(col, i[3], i[7]);
    const V t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpacklo_ps(r2, r3);
    const V t2 = _mm256_unpackhi_ps(r0, r1), t3 = _mm256_unpackhi_ps(r2, r3);
    c[0] = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(1, 0, 1, 0));
    c[1] = _mm256_shuffle_ps(t0, t1, _MM_SHUFFLE(3, 2, 3, 2));
    c[2] = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(1, 0, 1, 0));
    c[3] = _mm256_shuffle_ps(t2, t3, _MM_SHUFFLE(3, 2, 3, 2));
}
/// color8 from a vector of pixel indices.
POSTHASTE_AVX2_INLINE void color8(const float *col, VI idx, V *c)
{
    alignas(32) std::int32_t i[8];
    _mm256_store_si256(reinterpret_cast<VI *>(i), idx);
    color8(col, i, c);
}
/// Geo records a, b in the low 128 bits, c, d in the high.
POSTHASTE_AVX2_INLINE V
quad8(const Geo *geo, std::int32_t a, std::int32_t b, std::int32_t c, std::int32_t d)
{
    auto half = [geo](std::int32_t x, std::int32_t y) {
        return _mm_castpd_ps(_mm_loadh_pd(_mm_load_sd(reinterpret_cast<const double *>(geo + x)),
                                          reinterpret_cast<const double *>(geo + y)));
    };
    return _mm256_insertf128_ps(_mm256_castps128_ps256(half(a, b)), half(c, d), 1);
}
/// The Geo records of pixels i[0..7]: density words and log depth, by 8-byte loads.
POSTHASTE_AVX2_INLINE void geo8(const Geo *geo, const std::int32_t *i, V &w, V &lz)
{
    const V a = quad8(geo, i[0], i[1], i[4], i[5]), b = quad8(geo, i[2], i[3], i[6], i[7]);
    w = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(2, 0, 2, 0));
    lz = _mm256_shuffle_ps(a, b, _MM_SHUFFLE(3, 1, 3, 1));
}

/// Writes the first `lanes` results (SoA, r[channel][lane]) of row y from x, lanes not in
/// `keep` copied from the input.
POSTHASTE_AVX2_INLINE void store8(
    const Gather &g, Image &out, int x, int y, int lanes, const V *r, V keep)
{
    alignas(32) float v[4][8];
    for (int k = 0; k < 4; ++k) {
        _mm256_store_ps(v[k], r[k]);
    }
    const int mask = _mm256_movemask_ps(keep);
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

/// Gather::uniform for pixels [x0, x1) of row y, eight at a time.
POSTHASTE_AVX2 void uniform_row_avx2(const Gather &g, Image &out, int y, int x0, int x1)
{
    const float *col = g.col_;
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const Frame8 fr{set1(0.0f),
                    set1(float(y) + 0.5f),
                    set1(float(g.w) - 0.5f),
                    set1(float(g.h) - 0.5f),
                    _mm256_set1_epi32(g.w)};
    const VI ky =
        _mm256_set1_epi32(int(pcg_hash(std::uint32_t(y) ^ pcg_hash(0u ^ pcg_hash(g.o.seed)))));
    const V most = set1(float(g.o.samples));
    const VI last = _mm256_set1_epi32(g.w - 1);
    for (int x = x0; x < x1; x += 8) {
        // A group past the row's end (narrow tiles) computes its lanes on the last pixel and
        // stores only the first `lanes`.
        const int lanes = std::min(8, x1 - x);
        const VI xc =
            _mm256_sub_epi32(_mm256_min_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane), last),
                             _mm256_set1_epi32(x));
        const VI lane2 = _mm256_slli_epi32(xc, 1);
        const float *vel = g.velocity.pixel(x, y);
        const V vx = _mm256_i32gather_ps(vel, lane2, 4),
                vy = _mm256_i32gather_ps(vel + 1, lane2, 4);
        const V len = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(vx, vx), _mm256_mul_ps(vy, vy)));
        const V moving = _mm256_cmp_ps(len, set1(0.5f), _CMP_GE_OQ);
        if (_mm256_movemask_ps(moving) == 0) {
            for (int j = 0; j < lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
            continue;
        }
        const VI xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
        Frame8 f = fr;
        f.xf = _mm256_add_ps(_mm256_cvtepi32_ps(xi), set1(0.5f));
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
            V c[4];
            color8(col, offset8(f, t, vx, vy), c);
            for (int k = 0; k < 4; ++k) {
                acc[k] = _mm256_add_ps(acc[k], _mm256_and_ps(c[k], active));
            }
        }
        for (int k = 0; k < 4; ++k) {
            acc[k] = _mm256_div_ps(acc[k], n);
        }
        store8(g, out, x, y, lanes, acc, moving);
    }
}

/// Gather::reconstruct for pixels [x0, x1) of row y, eight at a time: each lane follows its
/// own pixel's paths and sample counts (lanes past their count add nothing).
POSTHASTE_AVX2 void reconstruct_row_avx2(const Gather &g, Image &out, int y, int x0, int x1)
{
    const float *col = g.col_, *geo = reinterpret_cast<const float *>(g.geo_);
    const VI lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);

    const Frame8 fr{set1(0.0f),
                    set1(float(y) + 0.5f),
                    set1(float(g.w) - 0.5f),
                    set1(float(g.h) - 0.5f),
                    _mm256_set1_epi32(g.w)};
    const std::uint32_t s0 = pcg_hash(g.o.seed);
    const VI ky0 = _mm256_set1_epi32(int(pcg_hash(std::uint32_t(y) ^ pcg_hash(0u ^ s0))));
    const VI ky1 = _mm256_set1_epi32(int(pcg_hash(std::uint32_t(y) ^ pcg_hash(1u ^ s0))));
    const V most = set1(float(g.o.samples)), zero = _mm256_setzero_ps(), one = set1(1.0f),
            half = set1(0.5f), inv_soft = set1(g.inv_soft), inv_tile = set1(g.inv_tile);
    const V jit = set1(2.0f * g.o.tile_jitter * float(g.o.tile));
    const VI ntw = _mm256_set1_epi32(g.nmax.width());
    const VI tx_max = _mm256_set1_epi32(g.nmax.width() - 1),
             ty_max = _mm256_set1_epi32(g.nmax.height() - 1);
    const float *nbase = g.nmax.data();
    const VI last = _mm256_set1_epi32(g.w - 1);
    for (int x = x0; x < x1; x += 8) {
        // A group past the row's end (narrow tiles) computes its lanes on the last pixel and
        // stores only the first `lanes`.
        const int lanes = std::min(8, x1 - x);
        const VI xc =
            _mm256_sub_epi32(_mm256_min_epi32(_mm256_add_epi32(_mm256_set1_epi32(x), lane), last),
                             _mm256_set1_epi32(x));
        const VI lane2 = _mm256_slli_epi32(xc, 1);
        const VI xi = _mm256_add_epi32(_mm256_set1_epi32(x), lane);
        Frame8 f = fr;
        f.xf = _mm256_add_ps(_mm256_cvtepi32_ps(xi), half);
        // Jittered neighbour-max lookup.
        const VI hj = pcg8(_mm256_xor_si256(xi, ky1));
        const V jx = _mm256_mul_ps(_mm256_sub_ps(unit8(hj), half), jit);
        const V jy = _mm256_mul_ps(_mm256_sub_ps(unit8(pcg8(hj)), half), jit);
        const VI tx = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(
                                           _mm256_max_ps(_mm256_add_ps(f.xf, jx), zero), inv_tile)),
                                       tx_max);
        const VI ty = _mm256_min_epi32(_mm256_cvttps_epi32(_mm256_mul_ps(
                                           _mm256_max_ps(_mm256_add_ps(f.yf, jy), zero), inv_tile)),
                                       ty_max);
        const VI toff = _mm256_slli_epi32(_mm256_add_epi32(_mm256_mullo_epi32(ty, ntw), tx), 1);
        V nvx = _mm256_i32gather_ps(nbase, toff, 4), nvy = _mm256_i32gather_ps(nbase + 1, toff, 4);
        V L = _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(nvx, nvx), _mm256_mul_ps(nvy, nvy)));
        const V live = _mm256_cmp_ps(L, half, _CMP_GE_OQ);
        if (_mm256_movemask_ps(live) == 0) {
            for (int j = 0; j < lanes; ++j) {
                g.copy_pixel(out, x + j, y);
            }
            continue;
        }
        const std::size_t i0 = std::size_t(y) * std::size_t(g.w) + std::size_t(x);
        V cc[4];
        color8(col + i0 * 4, xc, cc);
        const V clz = _mm256_i32gather_ps(geo + i0 * 2 + 1, _mm256_slli_epi32(xc, 1), 4);
        const float *vel = g.velocity.pixel(x, y);
        const V cvx = _mm256_i32gather_ps(vel, lane2, 4),
                cvy = _mm256_i32gather_ps(vel + 1, lane2, 4);
        const V clen =
            _mm256_sqrt_ps(_mm256_add_ps(_mm256_mul_ps(cvx, cvx), _mm256_mul_ps(cvy, cvy)));
        V dnx = _mm256_div_ps(nvx, L), dny = _mm256_div_ps(nvy, L);
        const VI hu = pcg8(_mm256_xor_si256(xi, ky0));
        const V u = unit8(hu), u2 = unit8(pcg8(hu));

        const V own_path = _mm256_cmp_ps(clen, half, _CMP_GE_OQ);
        const V dcx = _mm256_and_ps(_mm256_div_ps(cvx, clen), own_path);
        const V dcy = _mm256_and_ps(_mm256_div_ps(cvy, clen), own_path);
        const V cosine = abs8(_mm256_add_ps(_mm256_mul_ps(dcx, dnx), _mm256_mul_ps(dcy, dny)));
        const V shared =
            _mm256_and_ps(_mm256_and_ps(own_path, _mm256_cmp_ps(cosine, set1(0.9f), _CMP_GT_OQ)),
                          _mm256_cmp_ps(clen, _mm256_mul_ps(half, L), _CMP_GE_OQ));
        const V inv_own =
            _mm256_and_ps(_mm256_div_ps(one, _mm256_mul_ps(set1(2.0f), clen)), own_path);
        dnx = _mm256_blendv_ps(dnx, dcx, shared);
        dny = _mm256_blendv_ps(dny, dcy, shared);
        nvx = _mm256_blendv_ps(nvx, _mm256_mul_ps(dcx, L), shared);
        nvy = _mm256_blendv_ps(nvy, _mm256_mul_ps(dcy, L), shared);
        const V longer =
            _mm256_and_ps(shared, _mm256_cmp_ps(clen, _mm256_mul_ps(set1(0.8f), L), _CMP_GT_OQ));
        nvx = _mm256_blendv_ps(nvx, cvx, longer);
        nvy = _mm256_blendv_ps(nvy, cvy, longer);
        L = _mm256_blendv_ps(L, clen, longer);

        const V n = _mm256_and_ps(count8(L, most), live);
        const V step = _mm256_div_ps(set1(2.0f), _mm256_max_ps(n, one));
        const V delta = _mm256_mul_ps(L, step);
        const V own_w = _mm256_and_ps(_mm256_mul_ps(delta, inv_own), shared);
        V fg[4] = {zero, zero, zero, zero}, bg[4] = {zero, zero, zero, zero};
        V F = zero, B = zero;
        const int n_max = max_lane(n);
        for (int i = 0; i < n_max; ++i) {
            const V fi = set1(float(i));
            const V active = _mm256_cmp_ps(fi, n, _CMP_LT_OQ);
            const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u), step));
            alignas(32) std::int32_t idx[8];
            _mm256_store_si256(reinterpret_cast<VI *>(idx), offset8(f, t, nvx, nvy));
            V words, slz, swx, swy;
            geo8(g.geo_, idx, words, slz);
            halves8(words, swx, swy);
            // |v| = 1 / (2 |w|); where w = 0 it is unused (the weight has a factor |w . d|).
            const V slen =
                _mm256_mul_ps(half,
                              simd::v8::rsqrt(_mm256_max_ps(
                                  _mm256_add_ps(_mm256_mul_ps(swx, swx), _mm256_mul_ps(swy, swy)),
                                  set1(1e-30f))));
            const V T = _mm256_mul_ps(abs8(t), L);
            const V fr_w = simd::v8::clamp(
                _mm256_add_ps(half, _mm256_mul_ps(_mm256_sub_ps(clz, slz), inv_soft)), zero, one);
            const V reach_s =
                simd::v8::clamp(_mm256_sub_ps(_mm256_add_ps(slen, half), T), zero, one);
            const V reach_c =
                simd::v8::clamp(_mm256_sub_ps(_mm256_add_ps(clen, half), T), zero, one);
            const V along = abs8(_mm256_add_ps(_mm256_mul_ps(swx, dnx), _mm256_mul_ps(swy, dny)));
            const V wf = _mm256_and_ps(
                _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(fr_w, reach_s), along), delta), active);
            const V wb = _mm256_and_ps(
                _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr_w), reach_c), own_w), active);
            F = _mm256_add_ps(F, wf);
            B = _mm256_add_ps(B, wb);
            V sc[4];
            color8(col, idx, sc);
            for (int k = 0; k < 4; ++k) {
                fg[k] = _mm256_add_ps(fg[k], _mm256_mul_ps(wf, sc[k]));
                bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, sc[k]));
            }
        }
        // Guertin's second direction, for lanes whose own path is not shared.
        V own_delta = delta;
        const V second = _mm256_andnot_ps(shared, _mm256_and_ps(own_path, live));
        if (_mm256_movemask_ps(second) != 0) {
            const V half_n = _mm256_floor_ps(_mm256_mul_ps(_mm256_add_ps(n, one), half));
            const V m = _mm256_and_ps(
                _mm256_max_ps(set1(2.0f), _mm256_min_ps(count8(clen, most), half_n)), second);
            const V mstep = _mm256_div_ps(set1(2.0f), _mm256_max_ps(m, one));
            const V od = _mm256_mul_ps(clen, mstep);
            own_delta = _mm256_blendv_ps(own_delta, od, second);
            const V wm = _mm256_mul_ps(od, inv_own);
            const int m_max = max_lane(m);
            for (int i = 0; i < m_max; ++i) {
                const V fi = set1(float(i));
                const V active = _mm256_cmp_ps(fi, m, _CMP_LT_OQ);
                const V t = _mm256_add_ps(set1(-1.0f), _mm256_mul_ps(_mm256_add_ps(fi, u2), mstep));
                alignas(32) std::int32_t idx[8];
                _mm256_store_si256(reinterpret_cast<VI *>(idx), offset8(f, t, cvx, cvy));
                V words, slz;
                geo8(g.geo_, idx, words, slz);
                const V fr_w = simd::v8::clamp(
                    _mm256_add_ps(half, _mm256_mul_ps(_mm256_sub_ps(clz, slz), inv_soft)),
                    zero,
                    one);
                const V wb = _mm256_and_ps(_mm256_mul_ps(_mm256_sub_ps(one, fr_w), wm), active);
                B = _mm256_add_ps(B, wb);
                V sc[4];
                color8(col, idx, sc);
                for (int k = 0; k < 4; ++k) {
                    bg[k] = _mm256_add_ps(bg[k], _mm256_mul_ps(wb, sc[k]));
                }
            }
        }
        const V full = _mm256_cmp_ps(F, one, _CMP_GE_OQ);
        const V wc = _mm256_blendv_ps(
            one, _mm256_mul_ps(_mm256_mul_ps(set1(1e-3f), own_delta), inv_own), own_path);
        B = _mm256_add_ps(B, wc);
        const V rest = _mm256_div_ps(_mm256_sub_ps(one, F), B);
        V r[4];
        for (int k = 0; k < 4; ++k) {
            const V blend = _mm256_add_ps(
                fg[k], _mm256_mul_ps(rest, _mm256_add_ps(bg[k], _mm256_mul_ps(wc, cc[k]))));
            r[k] = _mm256_blendv_ps(blend, _mm256_div_ps(fg[k], F), full);
        }
        store8(g, out, x, y, lanes, r, live);
    }
}
#endif

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
    // The AVX2 rows address the colour records with 32-bit offsets.
    const bool vector =
        simd::avx2() && std::size_t(w) * std::size_t(h) * 4 < (std::size_t(1) << 31);
    const Packed packed = pack(color, motion, depth, o, vector);
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
    // Per tile, only the tiles whose own vectors can reach it (plus the jitter's one tile):
    // slow regions beside fast ones get a short neighbour max (fewer samples, along motion that
    // can actually cover them) and pass the coherence test more often.
    const int margin = o.tile_jitter > 0.0f ? 1 : 0;
    const Image nmax = neighbour_max_reach(tiles, o.tile, margin, std::max(radius, 1));
    const Image nbounds =
        o.coherence > 0.0f && o.method == BlurMethod::Reconstruct
            ? neighbour_bounds_reach(
                  tile_bounds(packed.velocity, o.tile), tiles, o.tile, margin, std::max(radius, 1))
            : Image();
    st.neighbour_max_ms = ms_since(t0);
    st.neighbour_max_cpu_ms = process_cpu_ms() - c0;

    t0 = std::chrono::steady_clock::now();
    c0 = process_cpu_ms();
    Image out = Image::uninitialized(w, h, color.channels());
    const Gather g{color,
                   packed.px.get(),
                   packed.col.get(),
                   packed.geo.get(),
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
            const bool uniform = o.method == BlurMethod::Uniform || coherent;
#if POSTHASTE_HAVE_AVX2_TARGET
            if (vector) {
                for (int y = r.y0; y < r.y1; ++y) {
                    if (uniform) {
                        uniform_row_avx2(g, out, y, r.x0, r.x1);
                    } else {
                        reconstruct_row_avx2(g, out, y, r.x0, r.x1);
                    }
                }
                return;
            }
#endif
            for (int y = r.y0; y < r.y1; ++y) {
                for (int x = r.x0; x < r.x1; ++x) {
                    if (uniform) {
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
