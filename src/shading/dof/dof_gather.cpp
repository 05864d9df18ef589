#include "shading/dof/dof_gather.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <memory>
#include <new>
#include <vector>

#include "core/hash.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/timing.h"
#include "shading/dof/dof_kernels.h"
#include "shading/dof/dof_patterns.h"
#include "shading/tiles.h"

namespace posthaste::shading {
namespace {

using Clock = std::chrono::steady_clock;

// One resolution level of the gather's input, as planes (structure of arrays, so that eight
// horizontally adjacent pixels are one contiguous load): colour channels, signed CoC radius (in
// this level's pixels), 1 / CoC^2 (+inf at 0: the near field's footprint and, clamped to 1, the
// background's) and size.
struct Level : dof::PlanesView {
    glm::vec4 color(std::size_t i) const { return {ch[0][i], ch[1][i], ch[2][i], ch[3][i]}; }
};

// Storage behind a Level: four colour planes and the 1 / CoC^2 plane (the CoC plane is the
// caller's).
struct Planes {
    ScratchArray<float> data;
    std::size_t n = 0;

    // All written by the caller. A large frame's planes (40 MB at 1080p) come from the scratch
    // pool (core/memory.h): kept between frames, in 2 MB pages where the system has them, so
    // touching them costs neither a page clear nor a fault per 4 KiB.
    void allocate(std::size_t pixels)
    {
        n = pixels;
        data = scratch_array<float>(5 * pixels);
    }
    float *channel(int k) { return data.get() + std::size_t(k) * n; }
    float *inv2() { return data.get() + 4 * n; }
    Level level(const float *coc, int w, int h)
    {
        Level lv;
        for (int k = 0; k < 4; ++k) {
            lv.ch[k] = channel(k);
        }
        lv.coc = coc;
        lv.inv2 = inv2();
        lv.width = w;
        lv.height = h;
        return lv;
    }
};

using dof::Patterns;
using dof::Tap;

struct Context {
    const DofSettings *settings = nullptr;
    float density = 8.0f;  ///< Samples per R^2 of this level's patterns.
    Patterns patterns;
};

inline int variant_of(const Context &cx, int x, int y, std::uint32_t which)
{
    return int(hash4(std::uint32_t(x),
                     std::uint32_t(y + cx.settings->jitter_y0),
                     which,
                     cx.settings->seed) >>
               28);
}

// The two layers at one pixel: the near field in front of it (average colour and coverage
// alpha) and what lies behind (average colour). Composite: back (1 - alpha) + front alpha.
struct Layers {
    glm::vec4 front{0.0f};
    float alpha = 0.0f;
    glm::vec4 back{0.0f};

    glm::vec4 composite() const { return back * (1.0f - alpha) + front * alpha; }
};

// Baseline: a uniform disc (or polygon) of the pixel's own CoC, no depth test.
glm::vec4 gather_simple(const Context &cx, const Level &lv, int x, int y)
{
    const std::size_t ip = std::size_t(y) * std::size_t(lv.width) + std::size_t(x);
    const float radius = std::fabs(lv.coc[ip]);
    if (radius < 0.5f) {
        return lv.color(ip);
    }
    const int k = cx.patterns.level(radius);
    const int n = cx.patterns.count(k);
    const Tap *taps = cx.patterns.taps(k, variant_of(cx, x + cx.settings->jitter_x0, y, 0));
    glm::vec4 sum = lv.color(ip);
    for (int i = 0; i < n; ++i) {
        const int qx = std::clamp(x + taps[i].dx, 0, lv.width - 1);
        const int qy = std::clamp(y + taps[i].dy, 0, lv.height - 1);
        sum += lv.color(std::size_t(qy) * std::size_t(lv.width) + std::size_t(qx));
    }
    return sum / float(n + 1);
}

// Blur under three quarters of a pixel. A CoC of radius r < 0.5 px reaches no neighbour's
// centre, yet the lens spreads the pixel by a disc of variance r^2 / 4 per axis: a highlight on
// a surface just off the focus plane loses a tenth of its peak to its neighbours (the Cycles
// set's sun glint at r = 0.49, docs/ACCURACY.md). The gather's taps weigh a neighbour by the
// disc's overlap with a pixel-wide edge, which is not that variance until the disc covers the
// neighbours' centres well: one bright pixel gathered at r = 0.52 spreads by 0.15 of the disc's
// variance, at 0.6 by 0.51, at 0.75 by 0.72, from 0.76 on by 0.85-1.17 (measured on an impulse,
// docs/nodes/dof.md). So the background of a pixel with r under kStencilMax takes the
// 4-neighbour stencil (1 - 4a, a) with a = r^2 / 8 instead, which adds exactly the disc's
// variance (its frequency response is the disc's to second order): deterministic, no jittered
// taps. Gather form, the pixel's own radius. A pixel in the near field (in front of the focus
// plane, r >= 0.5) keeps the gather, which its own layer needs. Below kSubPixelMin the change is
// under 5e-4 of the local contrast and the pixel is left as it is. Adds the blur of row y (its
// colour less `subtract`, as the planes hold it) to `dst`.
constexpr float kSubPixelMin = 0.0625f;
constexpr float kStencilMax = 0.75f;

/// Whether a pixel of signed CoC radius c takes the stencil (its background is not gathered).
inline bool takes_stencil(float c)
{
    const float r = std::fabs(c);
    return r >= kSubPixelMin && (r < 0.5f || (c > 0.0f && c < kStencilMax));
}

// Near/far gather over a group of up to eight horizontally adjacent pixels (x0 .. x0 + 7, y) that
// share their tap offsets, so that the vector path reads each tap as one contiguous load of eight
// pixels per plane. Per pixel p with signed radius c_p:
// - the near field (samples q in front of p and of the focus plane) can reach p from as far as
//   the tile neighbourhood's largest near CoC, `near_radius`, and is gathered over that (one
//   spiral for the whole group): it spreads with its own CoC and gives a coverage alpha
//   sum cov (R^2 / n) / c_q^2;
// - the background (everything else) only reaches p within p's own CoC (weights use
//   min(|c_q|, |c_p|) behind p, and |c_q| < |c_p| in front), so it is gathered over a spiral of
//   about |c_p|: the group's pixels are served largest radius first, each pass taking every
//   pixel for which the pass's spiral puts at least 3/4 of the samples that its own radius would
//   get inside its own disc (a pixel outside a sample's reach gets a zero weight from it, so a
//   larger spiral only costs density). Pixels under half a pixel, or whose near field already
//   covers the lens (alpha >= 1: the composite would weigh the background by 0), skip it.
// The spiral variant is hashed from (group, y), so the result does not depend on the thread
// count. Every target sums each pixel's taps in the same order; targets differ only in rounding.
// The group kernels (setup, near pass, background pass, composite, and the rows between the
// interleaved image and the planes) are in dof_kernels.cpp, written once over Highway.
using dof::Group;
using dof::kLanes;
using dof::merge_row;
using dof::split_row;

// Gathers both layers of the pixels x0 .. x0 + 7 of row y (x0 a multiple of 8; lanes from
// `count` on are past the row's end) into g; returns the near samples' area (for alpha).
float gather_group(
    const Context &cx, const Level &lv, int x0, int y, int count, float near_radius, Group &g)
{
    dof::setup_group(lv, x0, y, count, g);
    const int group = (x0 + cx.settings->jitter_x0) / kLanes;
    float sample_area = 0.0f;
    if (near_radius >= 0.5f) {
        const int k = cx.patterns.level(near_radius);
        const int n = cx.patterns.count(k);
        const float r = cx.patterns.radius(k);
        // Each sample stands for R^2 / n of the kernel's area (in units of the unit shape's
        // area), a near sample's footprint is |c_q|^2 of them.
        sample_area = r * r / float(n);
        dof::near_pass(lv, x0, y, cx.patterns.taps(k, variant_of(cx, group, y, 1)), n, g);
    }
    unsigned remaining = 0;
    for (int j = 0; j < count; ++j) {
        // A background pixel under kStencilMax has its blur from add_sub_pixel_blur.
        if ((g.cp[j] <= -0.5f || g.cp[j] >= kStencilMax) && g.near_w[j] * sample_area < 1.0f) {
            remaining |= 1u << j;
        }
    }
    if (remaining == 0) {
        return sample_area;
    }
    const int variant = variant_of(cx, group, y, 0);
    const int cap = std::max(cx.settings->samples, 1);
    while (remaining != 0) {
        int top = 0;
        float top_r = -1.0f;
        for (int j = 0; j < kLanes; ++j) {
            if (((remaining >> j) & 1u) && g.acp[j] > top_r) {
                top = j;
                top_r = g.acp[j];
            }
        }
        const int k = cx.patterns.level(top_r);
        const int n = cx.patterns.count(k);
        const float r = cx.patterns.radius(k);
        unsigned lanes = 1u << top;
        for (int j = 0; j < kLanes; ++j) {
            if ((remaining >> j) & 1u) {
                const float a2 = g.acp[j] * g.acp[j];
                const float own =
                    std::clamp(std::ceil(cx.density * a2), float(std::min(6, cap)), float(cap));
                if (float(n) * a2 >= 0.75f * own * r * r) {
                    lanes |= 1u << j;
                }
            }
        }
        dof::back_pass(lv,
                       x0,
                       y,
                       cx.patterns.taps(k, variant),
                       cx.patterns.offsets(k, variant),
                       n,
                       cx.patterns.reach(k),
                       lanes,
                       g);
        remaining &= ~lanes;
    }
    return sample_area;
}

// The two layers of each of the first `count` lanes (the half-resolution path keeps them apart).
void layers_of(const Group &g, float sample_area, int count, Layers *out)
{
    for (int j = 0; j < count; ++j) {
        Layers &l = out[j];
        l = Layers{};
        if (g.front_w[j] > 0.0f) {
            const float inv = 1.0f / g.front_w[j];
            l.front = glm::vec4(g.front[0][j], g.front[1][j], g.front[2][j], g.front[3][j]) * inv;
            l.alpha = std::min(g.near_w[j] * sample_area, 1.0f);
        }
        if (g.back_w[j] > 0.0f) {
            const float inv = 1.0f / g.back_w[j];
            l.back = glm::vec4(g.back[0][j], g.back[1][j], g.back[2][j], g.back[3][j]) * inv;
        } else {
            l.back = l.front;
            l.alpha = 1.0f;
        }
    }
}

// Full-resolution pixel from the half-resolution layers: the background is upsampled with
// bilinear weights damped by CoC difference (so a sharp edge's colour does not leak into the
// blurred side), blended with the sharp pixel by its own CoC, then the near layer goes over.
glm::vec4 composite_half(const Level &full,
                         int x,
                         int y,
                         int w2,
                         int h2,
                         const std::vector<float> &coc2,
                         const std::vector<glm::vec4> &back2,
                         const std::vector<glm::vec4> &front2,
                         const std::vector<float> &alpha2)
{
    const std::size_t ip = std::size_t(y) * std::size_t(full.width) + std::size_t(x);
    const float cp = full.coc[ip];
    const float fx = 0.5f * (float(x) + 0.5f) - 0.5f, fy = 0.5f * (float(y) + 0.5f) - 0.5f;
    const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
    const float tx = fx - float(x0), ty = fy - float(y0);
    glm::vec4 back(0.0f), front(0.0f);
    float back_w = 0.0f, alpha = 0.0f;
    for (int j = 0; j < 4; ++j) {
        const int qx = std::clamp(x0 + (j & 1), 0, w2 - 1);
        const int qy = std::clamp(y0 + (j >> 1), 0, h2 - 1);
        const float bw = ((j & 1) ? tx : 1.0f - tx) * ((j >> 1) ? ty : 1.0f - ty);
        const std::size_t q = std::size_t(qy) * std::size_t(w2) + std::size_t(qx);
        const float wb = bw / (1.0f + std::fabs(2.0f * coc2[q] - cp));
        back += back2[q] * wb;
        back_w += wb;
        front += front2[q] * bw;
        alpha += alpha2[q] * bw;
    }
    const float sharp = std::clamp(std::fabs(cp) - 0.5f, 0.0f, 1.0f);
    const glm::vec4 bg = full.color(ip) * (1.0f - sharp) + back * (sharp / back_w);
    return bg * (1.0f - alpha) + front;
}

void add_sub_pixel_blur(
    const Image &color, const DofSettings &st, const float *radius, int y, float *const *dst)
{
    const int w = color.width(), h = color.height(), nc = std::min(color.channels(), 4);
    const Image *sub = st.subtract;
    const auto value = [&](int x, int yy, int k) {
        float v = color.pixel(x, yy)[k];
        if (sub && k < 3 && yy >= st.subtract_y0 && yy < st.subtract_y0 + sub->height() &&
            x >= st.subtract_x0 && x < st.subtract_x0 + sub->width()) {
            v -= sub->pixel(x - st.subtract_x0, yy - st.subtract_y0)[k];
        }
        // Non-finite values as 0, as the planes read them (dof::split_row).
        return std::fabs(v) <= std::numeric_limits<float>::max() ? v : 0.0f;
    };
    const int ym = std::max(y - 1, 0), yp = std::min(y + 1, h - 1);
    // Without a lighting split the pixels are read straight from the rows (the same values).
    const int cs = color.channels();
    const float *row = color.pixel(0, y), *up = color.pixel(0, ym), *down = color.pixel(0, yp);
    const auto finite = [](float v) {
        return std::fabs(v) <= std::numeric_limits<float>::max() ? v : 0.0f;
    };
    for (int x = 0; x < w; ++x) {
        if (!takes_stencil(radius[x])) {
            continue;
        }
        const float r = std::fabs(radius[x]);
        const float a = 0.125f * r * r;
        const int xm = std::max(x - 1, 0), xp = std::min(x + 1, w - 1);
        if (!sub) {
            const std::size_t i = std::size_t(x) * std::size_t(cs);
            const std::size_t im = std::size_t(xm) * std::size_t(cs),
                              ip = std::size_t(xp) * std::size_t(cs);
            for (int k = 0; k < nc; ++k) {
                const float c = finite(row[i + std::size_t(k)]);
                const float around =
                    (finite(row[im + std::size_t(k)]) + finite(row[ip + std::size_t(k)])) +
                    (finite(up[i + std::size_t(k)]) + finite(down[i + std::size_t(k)]));
                dst[k][x] = c + a * (around - 4.0f * c);
            }
            continue;
        }
        for (int k = 0; k < nc; ++k) {
            const float c = value(x, y, k);
            const float around =
                (value(xm, y, k) + value(xp, y, k)) + (value(x, ym, k) + value(x, yp, k));
            dst[k][x] = c + a * (around - 4.0f * c);
        }
    }
}

}  // namespace

bool apply_dof(const Image &color,
               const Image &depth,
               const DofLens &lens,
               const DofSettings &settings,
               Image &out,
               DofTimes *times)
{
    DofTimes tm;
    auto t0 = Clock::now();
    double c0 = process_cpu_ms();
    const float max_radius = 0.5f * std::max(settings.max_coc_px, 0.0f);
    CocField field = compute_coc(depth, lens, max_radius);
    tm.coc_ms = ms_since(t0);
    tm.coc_cpu_ms = process_cpu_ms() - c0;
    t0 = Clock::now();
    c0 = process_cpu_ms();
    reduce_tiles(field);
    tm.tiles_ms = ms_since(t0);
    tm.tiles_cpu_ms = process_cpu_ms() - c0;
    // The simple method (the seeds' baseline) leaves every CoC under half a pixel alone.
    if (field.max_radius < (settings.method == DofMethod::Simple ? 0.5f : kSubPixelMin)) {
        if (times) {
            *times = tm;
        }
        return false;
    }

    t0 = Clock::now();
    c0 = process_cpu_ms();
    const int w = color.width(), h = color.height(), nc = color.channels();
    Planes planes;
    planes.allocate(color.pixel_count());
    float *const plane[4] = {
        planes.channel(0), planes.channel(1), planes.channel(2), planes.channel(3)};
    // Whole rows: the split is bandwidth-bound, and a 64-pixel tile row is too short for the
    // hardware prefetcher (docs/ARCHITECTURE.md, "Speed").
    parallel_for(0, h, [&](int y) {
        const std::size_t row = std::size_t(y) * std::size_t(w);
        float *const dst[4] = {plane[0] + row, plane[1] + row, plane[2] + row, plane[3] + row};
        split_row(color.pixel(0, y), nc, 0, w, dst);
        const float *c = field.radius.data() + row;
        float *inv2 = planes.inv2() + row;
        for (int x = 0; x < w; ++x) {
            inv2[x] = 1.0f / (c[x] * c[x]);  // +inf at 0
        }
        // The lighting split's rest: colour less the share, in the planes every path reads.
        const Image *sub = settings.subtract;
        if (sub && nc >= 3 && y >= settings.subtract_y0 &&
            y < settings.subtract_y0 + sub->height()) {
            const int x0 = std::max(settings.subtract_x0, 0),
                      x1 = std::min(settings.subtract_x0 + sub->width(), w);
            const int sc = sub->channels();
            const float *src = sub->pixel(x0 - settings.subtract_x0, y - settings.subtract_y0);
            for (int x = x0; x < x1; ++x, src += sc) {
                dst[0][x] -= src[0];
                dst[1][x] -= src[1];
                dst[2][x] -= src[2];
            }
        }
        if (settings.method == DofMethod::Gather) {
            add_sub_pixel_blur(color, settings, c, y, dst);
        }
    });

    Context cx;
    cx.settings = &settings;
    cx.density = settings.density;
    cx.patterns.build(field.max_radius, settings, settings.density, w);
    tm.coc_ms += ms_since(t0);
    tm.coc_cpu_ms += process_cpu_ms() - c0;
    const Level full = planes.level(field.radius.data(), w, h);
    const bool simple = settings.method == DofMethod::Simple;
    const bool half = settings.half_res && !simple;
    const auto tile_of = [&](int x, int y) {
        return std::size_t((y / field.tile) * field.tiles_x + x / field.tile);
    };

    // Half resolution: each 2x2 block keeps its nearest CoC (halved) and the mean colour of the
    // pixels within one pixel of CoC of it, so a block straddling a depth edge stays on the
    // near side; then gather both layers there.
    const int w2 = (w + 1) / 2, h2 = (h + 1) / 2;
    Planes planes2;
    std::vector<glm::vec4> back2, front2;  // front2: premultiplied by alpha
    std::vector<float> coc2, alpha2;
    if (half) {
        t0 = Clock::now();
        c0 = process_cpu_ms();
        planes2.allocate(std::size_t(w2) * std::size_t(h2));
        coc2.resize(planes2.n);
        parallel_for_tiles(Rect{0, 0, w2, h2}, [&](const Rect &t) {
            for (int y = t.y0; y < t.y1; ++y) {
                for (int x = t.x0; x < t.x1; ++x) {
                    const int x0 = 2 * x, y0 = 2 * y;
                    const int x1 = std::min(x0 + 2, w), y1 = std::min(y0 + 2, h);
                    float cmin = std::numeric_limits<float>::infinity();
                    for (int yy = y0; yy < y1; ++yy) {
                        for (int xx = x0; xx < x1; ++xx) {
                            cmin = std::min(cmin, full.coc[std::size_t(yy) * w + xx]);
                        }
                    }
                    glm::vec4 sum(0.0f);
                    float cnt = 0.0f;
                    for (int yy = y0; yy < y1; ++yy) {
                        for (int xx = x0; xx < x1; ++xx) {
                            const std::size_t i = std::size_t(yy) * w + xx;
                            if (full.coc[i] <= cmin + 1.0f) {
                                sum += full.color(i);
                                cnt += 1.0f;
                            }
                        }
                    }
                    const std::size_t o = std::size_t(y) * w2 + x;
                    for (int k = 0; k < 4; ++k) {
                        planes2.channel(k)[o] = sum[k] / cnt;
                    }
                    coc2[o] = 0.5f * cmin;
                    planes2.inv2()[o] = 1.0f / (coc2[o] * coc2[o]);
                }
            }
        });
        tm.coc_ms += ms_since(t0);
        tm.coc_cpu_ms += process_cpu_ms() - c0;

        t0 = Clock::now();
        c0 = process_cpu_ms();
        const Level lv = planes2.level(coc2.data(), w2, h2);
        back2.resize(planes2.n);
        front2.resize(planes2.n);
        alpha2.resize(planes2.n);
        Context cx2;
        cx2.settings = &settings;
        cx2.density = settings.half_density;
        cx2.patterns.build(0.5f * field.max_radius, settings, settings.half_density, w2);
        parallel_for_tiles(
            Rect{0, 0, w2, h2},
            [&](const Rect &t) {
                const float radius = 0.5f * field.gather[tile_of(2 * t.x0, 2 * t.y0)];
                const float near_radius = 0.5f * field.near_gather[tile_of(2 * t.x0, 2 * t.y0)];
                for (int y = t.y0; y < t.y1; ++y) {
                    for (int x0 = t.x0; x0 < t.x1; x0 += kLanes) {
                        const int count = std::min(kLanes, t.x1 - x0);
                        Layers l[kLanes];
                        if (radius < 0.5f) {
                            for (int j = 0; j < count; ++j) {
                                l[j].back = lv.color(std::size_t(y) * w2 + std::size_t(x0 + j));
                            }
                        } else {
                            Group g;
                            const float area = gather_group(cx2, lv, x0, y, count, near_radius, g);
                            layers_of(g, area, count, l);
                        }
                        for (int j = 0; j < count; ++j) {
                            const std::size_t o = std::size_t(y) * w2 + std::size_t(x0 + j);
                            back2[o] = l[j].back;
                            front2[o] = l[j].front * l[j].alpha;
                            alpha2[o] = l[j].alpha;
                        }
                    }
                }
            },
            field.tile / 2);
        tm.gather_ms += ms_since(t0);
        tm.gather_cpu_ms += process_cpu_ms() - c0;
    }

    // Full resolution: copy in-focus tiles, gather small-CoC tiles here, and composite the
    // half-resolution layers elsewhere.
    t0 = Clock::now();
    c0 = process_cpu_ms();
    out = Image::uninitialized(w, h, nc);
    std::vector<std::uint8_t> gathered(std::size_t(field.tiles_x * field.tiles_y), 0);
    // skip_empty: a tile whose gather radius reaches no non-zero colour gathers zeros; copied.
    std::vector<std::uint8_t> in_reach;
    if (settings.skip_empty && !simple) {
        in_reach = tiles_in_reach(
            occupied_tiles(plane, w, h, field.tile),
            field.tiles_x,
            field.tiles_y,
            [&](std::size_t t) { return int(std::ceil(field.gather[t] / float(field.tile))) + 1; });
    }
    parallel_for_tiles(
        color.bounds(),
        [&](const Rect &t) {
            const int ti = (t.y0 / field.tile) * field.tiles_x + t.x0 / field.tile;
            const float radius = field.gather[std::size_t(ti)];
            const float near_radius = field.near_gather[std::size_t(ti)];
            const bool copy =
                (radius < 0.5f || (!in_reach.empty() && !in_reach[std::size_t(ti)])) && !simple;
            const bool use_half = half && radius >= settings.half_min_radius;
            gathered[std::size_t(ti)] = copy ? 0 : 1;
            for (int y = t.y0; y < t.y1; ++y) {
                for (int x0 = t.x0; x0 < t.x1; x0 += kLanes) {
                    const int count = std::min(kLanes, t.x1 - x0);
                    float v[4][kLanes];
                    if (!copy && !simple && !use_half) {
                        Group g;
                        const float area = gather_group(cx, full, x0, y, count, near_radius, g);
                        dof::composite_group(g, area, v);
                    } else {
                        for (int j = 0; j < count; ++j) {
                            const int x = x0 + j;
                            glm::vec4 c;
                            if (copy) {
                                c = full.color(std::size_t(y) * std::size_t(w) + std::size_t(x));
                            } else if (simple) {
                                c = gather_simple(cx, full, x, y);
                            } else {
                                c = composite_half(full, x, y, w2, h2, coc2, back2, front2, alpha2);
                            }
                            for (int k = 0; k < 4; ++k) {
                                v[k][j] = c[k];
                            }
                        }
                    }
                    merge_row(v, count, nc, out.pixel(x0, y));
                }
            }
        },
        field.tile);
    tm.composite_ms = ms_since(t0);
    tm.composite_cpu_ms = process_cpu_ms() - c0;
    for (std::uint8_t g : gathered) {
        (g ? tm.tiles_gathered : tm.tiles_copied) += 1;
    }
    if (times) {
        *times = tm;
    }
    return true;
}

}  // namespace posthaste::shading
