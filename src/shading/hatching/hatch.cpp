// Hatching: the frame's set-up (outline pen, tone curve, TAM constants) and its tiles; the
// per-pixel work is the Highway kernel in hatch_kernels.cpp.
#include "shading/hatching/hatch.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <glm/geometric.hpp>

#include "core/parallel.h"
#include "shading/hatching/hatch_kernel.h"

namespace posthaste::shading {
namespace {

constexpr float kPiF = 3.14159265358979323846f;

}  // namespace

using hatch_detail::KernelCtx;
using hatch_detail::LineTap;

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
    // Screen mode without outlines or light reads no geometry (sky and surfaces alike).
    const bool needs_samples = !s.screen_space || outlines || s.tone_from_light;

    Image out = Image::uninitialized(w, h, nc);
    const float mix = s.mix;
    if (mix <= 0.0f) {  // no drawing: the input as it is
        parallel_for(0, h, [&](int y) {
            std::copy_n(color.pixel(0, y), std::size_t(w) * std::size_t(nc), out.pixel(0, y));
        });
        return out;
    }
    const KernelCtx kc{.color = &color,
                       .depth = in.depth,
                       .normal = in.normal,
                       .position = in.position,
                       .out = &out,
                       .tam = &tam,
                       .curve = &curve,
                       .taps = line_taps.data(),
                       .tap_count = int(line_taps.size()),
                       .line_reach = line_reach,
                       .screen_space = s.screen_space,
                       .tone_from_light = s.tone_from_light,
                       .partial_mix = mix < 1.0f,
                       .needs_samples = needs_samples,
                       .depth_threshold = s.depth_threshold,
                       .cos_thr = cos_thr,
                       .inv_scale = inv_scale,
                       .lod_offset = lod_offset,
                       .flat_lod = flat_lod,
                       .finest = finest,
                       .ambient = s.ambient,
                       .exposure = s.exposure,
                       .mix = mix,
                       .light = light,
                       .paper = s.paper,
                       .ink_minus_paper = s.ink - s.paper,
                       .outline_color = s.outline,
                       .triplanar = s.triplanar,
                       .triplanar_sharpness = s.triplanar_sharpness,
                       .zero_pow = std::pow(0.0f, s.triplanar_sharpness),
                       .id = in.id,
                       .ids = s.ids.empty() ? nullptr : &s.ids};
    for (int l = 0; l < tam.levels(); ++l) {  // the kernel computes level offsets
        assert(int(tam.level_offset(l)) ==
               4 * (tam.size() * tam.size() - tam.level_size(l) * tam.level_size(l)) / 3);
    }
    // Wide, short tiles: each row of a tile is a long sequential read of every pass (64-pixel
    // rows are too short for the hardware prefetchers), and the tile's planes stay in L2. The
    // output of a pixel does not depend on the tile it falls in.
    constexpr int kTileW = 512, kTileH = 32;
    const int tiles_x = (w + kTileW - 1) / kTileW, tiles_y = (h + kTileH - 1) / kTileH;
    parallel_for(0, tiles_x * tiles_y, [&](int i) {
        const int tx = i % tiles_x, ty = i / tiles_x;
        const Rect t{tx * kTileW,
                     ty * kTileH,
                     std::min((tx + 1) * kTileW, w),
                     std::min((ty + 1) * kTileH, h)};
        hatch_detail::hatch_tile(kc, t);
    });
    return out;
}

}  // namespace posthaste::shading
