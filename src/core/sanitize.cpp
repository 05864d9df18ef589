#include "core/sanitize.h"

#include <cmath>
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
    parallel_for(0, h, [&](int y) {
        const float *p = image.pixel(0, y);
        for (std::size_t i = 0; i < row; ++i) {
            if (!acceptable(p[i], allow_positive_inf)) {
                bad[std::size_t(y)] = 1;
                return;
            }
        }
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
            }
        }
    });
    return storage;
}

}  // namespace posthaste
