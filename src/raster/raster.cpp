#include "raster/raster.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/parallel.h"

namespace posthaste::raster {
namespace {

constexpr int kOne = 1 << kSubpixelBits;
constexpr int kHalf = kOne / 2;
// Guard band: clipped triangles stay within +-kGuard pixels, so fixed-point coordinates fit in
// 23 bits and edge-function products in 48 bits of an int64.
constexpr float kGuard = 16384.0f;
constexpr std::size_t kJobTriangles = 4096;

// floor(a / b) for b > 0.
std::int64_t floor_div(std::int64_t a, std::int64_t b)
{
    const std::int64_t q = a / b;
    return (a % b != 0 && a < 0) ? q - 1 : q;
}

struct SetupTri {
    std::int32_t x[3], y[3];     // fixed point
    float x0, y0, k0, kdx, kdy;  // key plane, relative to (x0, y0) in pixels
    int bx0, by0, bx1, by1;      // inclusive pixel bounds
    std::uint32_t id;
};

// Signed distance of v to clip plane i (>= 0 inside): 0 is W >= near_w, 1-4 the guard band
// |X / W| <= kGuard, |Y / W| <= kGuard.
float plane_dist(int i, const glm::vec4 &v, float near_w)
{
    switch (i) {
        case 0:
            return v.w - near_w;
        case 1:
            return v.x + kGuard * v.w;
        case 2:
            return kGuard * v.w - v.x;
        case 3:
            return v.y + kGuard * v.w;
        default:
            return kGuard * v.w - v.y;
    }
}

void setup_triangle(const glm::vec4 &a,
                    const glm::vec4 &b,
                    const glm::vec4 &c,
                    std::uint32_t id,
                    const RasterParams &rp,
                    std::vector<SetupTri> &out)
{
    const glm::vec4 v[3] = {a, b, c};
    float px[3], py[3], pk[3];
    std::int32_t fx[3], fy[3];
    for (int i = 0; i < 3; ++i) {
        const float inv = 1.0f / v[i].w;
        px[i] = v[i].x * inv;
        py[i] = v[i].y * inv;
        pk[i] = v[i].z * inv;
        fx[i] = std::int32_t(std::lrint(double(px[i]) * kOne));
        fy[i] = std::int32_t(std::lrint(double(py[i]) * kOne));
    }
    std::int64_t area = std::int64_t(fx[1] - fx[0]) * (fy[2] - fy[0]) -
                        std::int64_t(fy[1] - fy[0]) * (fx[2] - fx[0]);
    if (area == 0 || (area < 0 && rp.cull_backfaces)) {
        return;
    }
    int o1 = 1, o2 = 2;
    if (area < 0) {
        std::swap(o1, o2);
    }
    SetupTri t;
    const int order[3] = {0, o1, o2};
    for (int i = 0; i < 3; ++i) {
        t.x[i] = fx[order[i]];
        t.y[i] = fy[order[i]];
    }
    const int minx = std::min({t.x[0], t.x[1], t.x[2]}), maxx = std::max({t.x[0], t.x[1], t.x[2]});
    const int miny = std::min({t.y[0], t.y[1], t.y[2]}), maxy = std::max({t.y[0], t.y[1], t.y[2]});
    // Pixel px is a candidate when its centre px * kOne + kHalf lies in [min, max].
    t.bx0 = std::max(0, (minx - kHalf + kOne - 1) >> kSubpixelBits);
    t.by0 = std::max(0, (miny - kHalf + kOne - 1) >> kSubpixelBits);
    t.bx1 = std::min(rp.width - 1, (maxx - kHalf) >> kSubpixelBits);
    t.by1 = std::min(rp.height - 1, (maxy - kHalf) >> kSubpixelBits);
    if (t.bx0 > t.bx1 || t.by0 > t.by1) {
        return;
    }
    // Key plane through the three (unsnapped) vertices.
    const float e1x = px[1] - px[0], e1y = py[1] - py[0], e2x = px[2] - px[0], e2y = py[2] - py[0];
    const float det = e1x * e2y - e1y * e2x;
    if (det == 0.0f) {
        return;
    }
    const float dk1 = pk[1] - pk[0], dk2 = pk[2] - pk[0];
    t.kdx = (dk1 * e2y - dk2 * e1y) / det;
    t.kdy = (dk2 * e1x - dk1 * e2x) / det;
    t.x0 = px[0];
    t.y0 = py[0];
    t.k0 = pk[0];
    t.id = id;
    out.push_back(t);
}

// Sutherland-Hodgman against the near plane and the guard band, only for triangles that need it.
void clip_and_setup(const glm::vec4 &a,
                    const glm::vec4 &b,
                    const glm::vec4 &c,
                    std::uint32_t id,
                    const RasterParams &rp,
                    std::vector<SetupTri> &out)
{
    const glm::vec4 tri[3] = {a, b, c};
    unsigned all_out = 0x1f, any_out = 0;
    for (const glm::vec4 &v : tri) {
        unsigned o = 0;
        for (int p = 0; p < 5; ++p) {
            if (plane_dist(p, v, rp.near_w) < 0.0f) {
                o |= 1u << p;
            }
        }
        all_out &= o;
        any_out |= o;
    }
    if (all_out) {
        return;
    }
    if (!any_out) {
        setup_triangle(a, b, c, id, rp, out);
        return;
    }
    glm::vec4 poly[12], tmp[12];
    int n = 3;
    std::copy(tri, tri + 3, poly);
    for (int p = 0; p < 5 && n >= 3; ++p) {
        if (!(any_out & (1u << p))) {
            continue;
        }
        int m = 0;
        for (int i = 0; i < n; ++i) {
            const glm::vec4 &s = poly[i], &e = poly[(i + 1) % n];
            const float ds = plane_dist(p, s, rp.near_w), de = plane_dist(p, e, rp.near_w);
            if (ds >= 0.0f) {
                tmp[m++] = s;
            }
            if ((ds >= 0.0f) != (de >= 0.0f)) {
                const float t = ds / (ds - de);
                tmp[m++] = s + (e - s) * t;
            }
        }
        n = m;
        std::copy(tmp, tmp + n, poly);
    }
    for (int i = 1; i + 1 < n; ++i) {
        setup_triangle(poly[0], poly[i], poly[i + 1], id, rp, out);
    }
}

void raster_tile(const Rect &tile,
                 const std::vector<const SetupTri *> &bin,
                 const RasterParams &rp,
                 RasterTarget target)
{
    for (const SetupTri *tp : bin) {
        const SetupTri &t = *tp;
        const int x0 = std::max(t.bx0, tile.x0), x1 = std::min(t.bx1, tile.x1 - 1);
        const int y0 = std::max(t.by0, tile.y0), y1 = std::min(t.by1, tile.y1 - 1);
        if (x0 > x1 || y0 > y1) {
            continue;
        }
        std::int64_t A[3], B[3], E[3];
        const std::int64_t cx = std::int64_t(x0) * kOne + kHalf,
                           cy = std::int64_t(y0) * kOne + kHalf;
        for (int i = 0; i < 3; ++i) {
            const int j = (i + 1) % 3;
            A[i] = std::int64_t(t.y[i]) - t.y[j];
            B[i] = std::int64_t(t.x[j]) - t.x[i];
            // E(p) = A (p.x - x_i) + B (p.y - y_i): positive inside. Top-left rule: edges that
            // are neither left (A > 0) nor top (A == 0, B > 0) exclude their own pixels.
            const bool top_left = A[i] > 0 || (A[i] == 0 && B[i] > 0);
            E[i] = A[i] * (cx - t.x[i]) + B[i] * (cy - t.y[i]) - (top_left ? 0 : 1);
        }
        const std::int64_t step[3] = {A[0] * kOne, A[1] * kOne, A[2] * kOne};
        const int span = x1 - x0;
        for (int y = y0; y <= y1; ++y) {
            // The covered pixels of a row are one span: intersect, per edge, the steps k >= 0
            // from x0 where E + k step >= 0 (exact integer bounds, no per-pixel edge tests).
            int k0 = 0, k1 = span;
            for (int i = 0; i < 3; ++i) {
                if (step[i] > 0) {
                    if (E[i] < 0) {
                        k0 = std::max<std::int64_t>(k0, -floor_div(E[i], step[i]));
                    }
                } else if (step[i] < 0) {
                    k1 = int(std::min<std::int64_t>(k1, E[i] < 0 ? -1 : floor_div(E[i], -step[i])));
                } else if (E[i] < 0) {
                    k1 = -1;
                }
            }
            E[0] += B[0] * kOne;
            E[1] += B[1] * kOne;
            E[2] += B[2] * kOne;
            if (k0 > k1) {
                continue;
            }
            const float ky = t.k0 + t.kdy * (float(y) + 0.5f - t.y0);
            float *keys = target.keys + std::size_t(y) * std::size_t(rp.width);
            std::uint32_t *ids =
                target.ids ? target.ids + std::size_t(y) * std::size_t(rp.width) : nullptr;
            for (int x = x0 + k0; x <= x0 + k1; ++x) {
                const float k = ky + t.kdx * (float(x) + 0.5f - t.x0);
                if (k > keys[x]) {
                    keys[x] = k;
                    if (ids) {
                        ids[x] = t.id;
                    }
                }
            }
        }
    }
}

}  // namespace

RasterCounts rasterize_over(const std::vector<DrawBatch> &batches,
                            const RasterParams &rp,
                            RasterTarget target)
{
    RasterCounts counts;
    // Jobs: fixed triangle ranges, independent of the thread count.
    struct Job {
        const DrawBatch *batch;
        std::size_t begin, end;
    };
    std::vector<Job> jobs;
    for (const DrawBatch &b : batches) {
        counts.submitted += b.triangle_count;
        for (std::size_t i = 0; i < b.triangle_count; i += kJobTriangles) {
            jobs.push_back({&b, i, std::min(b.triangle_count, i + kJobTriangles)});
        }
    }
    std::vector<std::vector<SetupTri>> setup(jobs.size());
    parallel_for(0, int(jobs.size()), [&](int j) {
        const Job &job = jobs[std::size_t(j)];
        std::vector<SetupTri> &out = setup[std::size_t(j)];
        out.reserve(job.end - job.begin);
        for (std::size_t i = job.begin; i < job.end; ++i) {
            const glm::uvec3 &t = job.batch->triangles[i];
            clip_and_setup(job.batch->vertices[t.x],
                           job.batch->vertices[t.y],
                           job.batch->vertices[t.z],
                           job.batch->id_base + std::uint32_t(i),
                           rp,
                           out);
        }
    });
    const int tx = (rp.width + kRasterTile - 1) / kRasterTile;
    const int ty = (rp.height + kRasterTile - 1) / kRasterTile;
    std::vector<std::vector<const SetupTri *>> bins(std::size_t(tx) * std::size_t(ty));
    for (const std::vector<SetupTri> &job : setup) {
        counts.binned += job.size();
        for (const SetupTri &t : job) {
            const int x0 = t.bx0 / kRasterTile, x1 = t.bx1 / kRasterTile;
            const int y0 = t.by0 / kRasterTile, y1 = t.by1 / kRasterTile;
            for (int y = y0; y <= y1; ++y) {
                for (int x = x0; x <= x1; ++x) {
                    bins[std::size_t(y) * std::size_t(tx) + std::size_t(x)].push_back(&t);
                }
            }
        }
    }
    parallel_for_tiles(
        Rect{0, 0, rp.width, rp.height},
        [&](const Rect &tile) {
            const std::size_t b = std::size_t(tile.y0 / kRasterTile) * std::size_t(tx) +
                                  std::size_t(tile.x0 / kRasterTile);
            raster_tile(tile, bins[b], rp, target);
        },
        kRasterTile);
    return counts;
}

RasterCounts rasterize(const std::vector<DrawBatch> &batches,
                       const RasterParams &rp,
                       RasterTarget target)
{
    parallel_for(0, rp.height, [&](int y) {
        const std::size_t row = std::size_t(y) * std::size_t(rp.width);
        std::fill(target.keys + row,
                  target.keys + row + std::size_t(rp.width),
                  -std::numeric_limits<float>::infinity());
        if (target.ids) {
            std::fill(target.ids + row, target.ids + row + std::size_t(rp.width), kNoTriangle);
        }
    });
    return rasterize_over(batches, rp, target);
}

}  // namespace posthaste::raster
