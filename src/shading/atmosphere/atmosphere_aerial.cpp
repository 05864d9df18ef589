// The aerial-perspective volume (froxels of in-scattering and transmittance along the view
// rays) and the frame pass that applies it and the sky; the Atmosphere it reads is
// atmosphere.cpp's.
#include <cassert>
#include <cstdint>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/atmosphere/atmosphere_kernels.h"
#include "shading/atmosphere/atmosphere_ray.h"

namespace posthaste::shading {

AerialPerspective::AerialPerspective(const Atmosphere &atmosphere,
                                     const glm::mat4 &world_to_camera,
                                     const glm::mat4 &world_to_ndc,
                                     const AerialPerspectiveSettings &settings)
    : settings_(settings), rays_(world_to_camera, world_to_ndc)
{
    build(atmosphere, nullptr);
}

AerialPerspective::AerialPerspective(const Atmosphere &atmosphere,
                                     const glm::mat4 &world_to_camera,
                                     const glm::mat4 &world_to_ndc,
                                     const AerialPerspectiveSettings &settings,
                                     const Image &depth)
    : settings_(settings), rays_(world_to_camera, world_to_ndc)
{
    // The deepest w = sqrt(distance / max) in each froxel column's cell of the frame, over rows
    // in parallel (a maximum: the same for any split). Sky and NaN depths read no froxel.
    const int cw = std::max(settings.width, 2), ch = std::max(settings.height, 2);
    const float max_distance = settings.max_distance > 0.0f ? settings.max_distance : 1.0f;
    const int w = depth.width(), h = depth.height();
    // Per row and column cell: the largest squared distance (z |ray|)^2; no root per pixel.
    std::vector<float> row_max(std::size_t(h) * std::size_t(cw), 0.0f);
    std::vector<int> cell_begin(std::size_t(cw) + 1, w);
    for (int x = w - 1; x >= 0; --x) {
        cell_begin[std::size_t(std::min(int((float(x) + 0.5f) / float(w) * float(cw)), cw - 1))] =
            x;
    }
    for (int cx = cw - 1; cx >= 0; --cx) {
        cell_begin[std::size_t(cx)] =
            std::min(cell_begin[std::size_t(cx)], cell_begin[std::size_t(cx) + 1]);
    }
    const float inv_w = 1.0f / float(w);  // a multiply per pixel, not a division
    parallel_for(0, h, [&](int y) {
        const float v = (float(y) + 0.5f) / float(h);
        const glm::vec3 r0 = rays_.depth_ray(0.0f, v), dr = rays_.depth_ray(1.0f, v) - r0;
        const float *z = depth.pixel(0, y);
        for (int cx = 0; cx < cw; ++cx) {
            float m = 0.0f;
            for (int x = cell_begin[std::size_t(cx)]; x < cell_begin[std::size_t(cx) + 1]; ++x) {
                const float u = (float(x) + 0.5f) * inv_w;
                const glm::vec3 r = r0 + u * dr;
                const float zz = z[x] > 0.0f && z[x] < std::numeric_limits<float>::infinity()
                                     ? z[x] * z[x]
                                     : 0.0f;  // sky and NaN read no froxel
                m = std::max(m, zz * glm::dot(r, r));
            }
            row_max[std::size_t(y) * std::size_t(cw) + std::size_t(cx)] =
                std::sqrt(std::min(std::sqrt(m) / max_distance, 1.0f));
        }
    });
    std::vector<float> cell(std::size_t(cw) * std::size_t(ch), 0.0f);
    for (int y = 0; y < h; ++y) {
        const int cy = std::min(int((float(y) + 0.5f) / float(h) * float(ch)), ch - 1);
        for (int cx = 0; cx < cw; ++cx) {
            float &c = cell[std::size_t(cy) * std::size_t(cw) + std::size_t(cx)];
            c = std::max(c, row_max[std::size_t(y) * std::size_t(cw) + std::size_t(cx)]);
        }
    }
    // A pixel in cell (cx, cy) interpolates columns cx - 1 .. cx + 1 (and rows likewise) and the
    // slices z0, z0 + 1 with z0 = int(w slices - 0.5): each column keeps the slices up to one past
    // the deepest z0 of its neighbouring cells (float rounding margin: one slice more).
    const int slices = std::max(settings.slices, 2);
    std::vector<int> last(std::size_t(cw) * std::size_t(ch), 0);
    for (int y = 0; y < ch; ++y) {
        for (int x = 0; x < cw; ++x) {
            float wmax = 0.0f;
            for (int j = std::max(y - 1, 0); j <= std::min(y + 1, ch - 1); ++j) {
                for (int i = std::max(x - 1, 0); i <= std::min(x + 1, cw - 1); ++i) {
                    wmax = std::max(wmax, cell[std::size_t(j) * std::size_t(cw) + std::size_t(i)]);
                }
            }
            const int z0 = std::max(int(wmax * float(slices) - 0.5f), 0);
            last[std::size_t(y) * std::size_t(cw) + std::size_t(x)] = std::min(z0 + 2, slices - 1);
        }
    }
    build(atmosphere, &last);
}

void AerialPerspective::build(const Atmosphere &atmosphere, const std::vector<int> *last_slice)
{
    const AerialPerspectiveSettings &settings = settings_;
    width_ = std::max(settings.width, 2);
    height_ = std::max(settings.height, 2);
    slices_ = std::max(settings.slices, 2);
    const int steps = std::max(settings.steps_per_slice, 1);
    const float max_distance = settings.max_distance > 0.0f ? settings.max_distance : 1.0f;
    settings_.max_distance = max_distance;
    inv_max_distance_ = 1.0f / max_distance;
    inv_slices_ = 1.0f / float(slices_);
    inv_centre_sum_.resize(std::size_t(slices_));
    for (int k = 0; k < slices_; ++k) {
        inv_centre_sum_[k] = float(slices_) / (2.0f * float(k) + 2.0f);
    }
    froxels_.assign(std::size_t(width_) * height_ * slices_,
                    Froxel{{0.0f, 0.0f, 0.0f, 0.0f}, {1.0f, 1.0f, 1.0f, 1.0f}});

    const double bottom = atmosphere.bottom_, top = atmosphere.top_;
    const glm::dvec3 p = atmosphere.planet_position(rays_.position());
    const double len = glm::length(p);
    if (!std::isfinite(len) || !(len > 0.0)) {
        return;  // leaves (0, 1): no aerial perspective
    }
    const glm::dvec3 up = p / len;
    const double r0 = std::clamp(len, bottom, top);
    const glm::dvec3 sun(atmosphere.sun_direction());
    const double metres = atmosphere.params().metres_per_unit;
    froxels_built_ = 0;
    for (int index = 0; index < width_ * height_; ++index) {
        froxels_built_ += last_slice ? (*last_slice)[std::size_t(index)] + 1 : slices_;
    }
    parallel_for(0, width_ * height_, [&](int index) {
        const int x = index % width_, y = index / width_;
        const glm::dvec3 dir(
            rays_.direction((x + 0.5f) / float(width_), (y + 0.5f) / float(height_)));
        Atmosphere::Ray ray;
        ray.r0 = r0;
        ray.mu0 = std::clamp(glm::dot(up, dir), -1.0, 1.0);
        ray.mus0 = glm::dot(up, sun);
        ray.nu = glm::dot(dir, sun);
        ray.phase_rayleigh = rayleigh_phase(float(ray.nu));
        ray.phase_mie = cornette_shanks_phase(float(ray.nu), atmosphere.params().mie_g);
        // Departure from the paper: froxels are not stopped at the planet; below it the medium
        // reads as ground-level air, since the depth pass decides where the scene ends.
        const double t_top = distance_to_sphere(r0, ray.mu0, top);
        ScatteringResult acc;
        double t_prev = 0.0;
        const int last = last_slice ? (*last_slice)[std::size_t(index)] : slices_ - 1;
        for (int k = 0; k <= last; ++k) {
            const double t = std::min(double(slice_distance(k)) * metres, t_top);
            acc = atmosphere.integrate(ray, t_prev, t, steps, acc, 0);
            t_prev = std::max(t_prev, t);
            froxels_[(std::size_t(k) * height_ + y) * width_ + x] =
                Froxel{{acc.inscatter.x, acc.inscatter.y, acc.inscatter.z, 0.0f},
                       {acc.transmittance.x, acc.transmittance.y, acc.transmittance.z, 1.0f}};
        }
    });
}

float AerialPerspective::slice_distance(int k) const
{
    const float w = (float(k) + 0.5f) / float(slices_);
    return settings_.max_distance * w * w;
}

/// Fills the kernels' parameters from the classes' private members.
struct AtmosphereKernels {
    static SkyCoordParams sky(const SkyView &v)
    {
        SkyCoordParams p;
        p.lut = v.lut_.data();
        p.lut_width = v.lut_.width();
        p.lut_height = v.lut_.height();
        for (int i = 0; i < 3; ++i) {
            p.up[i] = v.up_[i];
            p.sun_tangent[i] = v.sun_tangent_[i];
            p.sun_side[i] = v.sun_side_[i];
        }
        p.mu_horizon = v.mu_horizon_;
        p.theta_horizon = v.theta_horizon_;
        p.inv_theta_above = v.inv_theta_above_;
        p.inv_theta_below = v.inv_theta_below_;
        return p;
    }
    static void volume(const AerialPerspective &ap, AtmosphereRowParams &p)
    {
        static_assert(sizeof(AerialPerspective::Froxel) == 8 * sizeof(float));
        p.froxels = ap.froxels_.front().inscatter;
        p.ap_width = ap.width_;
        p.ap_height = ap.height_;
        p.slices = ap.slices_;
        p.inv_max_distance = ap.inv_max_distance_;
        p.inv_slices = ap.inv_slices_;
        p.inv_centre_sum = ap.inv_centre_sum_.data();
    }
};

SkyCoordParams SkyView::coord_params() const
{
    return AtmosphereKernels::sky(*this);
}

void SkyView::radiance_n(
    const float *x, const float *y, const float *z, int n, glm::vec3 *out) const
{
    static_assert(sizeof(glm::vec3) == 3 * sizeof(float));
    sky_view_radiance(AtmosphereKernels::sky(*this), x, y, z, n, &out->x);
}

namespace {

// Aerial perspective on finite depths; with `atmosphere` and `sky`, the sky on infinite ones.
void apply_frame(const Atmosphere *atmosphere,
                 const SkyView *sky,
                 const AerialPerspective &ap,
                 const Image &depth,
                 const Image &source,
                 Image &color,
                 bool sun_disc)
{
    assert(source.width() == color.width() && source.height() == color.height() &&
           source.channels() == color.channels());
    const bool copy = &source != &color;
    assert(color.channels() >= 3 && depth.channels() == 1);
    assert(color.width() == depth.width() && color.height() == depth.height());
    const float inv_w = 1.0f / float(color.width());
    const float inv_h = 1.0f / float(color.height());
    const int channels = color.channels();
    const CameraRays &rays = ap.rays();
    const glm::vec3 sun = atmosphere ? atmosphere->sun_direction() : glm::vec3(0.0f);
    const float cos_sun = atmosphere ? std::cos(atmosphere->params().sun_angular_radius_rad) : 2.0f;
    AtmosphereRowParams base;
    base.inv_w = inv_w;
    AtmosphereKernels::volume(ap, base);
    base.sky = sky != nullptr;
    if (sky) {
        base.sky_coords = AtmosphereKernels::sky(*sky);
    }
    base.sun_disc = sun_disc && atmosphere;
    for (int i = 0; i < 3; ++i) {
        base.sun[i] = sun[i];
    }
    base.cos_sun = cos_sun;
    const int w = color.width();
    // Bands of whole rows: the pass streams through memory, which a 64-pixel tile row (1 KiB of
    // RGBA) is too short for.
    const int band = 4, bands = (color.height() + band - 1) / band;
    parallel_for(0, bands, [&](int b) {
        const std::size_t n = std::size_t(w);
        std::vector<std::int32_t> disc_x(base.sun_disc ? n : 0);
        std::vector<float> disc_dir(base.sun_disc ? 3 * n : 0);
        AtmosphereRowParams r = base;
        for (int y = b * band; y < std::min(color.height(), (b + 1) * band); ++y) {
            float *row = color.pixel(0, y);
            if (copy) {  // then in place, in cache
                std::memcpy(row, source.pixel(0, y), sizeof(float) * n * std::size_t(channels));
            }
            const float v = (float(y) + 0.5f) * inv_h;
            const glm::vec3 origin = rays.depth_ray(0.0f, v);
            const glm::vec3 du = rays.depth_ray(1.0f, v) - origin;
            for (int i = 0; i < 3; ++i) {
                r.origin[i] = origin[i];
                r.du[i] = du[i];
            }
            ap.row_weights(v, r.cy, r.ty);
            const int listed = atmosphere_row(
                r, depth.pixel(0, y), row, channels, w, disc_x.data(), disc_dir.data());
            // The sun's disc over the sky the kernel wrote.
            for (int i = 0; i < listed; ++i) {
                const std::size_t k = std::size_t(i);
                const glm::vec3 l = atmosphere->sun_disc_radiance(
                    glm::vec3(disc_dir[3 * k], disc_dir[3 * k + 1], disc_dir[3 * k + 2]),
                    rays.position());
                float *px = row + std::size_t(disc_x[k]) * std::size_t(channels);
                px[0] += l.x;
                px[1] += l.y;
                px[2] += l.z;
            }
        }
    });
}

}  // namespace

void apply_atmosphere(const Atmosphere &atmosphere,
                      const SkyView &sky,
                      const AerialPerspective &ap,
                      const Image &depth,
                      Image &color,
                      bool sun_disc)
{
    apply_frame(&atmosphere, &sky, ap, depth, color, color, sun_disc);
}

void apply_atmosphere(const Atmosphere &atmosphere,
                      const SkyView &sky,
                      const AerialPerspective &ap,
                      const Image &depth,
                      const Image &source,
                      Image &color,
                      bool sun_disc)
{
    apply_frame(&atmosphere, &sky, ap, depth, source, color, sun_disc);
}

void apply_aerial_perspective(const AerialPerspective &ap, const Image &depth, Image &color)
{
    apply_frame(nullptr, nullptr, ap, depth, color, color, false);
}

}  // namespace posthaste::shading
