// Fog over a colour pass filtered at depth edges (filtered_edges.h).

#include "shading/fog/filtered_edges.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace posthaste::shading {
namespace {

/// Whether the 3x3 depths around (x, y) leave one plane, from the inverse depths `inv` (the
/// sky 0, no depth -1). A plane's inverse depth is affine on the screen, so along each of the
/// four lines through the pixel (a row, a column, the two diagonals) the second difference is
/// 0 up to rounding: more than 1 % of the pixel's own is an edge or a crease (the sky beside a
/// surface is one). A line with an end outside the frame or without depth is not looked at.
bool depth_edge(const Image &inv, int x, int y)
{
    const int w = inv.width(), h = inv.height();
    const float sp = inv.at(x, y, 0);
    auto line = [sp](float a, float b) {
        return (a >= 0.0f) & (b >= 0.0f) & (std::abs(a + b - 2.0f * sp) > 0.01f * sp);
    };
    if (x > 0 && y > 0 && x + 1 < w && y + 1 < h) {
        const float *up = inv.pixel(x, y - 1), *row = inv.pixel(x, y), *down = inv.pixel(x, y + 1);
        return line(row[-1], row[1]) | line(up[0], down[0]) | line(up[-1], down[1]) |
               line(down[-1], up[1]);
    }
    constexpr int kLines[4][2] = {{1, 0}, {0, 1}, {1, 1}, {1, -1}};
    for (const auto &d : kLines) {
        const int ax = x - d[0], ay = y - d[1], bx = x + d[0], by = y + d[1];
        if (ax >= 0 && ay >= 0 && ax < w && ay < h && bx >= 0 && by >= 0 && bx < w && by < h &&
            line(inv.at(ax, ay, 0), inv.at(bx, by, 0))) {
            return true;
        }
    }
    return false;
}

}  // namespace

void correct_filtered_edges(const Image &color,
                            const Image &transmittance,
                            const Image &inscatter,
                            const Image &depth,
                            float sigma,
                            Image &out)
{
    const int w = out.width(), h = out.height();
    const int nc = color.channels(), nt = transmittance.channels(), no = out.channels();
    float weight[3][3];
    for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
            // The centre weighs 1 outright: below sigma 1e-23 sigma^2 is 0 in float, and its
            // 0 / 0 was NaN in every edge pixel. The neighbours' weights then fall to 0.
            const int d2 = dx * dx + dy * dy;
            weight[dy + 1][dx + 1] = d2 == 0 ? 1.0f : std::exp(-float(d2) / (2.0f * sigma * sigma));
        }
    }
    // Reads the inputs only: each tile writes its own pixels of `out`.
    // Inverse depths: the sky 0, no depth (NaN, at most 0) -1.
    Image inv = Image::uninitialized(w, h, 1);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x, y, 0);
            inv.at(x, y, 0) = z > 0.0f ? 1.0f / z : -1.0f;
        }
    });
    parallel_for_tiles(out.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float zp = depth.at(x, y, 0);
                if (!(zp > 0.0f)) {
                    continue;
                }
                if (!depth_edge(inv, x, y)) {
                    continue;  // one plane: the correction is of the second order
                }
                const float *tp = transmittance.pixel(x, y), *ip = inscatter.pixel(x, y);
                float sum[3] = {0.0f, 0.0f, 0.0f}, total = 0.0f;
                // The neighbourhood's largest composite parts: the result stays within
                // [0, max T * max c + max I] whatever the colours' contrast.
                float t_max[3] = {0.0f, 0.0f, 0.0f}, c_max[3] = {0.0f, 0.0f, 0.0f};
                float i_max[3] = {0.0f, 0.0f, 0.0f};
                bool edge = false;
                for (int dy = -1; dy <= 1; ++dy) {
                    const int qy = y + dy;
                    if (qy < 0 || qy >= h) {
                        continue;
                    }
                    for (int dx = -1; dx <= 1; ++dx) {
                        const int qx = x + dx;
                        if (qx < 0 || qx >= w || !(depth.at(qx, qy, 0) > 0.0f)) {
                            continue;
                        }
                        const float wq = weight[dy + 1][dx + 1];
                        if (wq == 0.0f) {
                            continue;  // not in the filter (0 times an infinite colour is NaN)
                        }
                        total += wq;
                        const float *tq = transmittance.pixel(qx, qy);
                        const float *iq = inscatter.pixel(qx, qy);
                        const float *cq = color.pixel(qx, qy);
                        for (int c = 0; c < 3; ++c) {
                            const float dt = tq[c] - tp[c], di = iq[c] - ip[c];
                            edge = edge || dt != 0.0f || di != 0.0f;
                            sum[c] += wq * (dt * cq[c] + di);
                            t_max[c] = std::max(t_max[c], tq[c]);
                            c_max[c] = std::max(c_max[c], cq[c]);
                            i_max[c] = std::max(i_max[c], iq[c]);
                        }
                    }
                }
                if (!edge) {
                    continue;  // the neighbours' composite is the pixel's own: nothing changes
                }
                float *o = out.pixel(x, y);
                for (int c = 0; c < 3 && c < no && c < nc && c < nt; ++c) {
                    o[c] = std::clamp(o[c] + sum[c] / total, 0.0f, t_max[c] * c_max[c] + i_max[c]);
                }
            }
        }
    });
}

}  // namespace posthaste::shading
