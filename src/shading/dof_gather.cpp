#include "shading/dof_gather.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ctime>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <memory>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"

namespace posthaste::shading {
namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

// CPU time of the whole process (every thread), ms: on a shared machine the wall time of a pass
// depends on other load, its CPU time much less.
double process_cpu_ms()
{
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

constexpr float kGoldenAngle = 2.39996323f;
constexpr float kTwoPi = 6.28318531f;

// Non-finite colour (NaN, +-Inf) reads as 0: spreading an Inf, or even the largest half, over
// a disc would turn one bad pixel into a bright blot.
inline float sanitize(float v)
{
    return std::fabs(v) <= std::numeric_limits<float>::max() ? v : 0.0f;
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

// Sample patterns, precomputed per quantised gather radius: kVariants rotated and radially
// jittered golden-angle spirals of n = clamp(density R^2) taps (disc, or polygon by the blade
// shape), each tap an integer pixel offset and the shape-normalised distance of the pixel it
// reads. A pixel picks its variant by hash(x, y), so the noise is the same for any thread count.
constexpr int kVariants = 16;

struct Tap {
    std::int16_t dx, dy;
    float dist;
};

class Patterns {
   public:
    void build(float max_radius, const DofSettings &st, float density)
    {
        radii_.clear();
        for (float r = 0.25f;; r += std::max(0.25f, r / 32.0f)) {
            radii_.push_back(r);
            if (r >= max_radius) {
                break;
            }
        }
        const int cap = std::max(st.samples, 1);
        n_.resize(radii_.size());
        start_.resize(radii_.size());
        std::size_t total = 0;
        for (std::size_t k = 0; k < radii_.size(); ++k) {
            const float r = radii_[k];
            const float n = std::min(std::ceil(density * r * r), 1e6f);
            n_[k] = std::clamp(int(n), std::min(6, cap), cap);
            start_[k] = total;
            total += std::size_t(n_[k]) * kVariants;
        }
        taps_.resize(total);
        const float rotation = st.rotation_deg * (kTwoPi / 360.0f);
        parallel_for(0, int(radii_.size()), [&](int k) {
            const float r = radii_[std::size_t(k)];
            const int n = n_[std::size_t(k)];
            for (int v = 0; v < kVariants; ++v) {
                const float u = (float(v) + 0.5f) / float(kVariants);
                const float phi = kTwoPi * std::fmod(float(v) * 0.618034f, 1.0f);
                Tap *t = taps_.data() + start_[std::size_t(k)] + std::size_t(v * n);
                for (int i = 0; i < n; ++i) {
                    const float a = kGoldenAngle * float(i) + phi;
                    const float dx = std::cos(a), dy = std::sin(a);
                    const float dist = r * std::sqrt((float(i) + u) / float(n));
                    const float shape =
                        st.blades >= 3 ? polygon_boundary(a - rotation, st.blades) : 1.0f;
                    const int ox = int(std::lrint(dist * shape * dx));
                    const int oy = int(std::lrint(dist * shape * dy));
                    t[i].dx = std::int16_t(std::clamp(ox, -32767, 32767));
                    t[i].dy = std::int16_t(std::clamp(oy, -32767, 32767));
                    t[i].dist = std::sqrt(float(ox * ox + oy * oy)) / shape;
                }
            }
        });
    }
    /// The smallest quantised radius >= r (or the largest there is).
    int level(float r) const
    {
        const auto it = std::lower_bound(radii_.begin(), radii_.end(), r);
        return it == radii_.end() ? int(radii_.size()) - 1 : int(it - radii_.begin());
    }
    float radius(int k) const { return radii_[std::size_t(k)]; }
    int count(int k) const { return n_[std::size_t(k)]; }
    const Tap *taps(int k, int variant) const
    {
        return taps_.data() + start_[std::size_t(k)] + std::size_t(variant * n_[std::size_t(k)]);
    }

   private:
    std::vector<float> radii_;
    std::vector<int> n_;
    std::vector<std::size_t> start_;
    std::vector<Tap> taps_;
};

struct Context {
    const DofSettings *settings = nullptr;
    Patterns patterns;
};

inline int variant_of(const Context &cx, int x, int y, std::uint32_t which)
{
    return int(hash4(std::uint32_t(x), std::uint32_t(y), which, cx.settings->seed) >> 28);
}

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

// Baseline: a uniform disc (or polygon) of the pixel's own CoC, no depth test.
glm::vec4 gather_simple(const Context &cx, const Level &lv, int x, int y)
{
    const std::size_t ip = std::size_t(y) * std::size_t(lv.width) + std::size_t(x);
    const float radius = std::fabs(lv.coc[ip]);
    if (radius < 0.5f) {
        return lv.color[ip];
    }
    const int k = cx.patterns.level(radius);
    const int n = cx.patterns.count(k);
    const Tap *taps = cx.patterns.taps(k, variant_of(cx, x, y, 0));
    glm::vec4 sum = lv.color[ip];
    for (int i = 0; i < n; ++i) {
        const int qx = std::clamp(x + taps[i].dx, 0, lv.width - 1);
        const int qy = std::clamp(y + taps[i].dy, 0, lv.height - 1);
        sum += lv.color[std::size_t(qy) * std::size_t(lv.width) + std::size_t(qx)];
    }
    return sum / float(n + 1);
}

// Near/far gather at one pixel. The background (everything not in front of p in the near
// field) only reaches p within p's own CoC (weights use min(|c_q|, |c_p|) behind p, and
// |c_q| < |c_p| in front), so it is gathered over |c_p|; the near field can reach from as far
// as the tile neighbourhood's largest near CoC, `near_radius`, and is gathered over that.
Layers gather_layers(const Context &cx, const Level &lv, int x, int y, float near_radius)
{
    const int w = lv.width, h = lv.height;
    const std::size_t ip = std::size_t(y) * std::size_t(w) + std::size_t(x);
    const float cp = lv.coc[ip];
    const float acp = std::fabs(cp);
    const bool p_near = cp < -0.5f;
    const auto in_front = [cp](float cq) { return cq < -0.5f && cq <= cp + 1.0f; };

    // The pixel itself: part of the near layer when it is in the near field.
    const float w_self = 1.0f / std::max(cp * cp, 1.0f);
    glm::vec4 front(0.0f), back(0.0f);
    float front_w = 0.0f, back_w = 0.0f, alpha = 0.0f;
    if (p_near) {
        front = lv.color[ip] * w_self;
        front_w = w_self;
    } else {
        back = lv.color[ip] * w_self;
        back_w = w_self;
    }
    if (near_radius >= 0.5f) {
        const int k = cx.patterns.level(near_radius);
        const int n = cx.patterns.count(k);
        const float r = cx.patterns.radius(k);
        const Tap *taps = cx.patterns.taps(k, variant_of(cx, x, y, 1));
        // Each sample stands for R^2 / n of the kernel's area (in units of the unit shape's
        // area), a near sample's footprint is |c_q|^2 of them: alpha = sum cov (R^2 / n) / c_q^2.
        const float sample_area = r * r / float(n);
        for (int i = 0; i < n; ++i) {
            const int qx = std::clamp(x + taps[i].dx, 0, w - 1);
            const int qy = std::clamp(y + taps[i].dy, 0, h - 1);
            const std::size_t iq = std::size_t(qy) * std::size_t(w) + std::size_t(qx);
            const float cq = lv.coc[iq];
            if (!in_front(cq)) {
                continue;
            }
            // Near field in front of p: spreads with its own CoC over whatever is behind.
            const float cov = coverage(-cq, taps[i].dist);
            const float inv_area = 1.0f / (cq * cq);
            front += lv.color[iq] * (cov * inv_area);
            front_w += cov * inv_area;
            alpha += cov * inv_area * sample_area;
        }
    }
    // Once the near field covers the whole lens (alpha >= 1) the background is hidden: skip it
    // (the composite would weigh it by 1 - alpha = 0, so the result is the same bits).
    if (acp >= 0.5f && alpha < 1.0f) {
        const int k = cx.patterns.level(acp);
        const int n = cx.patterns.count(k);
        const Tap *taps = cx.patterns.taps(k, variant_of(cx, x, y, 0));
        for (int i = 0; i < n; ++i) {
            const int qx = std::clamp(x + taps[i].dx, 0, w - 1);
            const int qy = std::clamp(y + taps[i].dy, 0, h - 1);
            const std::size_t iq = std::size_t(qy) * std::size_t(w) + std::size_t(qx);
            const float cq = lv.coc[iq];
            if (in_front(cq)) {
                continue;  // the near loop below
            }
            // Behind p: limited by p's own CoC (a far field never bleeds over a sharper
            // foreground); seen through a near-field p, the background within p's disc shows.
            const float acq = std::fabs(cq);
            const float r_eff = cq > cp ? (p_near ? acp : std::min(acq, acp)) : acq;
            const float wgt = coverage(r_eff, taps[i].dist) / std::max(r_eff * r_eff, 1.0f);
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
    } else {
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
    if (field.max_radius < 0.5f) {
        if (times) {
            *times = tm;
        }
        return false;
    }

    t0 = Clock::now();
    c0 = process_cpu_ms();
    const int w = color.width(), h = color.height(), nc = color.channels();
    std::unique_ptr<glm::vec4[]> col(new glm::vec4[color.pixel_count()]);  // all written
    parallel_for_tiles(color.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float *p = color.pixel(x, y);
                glm::vec4 v(0.0f);
                if (nc >= 4) {
                    v = glm::vec4(sanitize(p[0]), sanitize(p[1]), sanitize(p[2]), sanitize(p[3]));
                } else {
                    for (int k = 0; k < nc; ++k) {
                        v[k] = sanitize(p[k]);
                    }
                }
                col[std::size_t(y) * std::size_t(w) + std::size_t(x)] = v;
            }
        }
    });

    Context cx;
    cx.settings = &settings;
    cx.patterns.build(field.max_radius, settings, settings.density);
    tm.coc_ms += ms_since(t0);
    tm.coc_cpu_ms += process_cpu_ms() - c0;
    const Level full{col.get(), field.radius.data(), w, h};
    const bool simple = settings.method == DofMethod::Simple;
    const bool half = settings.half_res && !simple;
    const auto tile_of = [&](int x, int y) {
        return std::size_t((y / field.tile) * field.tiles_x + x / field.tile);
    };

    // Half resolution: each 2x2 block keeps its nearest CoC (halved) and the mean colour of the
    // pixels within one pixel of CoC of it, so a block straddling a depth edge stays on the
    // near side; then gather both layers there.
    const int w2 = (w + 1) / 2, h2 = (h + 1) / 2;
    std::vector<glm::vec4> col2, back2, front2;  // front2: premultiplied by alpha
    std::vector<float> coc2, alpha2;
    if (half) {
        t0 = Clock::now();
        c0 = process_cpu_ms();
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
        tm.coc_cpu_ms += process_cpu_ms() - c0;

        t0 = Clock::now();
        c0 = process_cpu_ms();
        const Level lv{col2.data(), coc2.data(), w2, h2};
        back2.resize(col2.size());
        front2.resize(col2.size());
        alpha2.resize(col2.size());
        Context cx2;
        cx2.settings = &settings;
        cx2.patterns.build(0.5f * field.max_radius, settings, settings.half_density);
        parallel_for_tiles(
            Rect{0, 0, w2, h2},
            [&](const Rect &t) {
                const float radius = 0.5f * field.gather[tile_of(2 * t.x0, 2 * t.y0)];
                const float near_radius = 0.5f * field.near_gather[tile_of(2 * t.x0, 2 * t.y0)];
                for (int y = t.y0; y < t.y1; ++y) {
                    for (int x = t.x0; x < t.x1; ++x) {
                        const std::size_t o = std::size_t(y) * w2 + x;
                        Layers l;
                        if (radius < 0.5f) {
                            l.back = col2[o];
                        } else {
                            l = gather_layers(cx2, lv, x, y, near_radius);
                        }
                        back2[o] = l.back;
                        front2[o] = l.front * l.alpha;
                        alpha2[o] = l.alpha;
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
    parallel_for_tiles(
        color.bounds(),
        [&](const Rect &t) {
            const int ti = (t.y0 / field.tile) * field.tiles_x + t.x0 / field.tile;
            const float radius = field.gather[std::size_t(ti)];
            const float near_radius = field.near_gather[std::size_t(ti)];
            const bool copy = radius < 0.5f && !simple;
            const bool use_half = half && radius >= settings.half_min_radius;
            gathered[std::size_t(ti)] = copy ? 0 : 1;
            for (int y = t.y0; y < t.y1; ++y) {
                for (int x = t.x0; x < t.x1; ++x) {
                    const std::size_t ip = std::size_t(y) * std::size_t(w) + std::size_t(x);
                    glm::vec4 v;
                    if (copy) {
                        v = col[ip];
                    } else if (simple) {
                        v = gather_simple(cx, full, x, y);
                    } else if (use_half) {
                        v = composite_half(full, x, y, w2, h2, coc2, back2, front2, alpha2);
                    } else {
                        v = gather_layers(cx, full, x, y, near_radius).composite();
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
