#include "shading/hatching/tam.h"

#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <stdexcept>

#include "core/disk_cache.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/timing.h"

namespace posthaste::shading {
namespace {

double thread_cpu_ms()
{
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

constexpr float kPiF = 3.14159265358979323846f;
/// Safety stop per (tone, level): never reached with valid parameters (coverage tends to 1).
constexpr int kMaxStrokesPerLevel = 200000;

bool is_power_of_two(int v)
{
    return v > 0 && (v & (v - 1)) == 0;
}

int log2_int(int v)
{
    int l = 0;
    while ((1 << (l + 1)) <= v) {
        ++l;
    }
    return l;
}

/// Calls f(index, alpha) for each texel of a level of side s that the stroke touches (alpha > 0),
/// wrapping around the tile. Coverage is a 1-texel box-filtered capsule around a parabolic arc.
template <typename F>
void for_stroke_texels(const TamStroke &st, float width, int s, F &&f)
{
    const float sf = float(s);
    const float cx = st.cx * sf, cy = st.cy * sf;
    const float half_len = 0.5f * st.length * sf, bend = st.bend * sf, hw = 0.5f * width;
    const float reach = hw + 1.0f + std::abs(bend);  // farthest |perpendicular| with alpha > 0
    const float dx = st.dx, dy = st.dy;
    const int mask = s - 1;
    auto texel = [&](int x, int y) {
        const float px = float(x) + 0.5f - cx, py = float(y) + 0.5f - cy;
        const float a = px * dx + py * dy;   // along the stroke
        const float q = -px * dy + py * dx;  // across it
        float dist;
        if (std::abs(a) <= half_len) {
            const float t = a / half_len;
            dist = std::abs(q - bend * (1.0f - t * t));
        } else {
            const float ea = a > 0.0f ? a - half_len : a + half_len;
            dist = std::sqrt(ea * ea + q * q);
        }
        const float alpha = std::clamp(hw + 0.5f - dist, 0.0f, 1.0f);
        if (alpha > 0.0f) {
            f(std::size_t(y & mask) * std::size_t(s) + std::size_t(x & mask), alpha);
        }
    };
    // Walk along the major axis; on each line only the span within `reach` of the chord.
    const float ext = half_len + reach;
    if (std::abs(dy) >= std::abs(dx)) {
        const int y0 = int(std::floor(cy - std::abs(dy) * ext)) - 1;
        const int y1 = int(std::ceil(cy + std::abs(dy) * ext)) + 1;
        for (int y = y0; y <= y1; ++y) {
            const float py = float(y) + 0.5f - cy;
            // |q| <= reach with q = -px dy + py dx  =>  px in (py dx -+ reach) / dy
            const float xa = (py * dx - reach) / dy, xb = (py * dx + reach) / dy;
            const int x0 = int(std::floor(cx + std::min(xa, xb) - 0.5f));
            const int x1 = int(std::ceil(cx + std::max(xa, xb) - 0.5f));
            for (int x = x0; x <= x1; ++x) {
                texel(x, y);
            }
        }
    } else {
        const int x0 = int(std::floor(cx - std::abs(dx) * ext)) - 1;
        const int x1 = int(std::ceil(cx + std::abs(dx) * ext)) + 1;
        for (int x = x0; x <= x1; ++x) {
            const float px = float(x) + 0.5f - cx;
            const float ya = (px * dy - reach) / dx, yb = (px * dy + reach) / dx;
            const int y0 = int(std::floor(cy + std::min(ya, yb) - 0.5f));
            const int y1 = int(std::ceil(cy + std::max(ya, yb) - 0.5f));
            for (int y = y0; y <= y1; ++y) {
                texel(x, y);
            }
        }
    }
}

}  // namespace

float Tam::mean(int tone, int level) const
{
    const int s = level_size(level);
    const float *t = texels(tone, level);
    double sum = 0.0;
    for (int i = 0; i < s * s; ++i) {
        sum += t[i];
    }
    return float(sum / double(s * s));
}

void validate(const TamParams &p)
{
    if (!is_power_of_two(p.size) || p.size < 16 || p.size > 1024) {
        throw_usage("tam: size must be a power of two in 16..1024, got ", p.size);
    }
    const int max_stroke_levels = log2_int(p.size) - 2;  // coarsest stroke level >= 4 x 4
    if (p.stroke_levels < 1 || p.stroke_levels > max_stroke_levels) {
        throw_usage("tam: stroke_levels must be in 1..",
                    max_stroke_levels,
                    " for size ",
                    p.size,
                    ", got ",
                    p.stroke_levels);
    }
    if (!(p.width >= 0.25f && p.width <= 16.0f)) {
        throw_usage("tam: stroke width must be in 0.25..16 texels, got ", p.width);
    }
    if (!(p.length >= 0.02f && p.length <= 0.9f)) {
        throw_usage("tam: stroke length must be in 0.02..0.9 tiles, got ", p.length);
    }
    if (!(p.jitter >= 0.0f && p.jitter <= 1.0f)) {
        throw_usage("tam: jitter must be in 0..1, got ", p.jitter);
    }
    if (p.cross_tones < 0 || p.cross_tones > kTamTones) {
        throw_usage("tam: cross_tones must be in 0..", kTamTones, ", got ", p.cross_tones);
    }
    if (p.candidates < 1 || p.candidates > 256) {
        throw_usage("tam: candidates must be in 1..256, got ", p.candidates);
    }
    if (!(p.darkest > 0.0f && p.darkest <= 0.98f)) {
        throw_usage("tam: darkest must be in (0, 0.98], got ", p.darkest);
    }
}

Tam build_tam(const TamParams &p)
{
    validate(p);
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = thread_cpu_ms();
    // TamParams is 4-byte fields only: its bytes are the key as they are.
    static_assert(sizeof(TamParams) == 11 * 4 && alignof(TamParams) == 4);
    disk_cache::Key key("tam");
    key.add(p);
    Tam tam = disk_cache::cached<Tam>(
        key,
        [&] { return Tam::build(p); },
        [](const Tam &t, disk_cache::Writer &w) {
            w.put(std::int32_t(t.size_));
            w.put(std::int32_t(t.stroke_levels_));
            w.put_vector(t.data_);
            w.put_vector(t.strokes_);
        },
        [&](disk_cache::Reader &r) {
            Tam t = Tam::layout(p);
            if (r.get<std::int32_t>() != p.size || r.get<std::int32_t>() != p.stroke_levels) {
                throw std::out_of_range("tam: another layout");
            }
            std::vector<float> data = r.get_vector<float>(t.data_.size());
            if (data.size() != t.data_.size()) {
                throw std::out_of_range("tam: another size");
            }
            t.data_ = std::move(data);
            t.strokes_ = r.get_vector<TamStroke>(std::size_t(1) << 24);
            return t;
        });
    tam.pack();
    tam.build_cpu_ms_ = thread_cpu_ms() - cpu0;
    tam.build_ms_ = ms_since(t0);
    return tam;
}

Tam Tam::layout(const TamParams &p)
{
    Tam tam;
    tam.size_ = p.size;
    tam.stroke_levels_ = p.stroke_levels;
    const int all_levels = log2_int(p.size) + 1;
    std::size_t offset = 0;
    for (int l = 0; l < all_levels; ++l) {
        tam.level_offset_.push_back(offset);
        offset += std::size_t(p.size >> l) * std::size_t(p.size >> l);
    }
    tam.tone_stride_ = offset;
    tam.levels_ = all_levels;
    tam.data_.assign(offset * kTamTones, 0.0f);
    return tam;
}

Tam Tam::build(const TamParams &p)
{
    Tam tam = layout(p);
    const std::size_t offset = tam.tone_stride_;
    const int all_levels = tam.levels_;

    std::uint32_t counter = 0;
    auto random = [&]() { return hash_to_unit(hash4(counter++, 0x7a3u, 0x1f5u, p.seed)); };
    auto candidate = [&](int tone, int level) {
        const bool cross = tone >= kTamTones - p.cross_tones;
        const float base = cross ? p.cross_angle_deg : p.angle_deg;
        const float angle = (base + p.jitter * 12.0f * (2.0f * random() - 1.0f)) * kPiF / 180.0f;
        TamStroke st;
        st.cx = random();
        st.cy = random();
        st.dx = std::cos(angle);
        st.dy = -std::sin(angle);  // texel rows grow downwards; angles turn counter-clockwise
        st.length = std::min(0.9f, p.length * (1.0f + 0.5f * p.jitter * (2.0f * random() - 1.0f)));
        st.bend = 0.04f * p.jitter * st.length * (2.0f * random() - 1.0f);
        st.tone = tone;
        st.level = level;
        return st;
    };

    for (int tone = 0; tone < kTamTones; ++tone) {
        if (tone > 0) {  // nesting across tones: start from the lighter tone's strokes
            std::copy_n(tam.data_.begin() + std::ptrdiff_t((tone - 1) * offset),
                        offset,
                        tam.data_.begin() + std::ptrdiff_t(tone * offset));
        }
        const double target = double(p.darkest) * double(tone + 1) / double(kTamTones);
        for (int level = p.stroke_levels - 1; level >= 0; --level) {
            const int s = p.size >> level;
            double ink = double(tam.mean(tone, level)) * double(s) * double(s);
            for (int n = 0; n < kMaxStrokesPerLevel && ink < target * double(s) * double(s); ++n) {
                TamStroke best;
                float best_goodness = -1.0f;
                for (int c = 0; c < p.candidates; ++c) {
                    const TamStroke st = candidate(tone, level);
                    // Goodness (Praun et al. 4.2): new ink relative to ink drawn, summed over
                    // the levels the stroke enters (this level and every finer one).
                    float goodness = 0.0f;
                    for (int l = level; l >= 0; --l) {
                        const float *tex = tam.texels(tone, l);
                        float added = 0.0f, drawn = 0.0f;
                        for_stroke_texels(st, p.width, p.size >> l, [&](std::size_t i, float a) {
                            added += a * (1.0f - tex[i]);
                            drawn += a;
                        });
                        goodness += drawn > 0.0f ? added / drawn : 0.0f;
                    }
                    if (goodness > best_goodness) {
                        best_goodness = goodness;
                        best = st;
                    }
                }
                for (int l = level; l >= 0; --l) {
                    float *tex = tam.data_.data() + std::size_t(tone) * offset +
                                 tam.level_offset_[std::size_t(l)];
                    double added = 0.0;
                    for_stroke_texels(best, p.width, p.size >> l, [&](std::size_t i, float a) {
                        const float before = tex[i];
                        tex[i] = before + a * (1.0f - before);
                        added += double(tex[i] - before);
                    });
                    if (l == level) {
                        ink += added;
                    }
                }
                tam.strokes_.push_back(best);
            }
        }
        // Levels below the stroke levels: 2x2 box averages of the next finer level.
        for (int l = p.stroke_levels; l < all_levels; ++l) {
            const int s = p.size >> l;
            const float *src = tam.texels(tone, l - 1);
            float *dst =
                tam.data_.data() + std::size_t(tone) * offset + tam.level_offset_[std::size_t(l)];
            for (int y = 0; y < s; ++y) {
                for (int x = 0; x < s; ++x) {
                    const std::size_t i =
                        std::size_t(2 * y) * std::size_t(2 * s) + std::size_t(2 * x);
                    dst[std::size_t(y) * std::size_t(s) + std::size_t(x)] =
                        0.25f * (src[i] + src[i + 1] + src[i + std::size_t(2 * s)] +
                                 src[i + std::size_t(2 * s) + 1]);
                }
            }
        }
    }
    return tam;
}

void Tam::pack()
{
    // Texel-major copy for sampling: [0, tone 0 .. tone 5, tone 5] per texel.
    const std::size_t offset = tone_stride_;
    packed_.assign(offset * kPacked, 0.0f);
    for (std::size_t i = 0; i < offset; ++i) {
        float *dst = packed_.data() + i * kPacked;
        for (int t = 0; t < kTamTones; ++t) {
            dst[t + 1] = data_[std::size_t(t) * offset + i];
        }
        dst[kTamTones + 1] = dst[kTamTones];
    }
}

}  // namespace posthaste::shading
