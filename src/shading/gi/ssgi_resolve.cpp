// The resolve of ssgi's reduced result (ssgi.h, ssgi_resolve): a depth- and normal-aware
// denoise at the reduced resolution, then the upsample to the depth pass's resolution, with the
// albedo folded in.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/sanitize.h"
#include "shading/gi/ssgi.h"
#include "shading/gi/ssgi_resolve_kernels.h"

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

/// The unit normal at (x, y) (non-finite components as 0), 0 where it is zero.
glm::vec3 unit_normal(const Image &normal, int x, int y)
{
    const glm::vec3 n(finite_or_zero(normal.at(x, y, 0)),
                      finite_or_zero(normal.at(x, y, 1)),
                      finite_or_zero(normal.at(x, y, 2)));
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
    // The unit normals as three floats a pixel, for the Highway rows.
    const float *lnf = reinterpret_cast<const float *>(lnorm.data());
    if (denoise) {
        parallel_for(0, oh, [&](int y) {
            const auto scalar = [&](int x) {
                const float z = lz(x, y);
                if (!(z > 0.0f)) {
                    return;  // no surface: kept
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
            };
            // The pixels whose 5 x 5 window lies inside the row through Highway's lanes (the
            // same bits), the two at each end here.
            int x = 0;
            if (ow >= 4) {
                for (; x < 2; ++x) {
                    scalar(x);
                }
                const SsgiDenoiseRow r{ld.data(), lnf, light.data(), ow, oh, y, low.pixel(0, y)};
                x = ssgi_denoise_row(r, 2, ow - 2);
            }
            for (; x < ow; ++x) {
                scalar(x);
            }
        });
    }
    // Every pixel is written below (the sky and pixels no tap reaches: 0), so the image is not
    // cleared first (a 25 MB pass at 1080p). The rows go through ssgi_upsample_row (Highway
    // lanes, the scalar loop's bits), the albedo after them.
    if (light.channels() != 3) {
        throw_runtime("ssgi_resolve: the reduced light has ", light.channels(), " channels, not 3");
    }
    if (apply && apply->color && apply->sum &&
        (apply->color->width() != w || apply->color->height() != h || apply->sum->width() != w ||
         apply->sum->height() != h || apply->sum->channels() != apply->color->channels())) {
        throw_runtime("ssgi_resolve: the colour to add to is not the depth pass's size");
    }
    Image out = Image::uninitialized(w, h, 3);
    // Per output column: the reduced columns left and right, and the horizontal weight.
    const std::size_t wn = std::size_t(w);
    std::vector<std::int32_t> col0(wn), col1(wn);
    std::vector<float> colf(wn);
    for (int x = 0; x < w; ++x) {
        const int i0 = std::min(x / st, ow - 1);
        col0[std::size_t(x)] = i0;
        col1[std::size_t(x)] = std::min(i0 + 1, ow - 1);
        colf[std::size_t(x)] = float(x - i0 * st) / float(st);
    }
    parallel_for(0, h, [&](int y) {
        const int j0 = std::min(y / st, oh - 1), j1 = std::min(j0 + 1, oh - 1);
        const int nc = normal.channels();
        SsgiUpsampleRow r;
        // The row's normal: read in place where it has three channels, else as planes.
        std::vector<float> planes;
        if (nc == 3) {
            r.n3 = normal.pixel(0, y);
        } else {
            planes.resize(3 * std::size_t(w));
            float *nx = planes.data(), *ny = nx + w, *nz = ny + w;
            const float *nrow = normal.pixel(0, y);
            for (int x = 0; x < w; ++x) {
                const float *np = nrow + std::size_t(x) * std::size_t(nc);
                nx[x] = np[0];
                ny[x] = nc > 1 ? np[1] : 0.0f;
                nz[x] = nc > 2 ? np[2] : 0.0f;
            }
            r.nx = nx;
            r.ny = ny;
            r.nz = nz;
        }
        r.z0 = ld.data() + std::size_t(j0) * std::size_t(ow);
        r.z1 = ld.data() + std::size_t(j1) * std::size_t(ow);
        r.n0 = lnf + 3 * std::size_t(j0) * std::size_t(ow);
        r.n1 = lnf + 3 * std::size_t(j1) * std::size_t(ow);
        r.v0 = low.pixel(0, j0);
        r.v1 = low.pixel(0, j1);
        r.fy = float(y - j0 * st) / float(st);
        r.z = depth.pixel(0, y);
        r.ow = ow;
        r.i0 = col0.data();
        r.i1 = col1.data();
        r.fx = colf.data();
        if (apply) {
            r.albedo = apply->albedo->pixel(0, y);
            r.na = apply->albedo->channels();
            r.intensity = apply->intensity;
            if (apply->material && apply->material->channels() > 1) {
                r.material = apply->material->pixel(0, y);
                r.mc = apply->material->channels();
            }
        }
        ssgi_upsample_row(r, w, out.pixel(0, y));
        if (apply && apply->color && apply->sum) {
            ssgi_add_row(apply->color->pixel(0, y),
                         out.pixel(0, y),
                         w,
                         apply->color->channels(),
                         apply->sum->pixel(0, y));
        }
    });
    return out;
}

void ssgi_add_row(const float *src, const float *light, int w, int nc, float *dst)
{
    constexpr float kTop = std::numeric_limits<float>::max();
    constexpr float kInf = std::numeric_limits<float>::infinity();
    // Channel counts known at compile time where they usually are (the loop vectorises).
    const auto add = [&]<int kNc>() {
        const int n = kNc > 0 ? kNc : nc;
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < n; ++c) {
                // The light is finite and not negative: a finite colour's sum can overflow
                // only upward, and stops at float's largest (NaN and infinities stay).
                const float v = src[x * n + c];
                const float sum = v + (c < 3 ? light[x * 3 + c] : 0.0f);
                dst[x * n + c] = std::min(sum, v == kInf ? kInf : kTop);
            }
        }
    };
    if (nc == 4) {
        add.template operator()<4>();
    } else if (nc == 3) {
        add.template operator()<3>();
    } else {
        add.template operator()<0>();
    }
}

}  // namespace posthaste::shading
