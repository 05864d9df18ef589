// Fog over a colour pass filtered at depth edges (filtered_edges.h).

#include "shading/fog/filtered_edges.h"

#include <algorithm>
#include <cmath>

#include "core/parallel.h"

namespace posthaste::shading {

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
            weight[dy + 1][dx + 1] = std::exp(-float(dx * dx + dy * dy) / (2.0f * sigma * sigma));
        }
    }
    // Reads the inputs only: each tile writes its own pixels of `out`.
    parallel_for_tiles(out.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                if (!(depth.at(x, y, 0) > 0.0f)) {
                    continue;
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
