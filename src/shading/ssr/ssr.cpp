// Screen-space reflections (see ssr.h).

#include "shading/ssr/ssr.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <glm/geometric.hpp>
#include <optional>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"
#include "core/simd.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/atmosphere/atmosphere_kernels.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"
#include "shading/lighting/lighting.h"
#include "shading/ssr/ssr_kernels.h"
#include "shading/ssr/ssr_march.h"
#include "shading/ssr/ssr_rows.h"

namespace posthaste::shading {
namespace {

using ssr_detail::CellRows;
using ssr_detail::glossy_pixel;
using ssr_detail::GlossyPixel;
using ssr_detail::Marcher;
using ssr_detail::RaySegment;
using ssr_detail::ScreenPoint;
using ssr_detail::soa_arrays;
using ssr_detail::weight_row_inputs;

}  // namespace

namespace {

/// The scene sky's radiance (SceneSky::radiance, no sun disc) of unit directions: the sky-view
/// table on the vector kernel (the same bits), the ground's share after it.
class SkyLookup {
   public:
    SkyLookup(const SceneSky &sky, bool vector_kernels)
        : sky_(sky),
          lut_(sky.atmosphere().cached_sky_view().coord_params()),
          vector_kernels_(vector_kernels)
    {
    }

    void operator()(const std::vector<glm::vec3> &dirs, std::vector<glm::vec3> &values) const
    {
        values.resize(dirs.size());
        if (!vector_kernels_) {
            for (std::size_t i = 0; i < dirs.size(); ++i) {
                values[i] = sky_.radiance(dirs[i], camera_, false);
            }
            return;
        }
        thread_local std::vector<float> soa;
        const std::size_t n = dirs.size(), pitch = soa_arrays(soa, n, 6, 3);
        for (std::size_t i = 0; i < n; ++i) {
            soa[i] = dirs[i].x;
            soa[pitch + i] = dirs[i].y;
            soa[2 * pitch + i] = dirs[i].z;
        }
        ssr_sky_view_radiance(lut_,
                              soa.data(),
                              soa.data() + pitch,
                              soa.data() + 2 * pitch,
                              int(n),
                              soa.data() + 3 * pitch,
                              soa.data() + 4 * pitch,
                              soa.data() + 5 * pitch);
        for (std::size_t i = 0; i < n; ++i) {
            values[i] = glm::vec3(soa[3 * pitch + i], soa[4 * pitch + i], soa[5 * pitch + i]) +
                        sky_.ground(dirs[i], camera_);
        }
    }

   private:
    const SceneSky &sky_;
    const SkyCoordParams lut_;
    const bool vector_kernels_;
    const glm::vec3 camera_{0.0f, kSkyCameraY, 0.0f};
};

/// The march's grid: 1 / z of each gs x gs cell's nearest surface (the sky's +inf is 0), gw x gh
/// cells. The march compares in 1 / z (no division per step); at half resolution and below a
/// quarter of the memory the rays wander through. Coarser cells would merge surfaces that the
/// rays must tell apart (the balls' silhouettes, thin features).
std::vector<float> nearest_inverse_depth(const Image &depth, int gs, int gw, int gh)
{
    const int w = depth.width(), h = depth.height();
    std::vector<float> inv_depth(std::size_t(gw) * std::size_t(gh));
    parallel_for(0, gh, [&](int gy) {
        for (int gx = 0; gx < gw; ++gx) {
            float inv = 0.0f;
            for (int y = gy * gs; y < std::min(h, gy * gs + gs); ++y) {
                for (int x = gx * gs; x < std::min(w, gx * gs + gs); ++x) {
                    const float z = depth.at(x, y, 0);
                    inv = std::max(inv, z > 0.0f ? 1.0f / z : 0.0f);
                }
            }
            inv_depth[std::size_t(gy) * std::size_t(gw) + std::size_t(gx)] = inv;
        }
    });
    return inv_depth;
}

/// What every traced row reads (shared, read-only but for `cells`, whose rows are its own).
struct TraceContext {
    const SsrInputs &in;
    const SsrParams &p;
    const CameraRays &rays;
    const Marcher &marcher;
    const SkyLookup &sky;
    CellRows &cells;
    bool vector_kernels;
    int st, tw;
    std::size_t step_pitch;
    SsrSegmentCamera segment_camera;
};

/// A row's glossy pixels traced in batches of about kBatchRays rays, in three passes: each
/// ray's segment; the depth tests of every ray's steps (the vector kernel), whose reads of the
/// depth grid, mostly cache misses, overlap when the rays follow each other without waiting on
/// their results; then each ray's crossings and what it meets, summed per pixel in the rays'
/// order.
class RowTracer {
   public:
    static constexpr int kBatchRays = 64;

    RowTracer(const TraceContext &cx, int ty) : cx_(cx), ty_(ty), y_(ty * cx.st)
    {
        if (cx_.vector_kernels) {
            ts_.resize(std::size_t(kBatchRays + cx_.p.rays) * cx_.step_pitch);
            crossed_.resize(ts_.size());
        }
    }

    /// Every traced pixel of the row; their cells written, the counts added up.
    void trace();

    long long pixels = 0, rays = 0, hits = 0;

   private:
    struct Ray {
        int pixel;  // in the batch
        glm::vec3 l;
        float nl, jitter;
        RaySegment seg;
        glm::vec4 hit{0.0f};
        int sky = -1;  // its sky direction's index, where it needs one
    };
    struct Candidate {  // a ray drawn, before its direction is known
        int pixel;
        float u1, u2, jitter;
    };
    struct Pixel {
        int x;
        GlossyPixel g;
        glm::vec3 origin;
        float alpha;
        glm::vec3 sum{0.0f};
        float wsum = 0.0f;
        int sky = -1;
    };

    void flush();
    void draw_directions();
    void march_batch();
    void meet();
    void resolve_pixels();

    const TraceContext &cx_;
    const int ty_, y_;
    std::vector<Candidate> candidates_;
    std::vector<Ray> batch_rays_;
    std::vector<Pixel> batch_pixels_;
    std::vector<float> ts_, crossed_;
    std::vector<glm::vec3> sky_dirs_, sky_values_;
    std::vector<float> seg_soa_, ggx_soa_;
};

/// The candidates' directions from the GGX lobe (ggx_reflection_twin, or its vector kernel, the
/// same bits); those below the surface are dropped.
void RowTracer::draw_directions()
{
    const std::size_t nc = candidates_.size(), cpitch = soa_arrays(ggx_soa_, nc, 13, 9);
    float *gin[9], *gout[4];
    for (int c = 0; c < 9; ++c) {
        gin[c] = ggx_soa_.data() + std::size_t(c) * cpitch;
    }
    for (int c = 0; c < 4; ++c) {
        gout[c] = ggx_soa_.data() + std::size_t(9 + c) * cpitch;
    }
    for (std::size_t k = 0; k < nc; ++k) {
        const Candidate &cand = candidates_[k];
        const Pixel &px = batch_pixels_[std::size_t(cand.pixel)];
        for (int c = 0; c < 3; ++c) {
            gin[c][k] = px.g.n[c];
            gin[3 + c][k] = px.g.view[c];
        }
        gin[6][k] = px.alpha;
        gin[7][k] = cand.u1;
        gin[8][k] = cand.u2;
    }
    if (cx_.vector_kernels) {
        ssr_ggx_rays(gin, int(nc), gout);
    } else {
        for (std::size_t k = 0; k < nc; ++k) {
            const float n[3] = {gin[0][k], gin[1][k], gin[2][k]};
            const float v[3] = {gin[3][k], gin[4][k], gin[5][k]};
            float l[3];
            ggx_reflection_twin(n, v, gin[6][k], gin[7][k], gin[8][k], l);
            for (int c = 0; c < 3; ++c) {
                gout[c][k] = l[c];
            }
            gout[3][k] = (n[0] * l[0] + n[1] * l[1]) + n[2] * l[2];
        }
    }
    batch_rays_.clear();
    for (std::size_t k = 0; k < nc; ++k) {
        const float nl = gout[3][k];
        if (!(nl > 0.0f)) {
            continue;
        }
        ++rays;
        const Candidate &cand = candidates_[k];
        const glm::vec3 l(gout[0][k], gout[1][k], gout[2][k]);
        // The segment now on the scalar path, for the whole batch below on the vector one.
        batch_rays_.push_back(
            Ray{cand.pixel,
                l,
                nl,
                cand.jitter,
                cx_.vector_kernels
                    ? RaySegment{}
                    : cx_.marcher.segment(batch_pixels_[std::size_t(cand.pixel)].origin, l)});
    }
    candidates_.clear();
}

/// The vector path: the rays' segments together (ssr_segments: segment()'s bits), then the
/// depth tests of every ray's steps.
void RowTracer::march_batch()
{
    const std::size_t n = batch_rays_.size(), pitch = soa_arrays(seg_soa_, n, 15, 6);
    for (std::size_t k = 0; k < n; ++k) {
        const Ray &ray = batch_rays_[k];
        const glm::vec3 &o = batch_pixels_[std::size_t(ray.pixel)].origin;
        for (int c = 0; c < 3; ++c) {
            seg_soa_[std::size_t(c) * pitch + k] = o[c];
            seg_soa_[std::size_t(3 + c) * pitch + k] = ray.l[c];
        }
    }
    float *out[9];
    for (int c = 0; c < 9; ++c) {
        out[c] = seg_soa_.data() + std::size_t(6 + c) * pitch;
    }
    ssr_segments(cx_.segment_camera,
                 seg_soa_.data(),
                 seg_soa_.data() + pitch,
                 seg_soa_.data() + 2 * pitch,
                 seg_soa_.data() + 3 * pitch,
                 seg_soa_.data() + 4 * pitch,
                 seg_soa_.data() + 5 * pitch,
                 int(n),
                 out);
    for (std::size_t k = 0; k < n; ++k) {
        RaySegment &seg = batch_rays_[k].seg;
        seg.steps = int(out[8][k]);
        if (seg.steps > 0) {
            seg.a = ScreenPoint{out[0][k], out[1][k], out[2][k]};
            seg.b = ScreenPoint{out[3][k], out[4][k], out[5][k]};
            seg.t_start = out[6][k];
            seg.t_end = out[7][k];
        }
    }
    for (std::size_t k = 0; k < batch_rays_.size(); ++k) {
        const Ray &ray = batch_rays_[k];
        if (ray.seg.steps > 0) {
            ssr_march_steps(cx_.marcher.grid(),
                            cx_.marcher.kernel_segment(ray.seg, ray.jitter),
                            ts_.data() + k * cx_.step_pitch,
                            crossed_.data() + k * cx_.step_pitch);
        }
    }
}

/// What each ray meets; the sky where it meets nothing on screen (or only partly, near the
/// edges), looked up with each pixel's mirror direction together afterwards.
void RowTracer::meet()
{
    sky_dirs_.clear();
    for (std::size_t k = 0; k < batch_rays_.size(); ++k) {
        Ray &ray = batch_rays_[k];
        ray.hit = glm::vec4(0.0f);  // the sky, for a ray with no segment on screen
        if (ray.seg.steps > 0) {
            ray.hit = cx_.vector_kernels
                          ? cx_.marcher.march_result(ray.seg,
                                                     ray.l,
                                                     ts_.data() + k * cx_.step_pitch,
                                                     crossed_.data() + k * cx_.step_pitch)
                          : cx_.marcher.march(ray.seg, ray.l, ray.jitter);
        }
        if (ray.hit.w < 1.0f && !cx_.in.environment) {
            ray.sky = int(sky_dirs_.size());
            sky_dirs_.push_back(ray.l);
        }
        batch_pixels_[std::size_t(ray.pixel)].wsum += ray.nl;
        hits += ray.hit.w > 0.0f ? 1 : 0;
    }
    for (Pixel &px : batch_pixels_) {
        if (px.wsum > 0.0f && !cx_.in.world) {
            px.sky = int(sky_dirs_.size());
            sky_dirs_.push_back(glm::reflect(-px.g.view, px.g.n));
        }
    }
    cx_.sky(sky_dirs_, sky_values_);
}

/// Each pixel's rays summed, less what the sky gave it already: its cell for the resolve.
void RowTracer::resolve_pixels()
{
    for (const Ray &ray : batch_rays_) {
        glm::vec3 radiance(ray.hit);
        if (ray.hit.w < 1.0f) {  // the sky, for what the screen does not show
            const glm::vec3 sky_l =
                cx_.in.environment
                    ? cx_.in.environment->seen(batch_pixels_[std::size_t(ray.pixel)].origin, ray.l)
                    : sky_values_[std::size_t(ray.sky)] * cx_.p.sky_scale;
            radiance = sky_l + (radiance - sky_l) * ray.hit.w;
        }
        batch_pixels_[std::size_t(ray.pixel)].sum += radiance * ray.nl;
    }
    const Image &normal = *cx_.in.normal;
    for (const Pixel &px : batch_pixels_) {
        if (!(px.wsum > 0.0f)) {
            continue;
        }
        const GlossyPixel &g = px.g;
        // What the colour pass reflected already: the sky model, or the renderer's world.
        const glm::vec3 reflected =
            cx_.in.world ? LatLongMap(*cx_.in.world).radiance(glm::reflect(-g.view, g.n))
                         : sky_values_[std::size_t(px.sky)] * cx_.p.sky_scale;
        const glm::vec3 change = px.sum / px.wsum - reflected;
        cx_.cells.set(px.x / cx_.st,
                      ty_,
                      {g.z,
                       normal.at(px.x, y_, 0),
                       normal.at(px.x, y_, 1),
                       normal.at(px.x, y_, 2),
                       change.x,
                       change.y,
                       change.z});
    }
}

void RowTracer::flush()
{
    draw_directions();
    if (cx_.vector_kernels) {
        march_batch();
    }
    meet();
    resolve_pixels();
    batch_rays_.clear();
    batch_pixels_.clear();
}

void RowTracer::trace()
{
    const SsrParams &p = cx_.p;
    const int tw = cx_.tw, y = y_;
    // The traced pixels' set-up (glossy_pixel) on the weight kernel, the same bits: their
    // weights, normals, view directions and points side by side.
    thread_local std::vector<float> setup;
    float *sw[3] = {}, *sn[3] = {}, *sv[3] = {}, *sp[3] = {}, *sin[9] = {};
    if (cx_.vector_kernels) {
        // (weight_row_inputs zeroes its inputs' pads.)
        const std::size_t spitch = soa_arrays(setup, std::size_t(tw), 21, 0);
        for (int c = 0; c < 9; ++c) {
            sin[c] = setup.data() + std::size_t(c) * spitch;
        }
        for (int c = 0; c < 3; ++c) {
            sw[c] = setup.data() + std::size_t(9 + c) * spitch;
            sn[c] = setup.data() + std::size_t(12 + c) * spitch;
            sv[c] = setup.data() + std::size_t(15 + c) * spitch;
            sp[c] = setup.data() + std::size_t(18 + c) * spitch;
        }
        SsrWeightRow r = weight_row_inputs(cx_.in, cx_.rays, p, y, cx_.st, tw, sin);
        for (int c = 0; c < 3; ++c) {
            r.position[c] = cx_.rays.position()[c];
            r.n_out[c] = sn[c];
            r.view_out[c] = sv[c];
            r.point_out[c] = sp[c];
        }
        ssr_weight_row(r, sw[0], sw[1], sw[2]);
    }
    for (int tx = 0; tx < tw; ++tx) {
        const int x = tx * cx_.st;
        std::optional<GlossyPixel> g;
        if (!cx_.vector_kernels) {
            g = glossy_pixel(cx_.in, cx_.rays, p, x, y);
        } else if (sw[0][tx] != 0.0f || sw[1][tx] != 0.0f || sw[2][tx] != 0.0f) {
            g = GlossyPixel{sin[0][tx],
                            sin[7][tx],
                            glm::vec3(sp[0][tx], sp[1][tx], sp[2][tx]),
                            glm::vec3(sn[0][tx], sn[1][tx], sn[2][tx]),
                            glm::vec3(sv[0][tx], sv[1][tx], sv[2][tx]),
                            glm::vec3(sw[0][tx], sw[1][tx], sw[2][tx])};
        }
        if (!g) {
            continue;
        }
        ++pixels;
        const float alpha = roughness_to_alpha(g->roughness);
        const int count =
            std::clamp(int(std::ceil(float(p.rays) * g->roughness / 0.35f)), 1, p.rays);
        // The origin leaves the surface by a fraction of its distance (depth precision).
        const glm::vec3 origin = g->point + g->n * (1e-3f * g->z + 1e-3f);
        const int pixel = int(batch_pixels_.size());
        batch_pixels_.push_back(Pixel{x, *g, origin, alpha});
        for (int i = 0; i < count; ++i) {
            // Stratified in the first coordinate (the lobe's angle from its axis).
            candidates_.push_back(
                Candidate{pixel,
                          (float(i) + hash_unit(x, y, 3 * i, p.seed)) / float(count),
                          hash_unit(x, y, 3 * i + 1, p.seed),
                          hash_unit(x, y, 3 * i + 2, p.seed)});
        }
        if (int(candidates_.size()) >= kBatchRays) {
            flush();
        }
    }
    flush();
}

}  // namespace

Image ssr(const SsrInputs &in, const SsrParams &p, SsrStats *stats)
{
    const Image &depth = *in.depth;
    const int w = depth.width(), h = depth.height();
    const int st = std::max(1, p.stride);
    // The traced grid: every st-th pixel in x and y.
    const int tw = (w + st - 1) / st, th = (h + st - 1) / st;
    const CameraRays rays(in.world_to_camera, in.world_to_ndc);
    // The vector kernels (the march's depth tests, the sky, the resolve's weights and window)
    // unless the scalar reference is asked for.
    const bool vector_kernels = simd::requested() != simd::Level::Scalar;
    const SkyLookup sky(scene_sky(p.sun_direction), vector_kernels);
    const int gs = std::min(st, 2);
    const int gw = (w + gs - 1) / gs, gh = (h + gs - 1) / gs;
    const std::vector<float> inv_depth = nearest_inverse_depth(depth, gs, gw, gh);
    const Marcher marcher(in, p, inv_depth.data(), gw, gh, gs);
    // Per traced cell what the resolve compares and averages (ssr_kernels.h, SsrResolveRow).
    CellRows cells(w, th, st);
    const TraceContext cx{in,
                          p,
                          rays,
                          marcher,
                          sky,
                          cells,
                          vector_kernels,
                          st,
                          tw,
                          std::size_t(p.steps + kSsrStepPad),
                          marcher.segment_camera()};
    std::atomic<long long> n_pixels{0}, n_rays{0}, n_hits{0};
    parallel_for(0, th, [&](int ty) {
        RowTracer row(cx, ty);
        row.trace();
        n_pixels += row.pixels;
        n_rays += row.rays;
        n_hits += row.hits;
    });
    Image out = ssr_detail::resolve(in, p, rays, cells, st, vector_kernels);
    if (stats) {
        stats->pixels = n_pixels;
        stats->rays = n_rays;
        stats->hits = n_hits;
    }
    return out;
}

}  // namespace posthaste::shading
