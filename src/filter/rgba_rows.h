#pragma once
// Running a kernel written for interleaved RGBA rows (the Highway kernels of grain and the tone
// curves) over an image of any layout with at least R, G, B.

#include <algorithm>
#include <vector>

#include "core/image.h"
#include "core/parallel.h"

namespace posthaste::filter {

/// kernel(y, src_row, dst_row, n) on every row of `src` into `dst` (the same shape), rows in
/// parallel. Four-channel rows go straight through; other layouts (3 or more than 4 channels)
/// through an RGBA copy of the row, alpha from channel 3 when there is one and 1 otherwise; then R,
/// G, B are written back and every other channel is copied unchanged.
template <typename Kernel>
void for_rgba_rows(const Image &src, Image &dst, const Kernel &kernel)
{
    const int w = src.width(), nc = src.channels();
    parallel_for(0, src.height(), [&](int y) {
        if (nc == 4) {
            kernel(y, src.pixel(0, y), dst.pixel(0, y), w);
            return;
        }
        std::vector<float> rgba(std::size_t(w) * 4);
        for (int x = 0; x < w; ++x) {
            const float *p = src.pixel(x, y);
            float *q = rgba.data() + std::size_t(x) * 4;
            std::copy(p, p + 3, q);
            q[3] = nc >= 4 ? p[3] : 1.0f;
        }
        kernel(y, rgba.data(), rgba.data(), w);
        for (int x = 0; x < w; ++x) {
            float *d = dst.pixel(x, y);
            std::copy(src.pixel(x, y), src.pixel(x, y) + nc, d);
            std::copy(rgba.data() + std::size_t(x) * 4, rgba.data() + std::size_t(x) * 4 + 3, d);
        }
    });
}

}  // namespace posthaste::filter
