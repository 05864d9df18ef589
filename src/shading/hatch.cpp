#include "shading/hatch.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>

#include "core/parallel.h"
#include "core/simd.h"
#include "core/simd_avx2.h"
#include "shading/hatch_kernel.h"

namespace posthaste::shading {
namespace {

constexpr float kPiF = 3.14159265358979323846f;

/// log2(x) for x > 0 within 0.005, continuous and increasing: exponent plus a quadratic on the
/// mantissa (exact at powers of two). For mip levels, where libm's log2f was a hot spot.
inline float fast_log2(float x)
{
    std::uint32_t bits;
    std::memcpy(&bits, &x, 4);
    const float e = float(int((bits >> 23) & 0xffu) - 127);
    bits = (bits & 0x007fffffu) | 0x3f800000u;  // mantissa in [1, 2)
    float m;
    std::memcpy(&m, &bits, 4);
    const float t = m - 1.0f;
    return e + t * (1.3466f - 0.3466f * t);
}

/// Per-pixel surface facts read from the passes.
struct Sample {
    bool hit = false;     ///< Finite positive depth and finite position.
    bool normal = false;  ///< hit and a usable (finite, non-zero) normal.
    float z = 0.0f;
    glm::vec3 p{0.0f}, n{0.0f};
};

/// x is finite (not NaN, not +-inf); cheaper than std::isfinite on three values.
inline bool finite_f(float x)
{
    return x - x == 0.0f;
}

Sample read_sample(const float *z_px, const float *p_px, const float *n_px)
{
    Sample s;
    const float z = *z_px;
    if (!(z > 0.0f && finite_f(z) && finite_f(p_px[0] + p_px[1] + p_px[2]))) {
        return s;  // sky, or unusable geometry
    }
    s.hit = true;
    s.z = z;
    s.p = {p_px[0], p_px[1], p_px[2]};
    const glm::vec3 nv{n_px[0], n_px[1], n_px[2]};
    const float len2 = glm::dot(nv, nv);
    if (len2 > 1e-4f && finite_f(len2)) {
        s.normal = true;
        s.n = std::abs(len2 - 1.0f) < 1e-4f ? nv : nv / std::sqrt(len2);
    }
    return s;
}

/// Whether pixel p carries an outline against neighbour q (one side only, so lines stay thin).
inline bool is_edge(const Sample &p, const Sample &q, bool q_after, float depth_thr, float cos_thr)
{
    if (!p.hit) {
        return false;
    }
    if (!q.hit) {
        return true;  // silhouette against the sky
    }
    const float gap = p.normal ? std::abs(glm::dot(p.n, q.p - p.p)) : std::abs(q.z - p.z);
    if (gap > depth_thr * p.z) {
        return p.z <= q.z;  // the nearer side draws the line
    }
    return q_after && p.normal && q.normal && glm::dot(p.n, q.n) < cos_thr;
}

/// World-space step to a neighbour usable for footprints: on the same smooth surface.
bool neighbour_step(const Sample &c, const Sample &q, glm::vec3 &step)
{
    if (!q.hit || !q.normal || glm::dot(c.n, q.n) < 0.7f) {
        return false;
    }
    step = q.p - c.p;
    return glm::dot(step, step) > 0.0f;  // at image borders the pixel stands in for q
}

/// The smaller of the forward and backward steps that are usable (central pixel c).
bool pick_step(const Sample &c, const Sample &a, const Sample &b, glm::vec3 &step)
{
    glm::vec3 sa, sb;
    const bool ha = neighbour_step(c, a, sa), hb = neighbour_step(c, b, sb);
    if (ha && hb) {
        step = glm::dot(sa, sa) <= glm::dot(sb, sb) ? sa : sb;
    } else if (ha || hb) {
        step = ha ? sa : sb;
    }
    return ha || hb;
}

}  // namespace

using hatch_detail::KernelCtx;
using hatch_detail::LineTap;
#if POSTHASTE_HAVE_AVX2_TARGET
using hatch_detail::hatch_tile_avx2;
#endif

ToneCurve::ToneCurve(float gamma)
{
    for (int i = 0; i <= kSegments; ++i) {
        table_[std::size_t(i)] = std::pow(float(i) / float(kSegments), 2.0f / gamma);
    }
}

float hatch_tone(const float *rgba, int channels, const HatchSettings &s)
{
    return ToneCurve(s.gamma).tone(rgba, channels, s.exposure);
}

Image hatch(const HatchInputs &in, const HatchSettings &s, const Tam &tam)
{
    const Image &color = *in.color;
    const int w = color.width(), h = color.height(), nc = color.channels();
    assert(in.depth && in.normal && in.position);
    assert(in.depth->width() == w && in.normal->width() == w && in.position->width() == w);
    assert(s.ids.empty() || in.id);

    const bool outlines = s.outline_width > 0.0f;
    const float cos_thr = std::cos(s.normal_threshold_deg * kPiF / 180.0f);
    const float line_r = 0.5f * (s.outline_width - 1.0f);  // coverage = clamp(r + 1 - dist)
    const int line_reach = outlines ? std::max(0, int(std::ceil(line_r))) : 0;
    // Outline pen taps, kept where the coverage is positive.
    std::vector<LineTap> line_taps;
    for (int dy = -line_reach; outlines && dy <= line_reach; ++dy) {
        for (int dx = -line_reach; dx <= line_reach; ++dx) {
            const float c =
                std::clamp(line_r + 1.0f - std::sqrt(float(dx * dx + dy * dy)), 0.0f, 1.0f);
            if (c > 0.0f) {
                line_taps.push_back({dx, dy, c});
            }
        }
    }
    const glm::vec3 light = glm::normalize(s.light_dir);
    const ToneCurve curve(s.gamma);
    const float finest = float(tam.size());
    const float flat_lod = float(tam.levels() - 1);
    const float inv_scale = 1.0f / s.scale;
    const float lod_offset = std::log2(inv_scale * finest);  // log2 of texels per metre
    const Rect bounds = color.bounds();
    // Locals, not reads through `s`: stores to the output could alias them otherwise.
    const glm::vec3 paper = s.paper, ink_minus_paper = s.ink - s.paper, outline_color = s.outline;
    const float mix = s.mix, exposure = s.exposure;
    const bool partial_mix = s.mix < 1.0f, screen_space = s.screen_space;
    // Screen mode without outlines or light reads no geometry (sky and surfaces alike).
    const bool needs_samples = !s.screen_space || outlines || s.tone_from_light;

    Image out = Image::uninitialized(w, h, nc);
    // The AVX2 kernel covers every mode; mix 0 (a copy) stays on the scalar path.
    const bool use_avx2 = POSTHASTE_HAVE_AVX2_TARGET && simd::avx2() && mix > 0.0f;
    [[maybe_unused]] const KernelCtx kc{&color,
                                        in.depth,
                                        in.normal,
                                        in.position,
                                        &out,
                                        &tam,
                                        &curve,
                                        line_taps.data(),
                                        int(line_taps.size()),
                                        line_reach,
                                        screen_space,
                                        s.tone_from_light,
                                        partial_mix,
                                        needs_samples,
                                        s.depth_threshold,
                                        cos_thr,
                                        inv_scale,
                                        lod_offset,
                                        flat_lod,
                                        finest,
                                        s.ambient,
                                        exposure,
                                        mix,
                                        light,
                                        paper,
                                        ink_minus_paper,
                                        outline_color,
                                        s.triplanar,
                                        s.triplanar_sharpness,
                                        std::pow(0.0f, s.triplanar_sharpness),
                                        in.id,
                                        s.ids.empty() ? nullptr : &s.ids};
    for (int l = 0; l < tam.levels(); ++l) {  // the AVX2 kernel computes level offsets
        assert(int(tam.level_offset(l)) ==
               4 * (tam.size() * tam.size() - tam.level_size(l) * tam.level_size(l)) / 3);
    }
#if POSTHASTE_HAVE_AVX2_TARGET
    if (use_avx2) {
        // Wide, short tiles: each row of a tile is a long sequential read of every pass (64-pixel
        // rows are too short for the hardware prefetchers), and the tile's planes stay in L2.
        // The output of a pixel does not depend on the tile it falls in.
        constexpr int kTileW = 512, kTileH = 32;
        const int tiles_x = (w + kTileW - 1) / kTileW, tiles_y = (h + kTileH - 1) / kTileH;
        parallel_for(0, tiles_x * tiles_y, [&](int i) {
            const int tx = i % tiles_x, ty = i / tiles_x;
            const Rect t{tx * kTileW,
                         ty * kTileH,
                         std::min((tx + 1) * kTileW, w),
                         std::min((ty + 1) * kTileH, h)};
            hatch_tile_avx2(kc, t);
        });
        return out;
    }
#endif
    parallel_for_tiles(bounds, [&](const Rect &t) {
        // Tile-local copies: samples on the tile plus the outline reach plus one pixel (edges and
        // footprints look at 4-neighbours), edge flags on the tile plus the outline reach.
        const Rect re = t.expand(line_reach).intersect(bounds);
        const Rect rs = re.expand(1).intersect(bounds);
        const int sw = rs.width(), ew = re.width();
        thread_local std::vector<Sample> tls_samples;  // reused: no allocation per tile
        tls_samples.resize(std::size_t(sw) * std::size_t(rs.height()));
        Sample *const smp = tls_samples.data();
        if (needs_samples) {
            for (int y = rs.y0; y < rs.y1; ++y) {
                Sample *row = smp + std::size_t(y - rs.y0) * std::size_t(sw);
                const float *zr = in.depth->pixel(rs.x0, y), *pr = in.position->pixel(rs.x0, y);
                const float *nr = in.normal->pixel(rs.x0, y);
                const int zs = in.depth->channels(), ps = in.position->channels();
                const int ns = in.normal->channels();
                for (int i = 0; i < sw; ++i) {
                    row[i] = read_sample(zr + i * zs, pr + i * ps, nr + i * ns);
                }
            }
        }
        // Neighbours by index; at the image border the pixel stands in for the missing one
        // (never an edge with itself, and a zero step is no footprint).
        auto index = [&](int x, int y) {
            return std::size_t(y - rs.y0) * std::size_t(sw) + std::size_t(x - rs.x0);
        };
        struct Around {
            std::size_t c, l, r, u, d;
        };
        auto around = [&](int x, int y) {
            const std::size_t c = index(x, y);
            return Around{c,
                          x > rs.x0 ? c - 1 : c,
                          x + 1 < rs.x1 ? c + 1 : c,
                          y > rs.y0 ? c - std::size_t(sw) : c,
                          y + 1 < rs.y1 ? c + std::size_t(sw) : c};
        };
        thread_local std::vector<std::uint8_t> tls_edges;
        std::vector<std::uint8_t> &edges = tls_edges;
        if (outlines) {
            edges.assign(std::size_t(ew) * std::size_t(re.height()), 0);
            for (int y = re.y0; y < re.y1; ++y) {
                for (int x = re.x0; x < re.x1; ++x) {
                    const Around a = around(x, y);
                    const Sample &c = smp[a.c];
                    if (!c.hit) {
                        continue;
                    }
                    const float dt = s.depth_threshold;
                    const bool e = is_edge(c, smp[a.l], false, dt, cos_thr) ||
                                   is_edge(c, smp[a.r], true, dt, cos_thr) ||
                                   is_edge(c, smp[a.u], false, dt, cos_thr) ||
                                   is_edge(c, smp[a.d], true, dt, cos_thr);
                    edges[std::size_t(y - re.y0) * std::size_t(ew) + std::size_t(x - re.x0)] =
                        e ? 1 : 0;
                }
            }
        }
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float *src = color.pixel(x, y);
                float *dst = out.pixel(x, y);
                bool masked_in = true;
                if (!s.ids.empty()) {
                    const float id = in.id->at(x, y, 0);
                    masked_in =
                        std::find(s.ids.begin(),
                                  s.ids.end(),
                                  std::isfinite(id) ? int(std::lround(id)) : -1) != s.ids.end();
                }
                if (!masked_in || mix <= 0.0f) {
                    std::copy_n(src, nc, dst);
                    continue;
                }
                const Around a = around(x, y);
                const Sample &c = smp[a.c];
                float darkness = 0.0f;
                if (screen_space || c.hit) {  // surface mode: the sky is blank paper
                    const float tone =
                        s.tone_from_light
                            ? curve((s.ambient +
                                     (1.0f - s.ambient) *
                                         (c.normal ? std::max(0.0f, glm::dot(c.n, light)) : 1.0f)) *
                                    s.exposure)
                            : curve.tone(src, nc, exposure);
                    darkness = 1.0f - tone;
                }
                float ink = 0.0f;
                if (screen_space) {
                    ink = tam.ramp(
                        darkness, (float(x) + 0.5f) / finest, (float(y) + 0.5f) / finest, 0.0f);
                } else if (c.hit && !c.normal) {
                    ink = tam.ramp(darkness, 0.0f, 0.0f, flat_lod);  // flat mean tone, no strokes
                } else if (c.hit && darkness > 0.0f) {
                    glm::vec3 dpx, dpy;
                    const bool hx = pick_step(c, smp[a.r], smp[a.l], dpx);
                    const bool hy = pick_step(c, smp[a.d], smp[a.u], dpy);
                    if (!hx && hy) {
                        dpx = dpy;
                    }
                    if (!hy && hx) {
                        dpy = dpx;
                    }
                    const bool footprint = hx || hy;
                    // Planes: 0 = (z, y) for x-facing, 1 = (x, z) for y-facing, 2 = (x, y).
                    const glm::vec3 an = glm::abs(c.n);
                    float weight[3] = {0.0f, 0.0f, 0.0f};
                    if (s.triplanar) {
                        float sum = 0.0f;
                        for (int a = 0; a < 3; ++a) {
                            weight[a] =
                                std::pow(std::max(an[a] - 0.2f, 0.0f), s.triplanar_sharpness);
                            sum += weight[a];
                        }
                        for (float &wa : weight) {
                            wa /= sum;  // sum > 0: the largest |n| of a unit vector is >= 0.577
                        }
                    } else {
                        weight[an.x >= an.y && an.x >= an.z ? 0 : (an.y >= an.z ? 1 : 2)] = 1.0f;
                    }
                    static constexpr int kU[3] = {2, 0, 0}, kV[3] = {1, 2, 1};
                    for (int a = 0; a < 3; ++a) {
                        if (weight[a] <= 0.0f) {
                            continue;
                        }
                        const float u = c.p[kU[a]] * inv_scale, v = c.p[kV[a]] * inv_scale;
                        float lod = flat_lod;
                        if (footprint) {
                            const float ux = dpx[kU[a]], vx = dpx[kV[a]];
                            const float uy = dpy[kU[a]], vy = dpy[kV[a]];
                            const float len2 = std::max(ux * ux + vx * vx, uy * uy + vy * vy);
                            // log2(sqrt(len2) * texels per metre)
                            lod = 0.5f * fast_log2(std::max(len2, 1e-30f)) + lod_offset;
                        }
                        ink += weight[a] * tam.ramp(darkness, u, v, lod);
                    }
                }

                float line = 0.0f;
                for (const LineTap &tap : line_taps) {
                    const int xx = x + tap.dx, yy = y + tap.dy;
                    if (xx >= re.x0 && xx < re.x1 && yy >= re.y0 && yy < re.y1 &&
                        edges[std::size_t(yy - re.y0) * std::size_t(ew) +
                              std::size_t(xx - re.x0)]) {
                        line = std::max(line, tap.coverage);
                    }
                }

                const float alpha = nc >= 4 ? (finite_f(src[3]) ? src[3] : 1.0f) : 1.0f;
                for (int ch = 0; ch < 3; ++ch) {
                    float v = paper[ch] + ink * (ink_minus_paper[ch]);
                    v += line * (outline_color[ch] - v);
                    v *= alpha;
                    if (partial_mix) {
                        const float base = finite_f(src[ch]) ? src[ch] : v;
                        v = base + mix * (v - base);
                    }
                    dst[ch] = v;
                }
                if (nc >= 4) {
                    dst[3] = alpha;
                    for (int ch = 4; ch < nc; ++ch) {
                        dst[ch] = src[ch];
                    }
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
