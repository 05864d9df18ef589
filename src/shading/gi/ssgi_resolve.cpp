// The resolve of ssgi's reduced result (ssgi.h, ssgi_resolve): a depth- and normal-aware
// denoise at the reduced resolution, then the upsample to the depth pass's resolution, with the
// albedo folded in.

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

#include "core/parallel.h"
#include "shading/gi/ssgi.h"

namespace posthaste::shading {

namespace {

/// The depth of the computed pixels (their top-left full-resolution pixel), NaN for no surface.
std::vector<float> reduced_depth(const Image &depth, int st, int ow, int oh)
{
    std::vector<float> ld(std::size_t(ow) * std::size_t(oh));
    for (int y = 0; y < oh; ++y) {
        for (int x = 0; x < ow; ++x) {
            const float z = depth.at(x * st, y * st, 0);
            ld[std::size_t(y) * std::size_t(ow) + std::size_t(x)] =
                z > 0.0f && std::isfinite(z) ? z : std::numeric_limits<float>::quiet_NaN();
        }
    }
    return ld;
}

/// The depth tent of the ao node's filters: 1 - |dz| / (0.1 z), at least 0 (NaN: 0).
float tent(float dz_abs, float inv_scale)
{
    const float t = 1.0f - dz_abs * inv_scale;
    return 0.0f < t ? t : 0.0f;
}

/// The unit normal at (x, y), 0 where it is zero or not finite.
glm::vec3 unit_normal(const Image &normal, int x, int y)
{
    const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
    const float len2 = glm::dot(n, n);
    return len2 > 1e-12f && std::isfinite(len2) ? n / std::sqrt(len2) : glm::vec3(0.0f);
}

/// How much two surfaces' normals agree: max(0, a.b)^8 (faces at right angles: 0); 1 when
/// either is unknown.
float normal_weight(const glm::vec3 &a, const glm::vec3 &b)
{
    if (a == glm::vec3(0.0f) || b == glm::vec3(0.0f)) {
        return 1.0f;
    }
    float t = std::max(0.0f, glm::dot(a, b));
    t *= t;
    t *= t;
    return t * t;
}

}  // namespace

Image ssgi_resolve(const Image &light,
                   const Image &depth,
                   const Image &normal,
                   int stride,
                   bool denoise,
                   const SsgiApply *apply)
{
    const int st = std::max(1, stride);
    const int ow = light.width(), oh = light.height(), w = depth.width(), h = depth.height();
    const std::vector<float> ld = reduced_depth(depth, st, ow, oh);
    auto lz = [&](int x, int y) { return ld[std::size_t(y) * std::size_t(ow) + std::size_t(x)]; };
    std::vector<glm::vec3> lnorm(ld.size());
    parallel_for(0, oh, [&](int y) {
        for (int x = 0; x < ow; ++x) {
            lnorm[std::size_t(y) * std::size_t(ow) + std::size_t(x)] =
                unit_normal(normal, x * st, y * st);
        }
    });
    auto ln = [&](int x, int y) -> const glm::vec3 & {
        return lnorm[std::size_t(y) * std::size_t(ow) + std::size_t(x)];
    };
    Image low = light;
    if (denoise) {
        parallel_for(0, oh, [&](int y) {
            for (int x = 0; x < ow; ++x) {
                const float z = lz(x, y);
                if (!(z > 0.0f)) {
                    continue;  // no surface: kept
                }
                const float inv = 1.0f / (0.1f * z);
                const glm::vec3 &n = ln(x, y);
                float sum[3] = {0.0f, 0.0f, 0.0f}, wsum = 0.0f;
                for (int j = std::max(0, y - 2); j <= std::min(oh - 1, y + 2); ++j) {
                    for (int i = std::max(0, x - 2); i <= std::min(ow - 1, x + 2); ++i) {
                        const float wt =
                            tent(std::abs(lz(i, j) - z), inv) * normal_weight(n, ln(i, j));
                        const float *v = light.pixel(i, j);
                        sum[0] += wt * v[0];
                        sum[1] += wt * v[1];
                        sum[2] += wt * v[2];
                        wsum += wt;
                    }
                }
                float *o = low.pixel(x, y);
                for (int c = 0; c < 3; ++c) {
                    o[c] = sum[c] / wsum;  // the centre's own weight is 1
                }
            }
        });
    }
    Image out(w, h, 3);
    parallel_for(0, h, [&](int y) {
        const int j0 = std::min(y / st, oh - 1), j1 = std::min(j0 + 1, oh - 1);
        const float fy = float(y - j0 * st) / float(st);
        const float *zrow = depth.pixel(0, y), *nrow = normal.pixel(0, y);
        const int nc = normal.channels();
        // Block by block: the four taps are the same for the pixels between two columns of
        // computed pixels.
        for (int i0 = 0; i0 < ow && i0 * st < w; ++i0) {
            const int i1 = std::min(i0 + 1, ow - 1);
            const int ti[4] = {i0, i1, i0, i1}, tj[4] = {j0, j0, j1, j1};
            float tz[4];
            glm::vec3 tn[4];
            const float *tv[4];
            for (int k = 0; k < 4; ++k) {
                tz[k] = lz(ti[k], tj[k]);
                tn[k] = ln(ti[k], tj[k]);
                tv[k] = low.pixel(ti[k], tj[k]);
            }
            for (int x = i0 * st; x < std::min(w, i0 * st + st); ++x) {
                const float z = zrow[x];
                if (!(z > 0.0f) || !std::isfinite(z)) {
                    continue;  // the sky: 0
                }
                const float fx = float(x - i0 * st) / float(st);
                const float inv = 1.0f / (0.1f * z);
                const float *np = nrow + std::size_t(x) * std::size_t(nc);
                const glm::vec3 n(np[0], np[1], np[2]);
                const float len2 = glm::dot(n, n);
                // max(0, n.m / |n|)^8 for a unit tap normal m; 1 where either is unknown.
                const bool known = len2 > 1e-12f && std::isfinite(len2);
                const float inv_len2 = known ? 1.0f / len2 : 0.0f;
                const float bw[4] = {
                    (1.0f - fx) * (1.0f - fy), fx * (1.0f - fy), (1.0f - fx) * fy, fx * fy};
                float sum[3] = {0.0f, 0.0f, 0.0f}, wsum = 0.0f, best = INFINITY;
                int nearest = 0;
                for (int k = 0; k < 4; ++k) {
                    const float dz = std::abs(tz[k] - z);
                    float nw = 1.0f;
                    if (known && tn[k] != glm::vec3(0.0f)) {
                        const float t = std::max(0.0f, glm::dot(n, tn[k]));
                        const float t2 = t * t * inv_len2;
                        nw = t2 * t2;
                        nw *= nw;
                    }
                    const float wt = bw[k] * tent(dz, inv) * nw;
                    sum[0] += wt * tv[k][0];
                    sum[1] += wt * tv[k][1];
                    sum[2] += wt * tv[k][2];
                    wsum += wt;
                    if (dz < best) {  // false for NaN
                        best = dz;
                        nearest = k;
                    }
                }
                float *o = out.pixel(x, y);
                if (wsum > 1e-6f) {
                    const float r = 1.0f / wsum;
                    for (int c = 0; c < 3; ++c) {
                        o[c] = sum[c] * r;
                    }
                } else if (best < INFINITY) {
                    for (int c = 0; c < 3; ++c) {
                        o[c] = tv[nearest][c];
                    }
                }
                if (apply) {
                    float k = apply->intensity;
                    if (apply->material && apply->material->channels() > 1) {
                        const float metal = apply->material->at(x, y, 1);
                        k *= std::isfinite(metal) ? 1.0f - std::clamp(metal, 0.0f, 1.0f) : 1.0f;
                    }
                    const float *a = apply->albedo->pixel(x, y);
                    const int na = apply->albedo->channels();
                    for (int c = 0; c < 3; ++c) {
                        o[c] = k * a[std::min(c, na - 1)] * std::max(0.0f, o[c]);
                    }
                }
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
