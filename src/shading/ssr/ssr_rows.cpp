// The ssr node's pixel set-up and its resolve (see ssr_rows.h).

#include "shading/ssr/ssr_rows.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>

#include "core/parallel.h"
#include "shading/lighting/env_brdf.h"
#include "shading/lighting/lighting.h"

namespace posthaste::shading::ssr_detail {

std::optional<GlossyPixel> glossy_pixel(
    const SsrInputs &in, const CameraRays &rays, const SsrParams &p, int x, int y, bool with_point)
{
    const Image &depth = *in.depth, &normal = *in.normal, &albedo = *in.albedo,
                &material = *in.material;
    GlossyPixel g;
    g.z = depth.at(x, y, 0);
    g.roughness = material.at(x, y, 0);
    // Sky, and surfaces too rough to reflect more than the ambient: nothing to do.
    if (!(g.z > 0.0f) || !std::isfinite(g.z) || !(g.roughness <= p.max_roughness)) {
        return std::nullopt;
    }
    g.n = glm::vec3(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
    const float nlen = glm::length(g.n);
    if (!(nlen > 0.0f)) {
        return std::nullopt;
    }
    g.n /= nlen;
    const float u = (float(x) + 0.5f) / float(depth.width());
    const float v = (float(y) + 0.5f) / float(depth.height());
    if (with_point) {  // the march's start; the resolve needs only the weight
        g.point = rays.position() + rays.depth_ray(u, v) * g.z;
    }
    g.view = -rays.direction(u, v);
    if (glm::dot(g.n, g.view) < 0.0f) {
        g.n = -g.n;  // as the renderer: the side we see
    }
    Surface surf;
    surf.albedo = glm::vec3(albedo.at(x, y, 0), albedo.at(x, y, 1), albedo.at(x, y, 2));
    surf.roughness = g.roughness;
    surf.metallic = material.at(x, y, 1);
    // The rasterizer's weight is 0 from roughness 0.776 (it reflects the ambient alone there);
    // a GGX lobe's is not.
    g.weight =
        p.ggx ? ggx_reflection_weight(surf, g.n, g.view) : sky_reflection_weight(surf, g.n, g.view);
    if (g.weight == glm::vec3(0.0f)) {
        return std::nullopt;
    }
    return g;
}

std::size_t soa_arrays(std::vector<float> &buf, std::size_t n, int arrays, int inputs)
{
    const std::size_t pitch = n + kSsrStepPad;
    if (buf.size() < std::size_t(arrays) * pitch) {
        buf.resize(std::size_t(arrays) * pitch);
    }
    for (int c = 0; c < inputs; ++c) {
        std::fill_n(buf.data() + std::size_t(c) * pitch + n, kSsrStepPad, 0.0f);
    }
    return pitch;
}

SsrWeightRow weight_row_inputs(const SsrInputs &in,
                               const CameraRays &rays,
                               const SsrParams &p,
                               int y,
                               int step,
                               int count,
                               float *const ch[9])
{
    const Image &depth = *in.depth, &normal = *in.normal, &albedo = *in.albedo,
                &material = *in.material;
    const float *zr = depth.pixel(0, y), *nr = normal.pixel(0, y), *ar = albedo.pixel(0, y),
                *mr = material.pixel(0, y);
    const std::size_t zc = std::size_t(depth.channels()) * std::size_t(step),
                      nc = std::size_t(normal.channels()) * std::size_t(step),
                      ac = std::size_t(albedo.channels()) * std::size_t(step),
                      mc = std::size_t(material.channels()) * std::size_t(step);
    for (int i = 0; i < count; ++i) {
        const std::size_t k = std::size_t(i);
        ch[0][i] = zr[k * zc];
        for (int c = 0; c < 3; ++c) {
            ch[1 + c][i] = nr[k * nc + std::size_t(c)];
            ch[4 + c][i] = ar[k * ac + std::size_t(c)];
        }
        ch[7][i] = mr[k * mc];
        ch[8][i] = mr[k * mc + 1];
    }
    for (int c = 0; c < 9; ++c) {
        std::fill(ch[c] + count, ch[c] + count + kSsrStepPad, 0.0f);
    }
    SsrWeightRow r;
    r.z = ch[0];
    r.nx = ch[1];
    r.ny = ch[2];
    r.nz = ch[3];
    r.ar = ch[4];
    r.ag = ch[5];
    r.ab = ch[6];
    r.roughness = ch[7];
    r.metallic = ch[8];
    r.n = count;
    r.width = depth.width();
    r.stride = step;
    r.v = (float(y) + 0.5f) / float(depth.height());
    for (int c = 0; c < 3; ++c) {
        r.origin[c] = rays.ray_origin()[c];
        r.du[c] = rays.ray_du()[c];
        r.dv[c] = rays.ray_dv()[c];
    }
    r.max_roughness = p.max_roughness;
    r.ggx_table = p.ggx ? ggx_albedo_table() : nullptr;
    return r;
}

namespace {

/// A pixel's colour plus the reflection's change, held between 0 (or the colour, where it was
/// already below) and the largest float (or the colour, where it was already above): the sky
/// reflection the change takes away is a model's and can exceed what the renderer left there,
/// and two huge finite values must not add up to infinity.
inline void add_change(float &v, float d)
{
    const float r = v + d;
    const float lo = std::min(v, 0.0f), hi = std::max(v, std::numeric_limits<float>::max());
    v = r < lo ? lo : (r > hi ? hi : r);
}

}  // namespace

Image resolve(const SsrInputs &in,
              const SsrParams &p,
              const CameraRays &rays,
              const CellRows &cells,
              int stride,
              bool vector_kernels)
{
    const Image &depth = *in.depth, &normal = *in.normal;
    const int w = depth.width(), h = depth.height(), st = stride;
    // The resolve: each glossy pixel's change is the mean of the traced cells within `denoise`
    // pixels on the same surface (depth within 5 %, normals within 25 degrees), weighted by the
    // pixel's own Fresnel and gloss. The rays' noise falls by the number of cells averaged; the
    // blur is that of the window on sharp reflections.
    // The colour is copied row by row in the resolve, which then adds to the row in cache.
    const Image &color = *in.color;
    Image out = Image::uninitialized(w, h, color.channels());
    const std::size_t row_values = std::size_t(w) * std::size_t(color.channels());
    const int radius = st > 1 ? std::max(p.denoise, st) : p.denoise;
    parallel_for(0, h, [&](int y) {
        std::copy_n(color.pixel(0, y), row_values, out.pixel(0, y));
        // The row's reflection weights (0 where the pixel is left alone): on the vector
        // kernel from the row's channels side by side, or glossy_pixel's scalar reference.
        // The weights, then the row's channels (kept by each thread from row to row;
        // weight_row_inputs zeroes the channels' pads).
        thread_local std::vector<float> buf;
        const std::size_t row = soa_arrays(buf, std::size_t(w), 12, 0);
        float *wr = buf.data(), *wg = wr + row, *wb = wg + row;
        if (vector_kernels) {
            float *ch[9];
            for (int c = 0; c < 9; ++c) {
                ch[c] = buf.data() + std::size_t(3 + c) * row;
            }
            ssr_weight_row(weight_row_inputs(in, rays, p, y, 1, w, ch), wr, wg, wb);
        } else {
            std::fill(wr, wr + 3 * row, 0.0f);
            for (int x = 0; x < w; ++x) {
                if (const std::optional<GlossyPixel> g =
                        glossy_pixel(in, rays, p, x, y, /*with_point=*/false)) {
                    wr[x] = g->weight.x;
                    wg[x] = g->weight.y;
                    wb[x] = g->weight.z;
                }
            }
        }
        const int ty0 = (std::max(0, y - radius) + st - 1) / st;
        const int ty1 = std::min(h - 1, y + radius) / st;
        if (vector_kernels) {
            const float *rows[2 * 8 + 1];  // radius <= 8
            SsrResolveRow rr;
            rr.row_count = ty1 - ty0 + 1;
            for (int i = 0; i < rr.row_count; ++i) {
                rows[i] = cells.row(ty0 + i);
            }
            rr.rows = rows;
            rr.pitch = cells.pitch();
            rr.cell_x = cells.cell_x();
            rr.stride = st;
            rr.radius = radius;
            rr.z = buf.data() + 3 * row;
            rr.nx = rr.z + row;
            rr.ny = rr.nx + row;
            rr.nz = rr.ny + row;
            rr.wr = wr;
            rr.wg = wg;
            rr.wb = wb;
            rr.n = w;
            rr.intensity = p.intensity;
            // The outputs over the row's albedo and material arrays, which are read.
            float *dr = buf.data() + 7 * row, *dg = dr + row, *db = dg + row, *apply = db + row;
            ssr_resolve_row(rr, dr, dg, db, apply);
            for (int x = 0; x < w; ++x) {
                if (apply[x] != 0.0f) {
                    float *px = out.pixel(x, y);
                    add_change(px[0], dr[x]);
                    add_change(px[1], dg[x]);
                    add_change(px[2], db[x]);
                }
            }
            return;
        }
        for (int x = 0; x < w; ++x) {
            const glm::vec3 weight(wr[x], wg[x], wb[x]);
            if (weight == glm::vec3(0.0f)) {
                continue;
            }
            const float z = depth.at(x, y, 0);
            const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
            glm::vec3 sum(0.0f);
            float count = 0.0f;
            const int tx0 = (std::max(0, x - radius) + st - 1) / st;
            const int tx1 = std::min(w - 1, x + radius) / st;
            for (int ty = ty0; ty <= ty1; ++ty) {
                for (int tx = tx0; tx <= tx1; ++tx) {
                    // Within 5 % of the pixel's depth (never for a cell without an estimate).
                    const float cz = cells.at(tx, ty, 0);
                    if (!(std::abs(cz - z) <= 0.05f * z)) {
                        continue;
                    }
                    const glm::vec3 cn(
                        cells.at(tx, ty, 1), cells.at(tx, ty, 2), cells.at(tx, ty, 3));
                    if (glm::dot(cn, n) < 0.9f) {  // unit normals (zero where not finite)
                        continue;
                    }
                    sum += glm::vec3(cells.at(tx, ty, 4), cells.at(tx, ty, 5), cells.at(tx, ty, 6));
                    count += 1.0f;
                }
            }
            if (count == 0.0f) {
                continue;  // no traced neighbour on this surface
            }
            const glm::vec3 d = weight * (sum / count) * p.intensity;
            float *px = out.pixel(x, y);
            add_change(px[0], d.x);
            add_change(px[1], d.y);
            add_change(px[2], d.z);
        }
    });
    return out;
}

}  // namespace posthaste::shading::ssr_detail
