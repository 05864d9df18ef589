#include "shading/dof_gather.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <vector>

#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

#include "core/hash.h"
#include "core/parallel.h"

namespace posthaste::shading {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr float kGoldenAngle = 2.39996323f;
constexpr float kTwoPi = 6.28318531f;
constexpr float kHalfMax = 65504.0f;  // largest half: what an EXR can hold anyway

float sanitize(float v)
{
    if (std::isnan(v)) {
        return 0.0f;
    }
    return std::clamp(v, -kHalfMax, kHalfMax);
}

// A regular n-gon inscribed in the unit circle: its boundary's distance from the centre in
// direction `angle` (relative to the blade rotation), in (cos(pi/n), 1].
float polygon_boundary(float angle, int blades)
{
    const float sector = kTwoPi / float(blades);
    float a = std::fmod(angle, sector);
    if (a < 0.0f) {
        a += sector;
    }
    return std::cos(0.5f * sector) / std::cos(a - 0.5f * sector);
}

// One resolution level of the gather's input: colour, signed CoC radius (in this level's
// pixels) and size.
struct Level {
    const glm::vec4 *color = nullptr;
    const float *coc = nullptr;
    int width = 0, height = 0;
};

struct Context {
    const DofSettings *settings = nullptr;
    std::vector<glm::vec2> dirs;  // unit golden-angle directions, one per sample index
    float rotation = 0.0f;        // blade rotation, radians
    float density = 3.0f;         // samples per R^2
};

// The two layers at one pixel: the near field in front of it (average colour and coverage
// alpha) and what lies behind (average colour). Composite: back (1 - alpha) + front alpha.
struct Layers {
    glm::vec4 front{0.0f};
    float alpha = 0.0f;
    glm::vec4 back{0.0f};

    glm::vec4 composite() const { return back * (1.0f - alpha) + front * alpha; }
};

// How much of a pixel at `distance` a CoC of `radius` covers: a one-pixel ramp centred on the
// rim, so a CoC under half a pixel reaches no neighbour.
inline float coverage(float radius, float distance)
{
    return std::clamp(radius - distance + 0.5f, 0.0f, 1.0f);
}

int sample_count(const Context &cx, float radius)
{
    const int max_samples = cx.settings->samples;
    const float n = std::ceil(cx.density * radius * radius);
    return std::clamp(int(std::min(n, 1e6f)), std::min(6, max_samples), max_samples);
}

// Sample i of n on the jittered spiral: pixel offset (ox, oy) and its shape-normalised
// distance from the centre (the CoC radius a point needs to reach the centre).
struct Spiral {
    const Context &cx;
    float radius, u, cj, sj, inv_n;

    float offset(int i, int &ox, int &oy) const
    {
        const glm::vec2 d0 = cx.dirs[std::size_t(i)];
        const float dx = d0.x * cj - d0.y * sj, dy = d0.x * sj + d0.y * cj;
        const float dist = radius * std::sqrt((float(i) + u) * inv_n);
        float shape = 1.0f;
        if (cx.settings->blades >= 3) {
            shape = polygon_boundary(std::atan2(dy, dx) - cx.rotation, cx.settings->blades);
        }
        ox = int(std::lrint(dist * shape * dx));
        oy = int(std::lrint(dist * shape * dy));
        // The distance of the pixel actually read (rounding moves it), shape-normalised.
        return std::sqrt(float(ox * ox + oy * oy)) / shape;
    }
};

Spiral make_spiral(const Context &cx, int x, int y, float radius, int n)
{
    const std::uint32_t seed = cx.settings->seed;
    const float phi = kTwoPi * hash_unit(x, y, 1, seed);
    return {cx, radius, hash_unit(x, y, 0, seed), std::cos(phi), std::sin(phi), 1.0f / float(n)};
}

// Baseline: a uniform disc (or polygon) of the pixel's own CoC, no depth test.
glm::vec4 gather_simple(const Context &cx, const Level &lv, int x, int y)
{
    const std::size_t ip = std::size_t(y) * std::size_t(lv.width) + std::size_t(x);
    const float radius = std::fabs(lv.coc[ip]);
    if (radius < 0.5f) {
        return lv.color[ip];
    }
    const int n = sample_count(cx, radius);
    const Spiral sp = make_spiral(cx, x, y, radius, n);
    glm::vec4 sum = lv.color[ip];
    for (int i = 0; i < n; ++i) {
        int ox, oy;
        sp.offset(i, ox, oy);
        const int qx = std::clamp(x + ox, 0, lv.width - 1);
        const int qy = std::clamp(y + oy, 0, lv.height - 1);
        sum += lv.color[std::size_t(qy) * std::size_t(lv.width) + std::size_t(qx)];
    }
    return sum / float(n + 1);
}

Layers gather_layers(const Context &cx, const Level &lv, int x, int y, float radius)
{
    const int w = lv.width, h = lv.height;
    const std::size_t ip = std::size_t(y) * std::size_t(w) + std::size_t(x);
    const float cp = lv.coc[ip];
    const float acp = std::fabs(cp);
    const int n = sample_count(cx, radius);
    const Spiral sp = make_spiral(cx, x, y, radius, n);

    const bool p_near = cp < -0.5f;
    // The pixel itself: part of the near layer when it is in the near field.
    const float w_self = 1.0f / std::max(cp * cp, 1.0f);
    glm::vec4 front(0.0f), back(0.0f);
    float front_w = 0.0f, back_w = 0.0f, alpha = 0.0f;
    if (p_near) {
        front = lv.color[ip] * w_self;
        front_w = w_self;
    }
    else {
        back = lv.color[ip] * w_self;
        back_w = w_self;
    }
    // Each sample stands for R^2 / n of the kernel's area (in units of the unit shape's area),
    // a near sample's footprint is |c_q|^2 of them: alpha = sum cov * (R^2 / n) / c_q^2.
    const float sample_area = radius * radius * sp.inv_n;
    for (int i = 0; i < n; ++i) {
        int ox, oy;
        const float dist = sp.offset(i, ox, oy);
        const int qx = std::clamp(x + ox, 0, w - 1);
        const int qy = std::clamp(y + oy, 0, h - 1);
        const std::size_t iq = std::size_t(qy) * std::size_t(w) + std::size_t(qx);
        const float cq = lv.coc[iq];
        const float acq = std::fabs(cq);
        if (cq < -0.5f && cq <= cp + 1.0f) {
            // Near field in front of p: spreads with its own CoC over whatever is behind.
            const float cov = coverage(acq, dist);
            const float inv_area = 1.0f / (acq * acq);
            front += lv.color[iq] * (cov * inv_area);
            front_w += cov * inv_area;
            alpha += cov * inv_area * sample_area;
        }
        else {
            // Behind p: limited by p's own CoC (a far field never bleeds over a sharper
            // foreground); seen through a near-field p, the background within p's disc shows.
            const float r_eff = cq > cp ? (p_near ? acp : std::min(acq, acp)) : acq;
            const float wgt = coverage(r_eff, dist) / std::max(r_eff * r_eff, 1.0f);
            back += lv.color[iq] * wgt;
            back_w += wgt;
        }
    }
    Layers l;
    if (front_w > 0.0f) {
        l.front = front / front_w;
        l.alpha = std::min(alpha, 1.0f);
    }
    if (back_w > 0.0f) {
        l.back = back / back_w;
    }
    else {
        l.back = l.front;
        l.alpha = 1.0f;
    }
    return l;
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
    const glm::vec4 bg = full.color[ip] * (1.0f - sharp) + back * (sharp / back_w);
    return bg * (1.0f - alpha) + front;
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
    const float max_radius = 0.5f * std::max(settings.max_coc_px, 0.0f);
    CocField field = compute_coc(depth, lens, max_radius);
    tm.coc_ms = ms_since(t0);
    t0 = Clock::now();
    reduce_tiles(field);
    tm.tiles_ms = ms_since(t0);
    if (field.max_radius < 0.5f) {
        if (times) {
            *times = tm;
        }
        return false;
    }

    t0 = Clock::now();
    const int w = color.width(), h = color.height(), nc = color.channels();
    std::vector<glm::vec4> col(color.pixel_count());
    parallel_for_tiles(color.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float *p = color.pixel(x, y);
                glm::vec4 v(0.0f);
                for (int k = 0; k < std::min(nc, 4); ++k) {
                    v[k] = sanitize(p[k]);
                }
                col[std::size_t(y) * std::size_t(w) + std::size_t(x)] = v;
            }
        }
    });
    tm.coc_ms += ms_since(t0);

    Context cx;
    cx.settings = &settings;
    cx.density = settings.density;
    cx.rotation = settings.rotation_deg * (kTwoPi / 360.0f);
    cx.dirs.resize(std::size_t(std::max(settings.samples, 1)));
    for (std::size_t i = 0; i < cx.dirs.size(); ++i) {
        const float a = kGoldenAngle * float(i);
        cx.dirs[i] = {std::cos(a), std::sin(a)};
    }
    const Level full{col.data(), field.radius.data(), w, h};
    const bool simple = settings.method == DofMethod::Simple;
    const bool half = settings.half_res && !simple;
    const auto tile_radius = [&](int x, int y) {
        return field.gather[std::size_t((y / field.tile) * field.tiles_x + x / field.tile)];
    };

    // Half resolution: each 2x2 block keeps its nearest CoC (halved) and the mean colour of the
    // pixels within one pixel of CoC of it, so a block straddling a depth edge stays on the
    // near side; then gather both layers there.
    const int w2 = (w + 1) / 2, h2 = (h + 1) / 2;
    std::vector<glm::vec4> col2, back2, front2;  // front2: premultiplied by alpha
    std::vector<float> coc2, alpha2;
    if (half) {
        t0 = Clock::now();
        col2.resize(std::size_t(w2) * std::size_t(h2));
        coc2.resize(col2.size());
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
                                sum += col[i];
                                cnt += 1.0f;
                            }
                        }
                    }
                    const std::size_t o = std::size_t(y) * w2 + x;
                    col2[o] = sum / cnt;
                    coc2[o] = 0.5f * cmin;
                }
            }
        });
        tm.coc_ms += ms_since(t0);

        t0 = Clock::now();
        const Level lv{col2.data(), coc2.data(), w2, h2};
        back2.resize(col2.size());
        front2.resize(col2.size());
        alpha2.resize(col2.size());
        Context cx2 = cx;
        cx2.density = settings.half_density;
        parallel_for_tiles(
            Rect{0, 0, w2, h2},
            [&](const Rect &t) {
                const float radius = 0.5f * tile_radius(2 * t.x0, 2 * t.y0);
                for (int y = t.y0; y < t.y1; ++y) {
                    for (int x = t.x0; x < t.x1; ++x) {
                        const std::size_t o = std::size_t(y) * w2 + x;
                        Layers l;
                        if (radius < 0.5f) {
                            l.back = col2[o];
                        }
                        else {
                            l = gather_layers(cx2, lv, x, y, std::max(radius, 0.5f));
                        }
                        back2[o] = l.back;
                        front2[o] = l.front * l.alpha;
                        alpha2[o] = l.alpha;
                    }
                }
            },
            field.tile / 2);
        tm.gather_ms += ms_since(t0);
    }

    // Full resolution: copy in-focus tiles, gather small-CoC tiles here, and composite the
    // half-resolution layers elsewhere.
    t0 = Clock::now();
    out = Image::uninitialized(w, h, nc);
    std::vector<std::uint8_t> gathered(std::size_t(field.tiles_x * field.tiles_y), 0);
    parallel_for_tiles(
        color.bounds(),
        [&](const Rect &t) {
            const int ti = (t.y0 / field.tile) * field.tiles_x + t.x0 / field.tile;
            const float radius = field.gather[std::size_t(ti)];
            const bool copy = radius < 0.5f && !simple;
            const bool use_half = half && radius >= settings.half_min_radius;
            gathered[std::size_t(ti)] = copy ? 0 : 1;
            for (int y = t.y0; y < t.y1; ++y) {
                for (int x = t.x0; x < t.x1; ++x) {
                    const std::size_t ip = std::size_t(y) * std::size_t(w) + std::size_t(x);
                    glm::vec4 v;
                    if (copy) {
                        v = col[ip];
                    }
                    else if (simple) {
                        v = gather_simple(cx, full, x, y);
                    }
                    else if (use_half) {
                        v = composite_half(full, x, y, w2, h2, coc2, back2, front2, alpha2);
                    }
                    else {
                        v = gather_layers(cx, full, x, y, radius).composite();
                    }
                    float *o = out.pixel(x, y);
                    for (int k = 0; k < nc; ++k) {
                        // Channels past the fourth pass through (sanitised).
                        o[k] = k < 4 ? v[k] : sanitize(color.pixel(x, y)[k]);
                    }
                }
            }
        },
        field.tile);
    tm.composite_ms = ms_since(t0);
    for (std::uint8_t g : gathered) {
        (g ? tm.tiles_gathered : tm.tiles_copied) += 1;
    }
    if (times) {
        *times = tm;
    }
    return true;
}

}  // namespace posthaste::shading
