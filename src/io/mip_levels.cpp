// src/io/mip_levels.cpp: the next MIP or rip level of a pass a node touched.

#include "io/mip_levels.h"

#include <algorithm>
#include <cstddef>

namespace posthaste::io_detail {

/// The source pixels (and their weights) one pixel of the next level averages along an axis of
/// n pixels. Halving an even n, or rounding up, takes blocks of two (an odd last block reads its
/// one pixel twice: a pixel of its own). Rounding an odd n = 2m + 1 down to m, each new pixel
/// covers (2m + 1) / m old ones: the overlaps weigh them (in units of 1/m), so the level keeps the
/// image's mean and place (dropping the last row or column, as a plain box does, shifted every
/// level up and left and biased it: a gradient's level 4 mean read 0.44 for 0.5).
std::vector<std::vector<std::pair<int, float>>> level_taps(int n,
                                                           bool along,
                                                           bool round_up,
                                                           int &nn)
{
    nn = !along ? n : std::max(1, round_up ? (n + 1) / 2 : n / 2);
    std::vector<std::vector<std::pair<int, float>>> taps(static_cast<std::size_t>(nn));
    for (int i = 0; i < nn; ++i) {
        auto &t = taps[std::size_t(i)];
        if (!along || n == 1) {
            t.push_back({i, 1.0f});
        } else if (n % 2 == 0 || round_up) {
            t.push_back({2 * i, 1.0f});
            t.push_back({std::min(2 * i + 1, n - 1), 1.0f});
        } else {
            const long lo = long(i) * n, hi = long(i + 1) * n;  // in units of 1/nn
            for (int s = int(lo / nn); s < n && long(s) * nn < hi; ++s) {
                const long a = std::max(lo, long(s) * nn), b = std::min(hi, long(s + 1) * nn);
                if (b > a) {
                    t.push_back({s, float(b - a)});
                }
            }
        }
    }
    return taps;
}

/// The next level along x, y or both: each pixel the weighted mean of the pixels above it
/// (level_taps; blocks of 2x2 where the sizes are even, as maketx's box filter).
std::vector<float> halve(const std::vector<float> &src,
                         int w,
                         int h,
                         int nch,
                         bool along_x,
                         bool along_y,
                         bool round_up,
                         int &nw,
                         int &nh)
{
    const auto tx = level_taps(w, along_x, round_up, nw);
    const auto ty = level_taps(h, along_y, round_up, nh);
    std::vector<float> dst(std::size_t(nw) * std::size_t(nh) * std::size_t(nch));
    for (int y = 0; y < nh; ++y) {
        for (int x = 0; x < nw; ++x) {
            float total = 0.0f;
            for (const auto &[sy, wy] : ty[std::size_t(y)]) {
                for (const auto &[sx, wx] : tx[std::size_t(x)]) {
                    total += wx * wy;
                }
            }
            for (int c = 0; c < nch; ++c) {
                float sum = 0.0f;
                for (const auto &[sy, wy] : ty[std::size_t(y)]) {
                    for (const auto &[sx, wx] : tx[std::size_t(x)]) {
                        sum += src[(std::size_t(sy) * std::size_t(w) + std::size_t(sx)) *
                                       std::size_t(nch) +
                                   std::size_t(c)] *
                               (wx * wy);
                    }
                }
                dst[(std::size_t(y) * std::size_t(nw) + std::size_t(x)) * std::size_t(nch) +
                    std::size_t(c)] = sum / total;
            }
        }
    }
    return dst;
}

}  // namespace posthaste::io_detail
