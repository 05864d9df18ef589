#include "shading/lighting/lighting_split.h"

#include <algorithm>
#include <cmath>
#include <iterator>

#include "core/parallel.h"

namespace posthaste::shading {

SplitRegion find_split(int width,
                       int height,
                       int reach,
                       const std::function<void(int y, std::uint8_t *row)> &mark_row,
                       int align)
{
    SplitRegion r;
    r.width = width;
    r.height = height;
    r.parts.assign(std::size_t(width) * std::size_t(height), 0);
    std::vector<int> first(std::size_t(height), width), last(std::size_t(height), -1);
    parallel_for(0, height, [&](int y) {
        std::uint8_t *row = r.parts.data() + std::size_t(y) * std::size_t(width);
        mark_row(y, row);
        const std::uint8_t *const begin = row, *const end = row + width;
        const auto set = [](std::uint8_t v) { return v != 0; };
        const std::uint8_t *f = std::find_if(begin, end, set);
        if (f != end) {
            const auto l =
                std::find_if(std::make_reverse_iterator(end), std::make_reverse_iterator(f), set);
            first[std::size_t(y)] = int(f - begin);
            last[std::size_t(y)] = int(l.base() - begin) - 1;
        }
    });
    Rect box{width, height, 0, 0};
    for (int y = 0; y < height; ++y) {
        if (last[std::size_t(y)] >= 0) {
            box = Rect{std::min(box.x0, first[std::size_t(y)]),
                       std::min(box.y0, y),
                       std::max(box.x1, last[std::size_t(y)] + 1),
                       y + 1};
        }
    }
    if (box.empty()) {
        return r;
    }
    r.box = box;
    Rect crop = box.expand(std::max(reach, 0)).intersect(Rect{0, 0, width, height});
    if (align > 1) {
        // The origin down to the grid (it is inside the frame, so not negative).
        crop.x0 -= crop.x0 % align;
        crop.y0 -= crop.y0 % align;
    }
    r.crop = crop;
    return r;
}

Image share_color(const Image &specular, const SplitRegion &region, float knee)
{
    const Rect &c = region.crop;
    Image share = Image::uninitialized(c.width(), c.height(), 4);
    parallel_for(0, c.height(), [&](int j) {
        const int y = c.y0 + j;
        for (int i = 0; i < c.width(); ++i) {
            const int x = c.x0 + i;
            const bool parts = region.at(x, y);
            const float *sp = specular.pixel(x, y);
            float *d = share.pixel(i, j);
            for (int k = 0; k < 3; ++k) {
                const float v = knee > 0.0f ? std::max(sp[k] - knee, 0.0f) : sp[k];
                d[k] = parts && std::isfinite(sp[k]) ? v : 0.0f;
            }
            d[3] = 0.0f;
        }
    });
    return share;
}

void compose_split(const Image &color,
                   const Image &share,
                   const Image &share_blurred,
                   const SplitRegion &region,
                   bool rest_still,
                   Image &out)
{
    const Rect &c = region.crop;
    const int cc = std::min(color.channels(), 3);
    parallel_for(0, c.height(), [&](int j) {
        const int y = c.y0 + j;
        for (int i = 0; i < c.width(); ++i) {
            const int x = c.x0 + i;
            const float *col = color.pixel(x, y);
            const float *s0 = share.pixel(i, j), *s1 = share_blurred.pixel(i, j);
            float *q = out.pixel(x, y);
            for (int k = 0; k < cc; ++k) {
                const float rest = col[k] - s0[k];  // the bits the filter subtracted
                const float changed = rest_still ? 0.0f : q[k] - rest;
                q[k] = col[k] + changed + (s1[k] - s0[k]);
            }
        }
    });
}

}  // namespace posthaste::shading
