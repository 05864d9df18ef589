#include "shading/dof/dof_patterns.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "core/parallel.h"

namespace posthaste::shading::dof {
namespace {

constexpr float kGoldenAngle = 2.39996323f;
constexpr float kTwoPi = 6.28318531f;

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

}  // namespace

void Patterns::build(float max_radius, const DofSettings &st, float density, int width)
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
                t[i].rim = 0.5f - std::sqrt(float(ox * ox + oy * oy)) / shape;
            }
            // Row by row: consecutive taps read neighbouring memory (the sums do not depend
            // on the order but for rounding).
            std::sort(t, t + n, [](const Tap &a, const Tap &b) {
                return a.dy != b.dy ? a.dy < b.dy : a.dx < b.dx;
            });
        }
    });
    reach_.assign(radii_.size(), 0);
    offsets_.resize(taps_.size());
    for (std::size_t k = 0; k < radii_.size(); ++k) {
        const std::size_t start = start_[k], end = start + std::size_t(n_[k]) * kVariants;
        for (std::size_t i = start; i < end; ++i) {
            const Tap &t = taps_[i];
            reach_[k] = std::max({reach_[k], std::abs(int(t.dx)), std::abs(int(t.dy))});
            offsets_[i] = std::ptrdiff_t(t.dy) * width + t.dx;
        }
    }
    lut_.resize(std::size_t(std::ceil(4.0f * radii_.back())) + 2);
    for (std::size_t i = 0; i < lut_.size(); ++i) {
        const auto it = std::lower_bound(radii_.begin(), radii_.end(), 0.25f * float(i));
        lut_[i] = it == radii_.end() ? int(radii_.size()) - 1 : int(it - radii_.begin());
    }
}

}  // namespace posthaste::shading::dof
