#include "core/sanitize.h"

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/parallel.h"

namespace posthaste {
namespace {

inline bool acceptable(float v, bool allow_positive_inf)
{
    return std::isfinite(v) || (allow_positive_inf && v > 0.0f && std::isinf(v));
}

}  // namespace

const Image &finite_view(const Image &image,
                         float replacement,
                         Image &storage,
                         bool allow_positive_inf)
{
    const int h = image.height();
    const std::size_t row = std::size_t(image.width()) * std::size_t(image.channels());
    std::vector<char> bad(std::size_t(h), 0);
    // A branch-free scan on the bits (the compiler vectorises it; an early exit would not be):
    // a value needs replacing when its magnitude's bits exceed kMaxGatherValue's (every NaN and
    // infinity does), except +inf where it is allowed (exactly 0x7f800000).
    const std::uint32_t pos_inf_ok = allow_positive_inf ? 0x7f800000u : 0xffffffffu;
    std::uint32_t max_bits;
    std::memcpy(&max_bits, &kMaxGatherValue, sizeof(max_bits));
    parallel_for(0, h, [&](int y) {
        const float *p = image.pixel(0, y);
        std::uint32_t any_bad = 0;
        for (std::size_t i = 0; i < row; ++i) {
            std::uint32_t u;
            std::memcpy(&u, p + i, sizeof(u));
            any_bad |= std::uint32_t((u & 0x7fffffffu) > max_bits) & std::uint32_t(u != pos_inf_ok);
        }
        bad[std::size_t(y)] = any_bad != 0;
    });
    bool any = false;
    for (char b : bad) {
        any = any || b;
    }
    if (!any) {
        return image;
    }
    storage = image;
    parallel_for(0, h, [&](int y) {
        if (!bad[std::size_t(y)]) {
            return;
        }
        float *p = storage.pixel(0, y);
        for (std::size_t i = 0; i < row; ++i) {
            if (!acceptable(p[i], allow_positive_inf)) {
                p[i] = replacement;
            } else if (std::abs(p[i]) > kMaxGatherValue && std::isfinite(p[i])) {
                p[i] = std::copysign(kMaxGatherValue, p[i]);
            }
        }
    });
    return storage;
}

}  // namespace posthaste
