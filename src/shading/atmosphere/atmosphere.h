#pragma once
// Physically based sky and aerial perspective after Hillaire, "A Scalable and Production Ready Sky
// and Atmosphere Rendering Technique" (EGSR 2020): a transmittance LUT, a multiple-scattering LUT
// (the paper's isotropic second-order term summed as the series 1 / (1 - f_ms), eq. 5-9), a
// sky-view LUT with a non-linear latitude mapping and an aerial-perspective froxel volume.
//
// Geometry: the scene sits on the planet surface. World y is up, the planet centre is at
// (0, -(bottom_radius + ground_altitude + camera_offset), 0) in metres, so world y = 0 is at
// altitude ground_altitude + camera_offset. Scene units convert to metres with `metres_per_unit`.
//
// Units: radiances are per unit sun illuminance. With sun_illuminance = (1, 1, 1) (the default)
// the outputs are unitless radiance scales (sr^-1); set it in lux to get luminance-like values in
// cd/m^2 (nits). Phase functions: Rayleigh, and Cornette-Shanks for Mie (as in the paper).
//
// Departures from the paper: the earth shadow on the sun is softened over the sun disc; the
// sky-view LUT stores the sky above and below the horizon in separate halves that are never
// blended (no leak of ground in-scattering into the sky across the horizon); its azimuth
// coordinate is sin(azimuth / 2) from the sun, and its latitude mapping is quadratic in the angle
// from the horizon on each side (the paper's non-linear mapping, split at the horizon).

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "core/image.h"
#include "shading/camera_rays.h"
#include "shading/fast_math.h"

namespace posthaste::shading {

/// The planet, its atmosphere, the sun and the LUT sizes. Defaults: Earth, from the paper.
struct AtmosphereParams {
    float bottom_radius_m = 6360e3f;                                 ///< planet radius, metres
    float top_radius_m = 6460e3f;                                    ///< atmosphere top, metres
    glm::vec3 rayleigh_scattering{5.802e-6f, 13.558e-6f, 33.1e-6f};  ///< per metre, at sea level
    float rayleigh_scale_height_m = 8000.0f;
    glm::vec3 mie_scattering{3.996e-6f};  ///< per metre, at sea level
    glm::vec3 mie_extinction{4.440e-6f};  ///< per metre (scattering + absorption), at sea level
    float mie_scale_height_m = 1200.0f;
    float mie_g = 0.8f;                                           ///< Cornette-Shanks asymmetry
    glm::vec3 ozone_absorption{0.650e-6f, 1.881e-6f, 0.085e-6f};  ///< per metre, at the peak
    float ozone_center_m = 25000.0f;  ///< tent profile: 1 at the centre, 0 at +-width/2
    float ozone_width_m = 30000.0f;
    glm::vec3 ground_albedo{0.3f};  ///< Lambertian, used by the multiple-scattering LUT

    glm::vec3 sun_direction{0.0f, 1.0f, 0.0f};  ///< world, towards the sun (normalised on build)
    glm::vec3 sun_illuminance{1.0f};            ///< at the top of the atmosphere (see Units)
    float sun_angular_radius_rad = 0.004675f;   ///< 0.2678 degrees

    float ground_altitude_m = 0.0f;  ///< altitude of the scene's ground (world y = 0), metres
    float camera_offset_m = 1.0f;    ///< lifts the scene so y = 0 is not exactly on the planet
    float metres_per_unit = 1.0f;    ///< scene units to metres
    float sky_view_y = 1.7f;         ///< world y (scene units) of the cached sky-view LUT's camera

    int transmittance_width = 256;
    int transmittance_height = 64;
    int multi_scattering_size = 32;
    int sky_view_width = 192;
    int sky_view_height = 108;  ///< rows [0, h/2) above the horizon, the rest below
    int transmittance_steps = 128;
    int multi_scattering_directions = 64;
    int multi_scattering_steps = 24;
    int sky_view_steps = 48;
};

/// Rayleigh phase function (1/sr).
inline float rayleigh_phase(float cos_theta)
{
    return 3.0f / (16.0f * 3.14159265358979f) * (1.0f + cos_theta * cos_theta);
}

/// Cornette-Shanks phase function (1/sr), the paper's Mie phase.
inline float cornette_shanks_phase(float cos_theta, float g)
{
    const float g2 = g * g;
    const float denom = std::max(1.0f + g2 - 2.0f * g * cos_theta, 1e-8f);
    return 3.0f / (8.0f * 3.14159265358979f) * (1.0f - g2) * (1.0f + cos_theta * cos_theta) /
           ((2.0f + g2) * denom * std::sqrt(denom));
}

/// Clamp to [0, 1]; NaN goes to 0.
inline float saturate(float x)
{
    return x > 0.0f ? (x < 1.0f ? x : 1.0f) : 0.0f;
}

/// An RGB table with bilinear lookups. Sizes are >= 2 on both axes.
class Lut2D {
   public:
    Lut2D() = default;
    /// A zero-filled width x height table (plus one padding texel after the last, so that a
    /// four-float load of any texel stays inside the storage).
    Lut2D(int width, int height)
        : width_(width), height_(height), texels_(std::size_t(width) * std::size_t(height) + 1)
    {
    }
    int width() const { return width_; }    ///< texels per row
    int height() const { return height_; }  ///< rows
    /// The texels, row by row, three floats each, then one padding texel.
    const float *data() const { return &texels_.front().x; }
    /// Texel (x, y), unchecked.
    glm::vec3 &at(int x, int y) { return texels_[std::size_t(y) * std::size_t(width_) + x]; }
    /// Texel (x, y), unchecked.
    const glm::vec3 &at(int x, int y) const
    {
        return texels_[std::size_t(y) * std::size_t(width_) + x];
    }
    /// Bilinear lookup over rows [row0, row0 + rows). u = 0 and u = 1 hit the centres of the first
    /// and last column, v = 0 and v = 1 those of the first and last row of the range. Clamped;
    /// NaN reads as 0.
    glm::vec3 sample_rows(float u, float v, int row0, int rows) const
    {
        const float fx = saturate(u) * float(width_ - 1);
        const float fy = saturate(v) * float(rows - 1);
        const int x0 = std::min(int(fx), width_ - 2);
        const int y0 = std::min(int(fy), rows - 2);
        const float tx = fx - float(x0), ty = fy - float(y0);
        const glm::vec3 *p = &texels_[std::size_t(row0 + y0) * std::size_t(width_) + x0];
        const glm::vec3 top = p[0] + tx * (p[1] - p[0]);
        const glm::vec3 bottom = p[width_] + tx * (p[width_ + 1] - p[width_]);
        return top + ty * (bottom - top);
    }
    /// Bilinear lookup over the whole table (see sample_rows).
    glm::vec3 sample(float u, float v) const { return sample_rows(u, v, 0, height_); }
    /// Every texel, the padding one last (the disk cache's payload).
    const std::vector<glm::vec3> &texel_vector() const { return texels_; }
    /// A table over `texels` (width * height + 1 of them, as texel_vector gives); false, and the
    /// table left alone, when the count does not match.
    bool assign(int width, int height, std::vector<glm::vec3> texels)
    {
        if (width < 2 || height < 2 ||
            texels.size() != std::size_t(width) * std::size_t(height) + 1) {
            return false;
        }
        width_ = width;
        height_ = height;
        texels_ = std::move(texels);
        return true;
    }

   private:
    int width_ = 0, height_ = 0;
    std::vector<glm::vec3> texels_;
};

/// In-scattered radiance and transmittance of a view ray segment. The composite of a surface seen
/// through it is L = L_surface * transmittance + inscatter.
struct ScatteringResult {
    glm::vec3 inscatter{0.0f};
    glm::vec3 transmittance{1.0f};
};

class Atmosphere;
struct SkyCoordParams;

/// The sky-view LUT for one camera altitude and sun: in-scattered radiance of the whole ray (to
/// the atmosphere top or the ground) by view direction. Immutable; cheap to look up.
class SkyView {
   public:
    /// An empty view; build one with Atmosphere::make_sky_view.
    SkyView() = default;
    /// Sky radiance (no sun disc) for a unit world-space view direction; NaN gives finite output.
    glm::vec3 radiance(const glm::vec3 &view_dir) const
    {
        const float mu = glm::dot(view_dir, up_);
        const float along = glm::dot(view_dir, sun_tangent_);
        const float side = glm::dot(view_dir, sun_side_);
        // u = sin(azimuth / 2) = sqrt((1 - cos azimuth) / 2): 0 towards the sun, 1 away from it,
        // finest near the sun's Mie halo.
        const float horizontal = std::sqrt(along * along + side * side);
        const float cos_azimuth = horizontal > 1e-12f ? along / horizontal : 1.0f;
        const float u = std::sqrt(std::max(0.5f - 0.5f * cos_azimuth, 0.0f));
        const float theta = fast_acos(mu);
        const bool above = !(mu < mu_horizon_);
        const float s = above ? 1.0f - std::sqrt(saturate(1.0f - theta * inv_theta_above_))
                              : std::sqrt(saturate((theta - theta_horizon_) * inv_theta_below_));
        return lookup(u, s, above);
    }
    /// The LUT at azimuth coordinate u = sin(azimuth / 2) and latitude coordinate s in [0, 1]
    /// of the half above (zenith to horizon) or below (horizon to nadir) the horizon.
    glm::vec3 lookup(float u, float s, bool above) const
    {
        const int half = lut_.height() / 2;
        return above ? lut_.sample_rows(u, s, 0, half)
                     : lut_.sample_rows(u, s, half, lut_.height() - half);
    }
    /// radiance() for n unit directions given as separate x, y, z arrays (a vector at a time,
    /// shading/atmosphere_kernels; the same results as radiance() up to float rounding).
    void radiance_n(const float *x, const float *y, const float *z, int n, glm::vec3 *out) const;
    /// The table and the frame its coordinates are taken in, for kernels that look it up
    /// themselves (shading/atmosphere/atmosphere_kernels.h).
    SkyCoordParams coord_params() const;
    /// The table: columns u = sin(azimuth / 2) from the sun, rows as described on the class.
    const Lut2D &lut() const { return lut_; }
    /// Cosine of the horizon's zenith angle at the LUT's camera (rays below hit the ground).
    float mu_horizon() const { return mu_horizon_; }

   private:
    friend class Atmosphere;
    friend struct AtmosphereKernels;
    Lut2D lut_;
    glm::vec3 up_{0.0f, 1.0f, 0.0f}, sun_tangent_{1.0f, 0.0f, 0.0f}, sun_side_{0.0f, 0.0f, 1.0f};
    float mu_horizon_ = 0.0f, theta_horizon_ = 1.5707963f;
    float inv_theta_above_ = 1.0f / 1.5707963f, inv_theta_below_ = 1.0f / 1.5707963f;
};

/// Froxel settings of the aerial perspective volume.
struct AerialPerspectiveSettings {
    int width = 32;
    int height = 32;
    int slices = 32;
    /// Distance (along the ray, scene units) covered by the slices; slice k holds the values at
    /// distance max_distance * ((k + 0.5) / slices)^2, so near slices are thin.
    float max_distance = 32000.0f;
    int steps_per_slice = 1;  ///< 2 changes the froxel error by < 0.02% (measured)
};

/// Aerial perspective for one camera: a froxel volume of in-scatter and transmittance from the
/// camera to each slice, over the camera frustum (NDC xy, distance along the ray).
class AerialPerspective {
   public:
    /// An empty volume; use the other constructor.
    AerialPerspective() = default;
    /// Build for the camera given by worldToCamera and worldToNDC (core/camera.h conventions).
    AerialPerspective(const Atmosphere &atmosphere,
                      const glm::mat4 &world_to_camera,
                      const glm::mat4 &world_to_ndc,
                      const AerialPerspectiveSettings &settings = {});
    /// The same volume, built only as deep as `depth` (the frame's camera-space z, any size)
    /// needs: each froxel column stops at the last slice that sample() can read for a pixel of
    /// that frame (the columns and slices a pixel interpolates between), so the slices behind the
    /// scene are never integrated. Lookups for that frame's depths give the same bits as the full
    /// volume; deeper lookups are undefined.
    AerialPerspective(const Atmosphere &atmosphere,
                      const glm::mat4 &world_to_camera,
                      const glm::mat4 &world_to_ndc,
                      const AerialPerspectiveSettings &settings,
                      const Image &depth);
    /// Froxels integrated by the constructor (width x height x slices for the full volume).
    long long froxels_built() const { return froxels_built_; }

    /// In-scatter and transmittance between the camera and the point at `distance` (scene units,
    /// along the ray) on the ray through NDC `uv`. Trilinear; distance 0, negative or NaN gives
    /// (0, 1); beyond max_distance (and +inf) gives the last slice, so apply the sky (not this)
    /// to pixels without geometry. uv outside [0,1]^2 clamps.
    ScatteringResult sample(glm::vec2 uv, float distance) const
    {
        const float fx = saturate(uv.x) * float(width_) - 0.5f;  // >= -0.5
        const float fy = saturate(uv.y) * float(height_) - 0.5f;
        const int x0 = std::min(int(fx + 1.0f) - 1, width_ - 2);  // floor, without a libm call
        const int y0 = std::min(int(fy + 1.0f) - 1, height_ - 2);
        const int cx = std::max(x0, 0), cy = std::max(y0, 0);
        const float tx = saturate(fx - float(cx)), ty = saturate(fy - float(cy));
        return fetch(cx, cy, tx, ty, std::sqrt(saturate(distance * inv_max_distance_)));
    }
    /// The froxel row below NDC v and the weight of the row after it (as sample() computes them).
    void row_weights(float v, int &cy, float &ty) const
    {
        const float fy = saturate(v) * float(height_) - 0.5f;
        cy = std::max(std::min(int(fy + 1.0f) - 1, height_ - 2), 0);
        ty = saturate(fy - float(cy));
    }
    /// Distance along the ray of the pixel at NDC uv whose depth pass (camera-space z) is `depth`.
    float distance_from_depth(glm::vec2 uv, float depth) const
    {
        return depth * glm::length(rays_.depth_ray(uv.x, uv.y));
    }
    /// The camera's position and per-pixel rays.
    const CameraRays &rays() const { return rays_; }
    /// The settings used (sizes clamped to >= 2, max_distance to > 0).
    const AerialPerspectiveSettings &settings() const { return settings_; }
    /// Distance (scene units) of slice k's centre.
    float slice_distance(int k) const;

   private:
    // Trilinear fetch at column (cx + tx, cy + ty) and w = sqrt(distance / max_distance).
    ScatteringResult fetch(int cx, int cy, float tx, float ty, float w) const
    {
        // Slice k's centre is at w = (k + 0.5) / slices with distance = max * w^2. Interpolation
        // between slices is linear in distance (not in w), which in-scatter nearly is.
        const float fz = w * float(slices_) - 0.5f;
        int z0;
        float tz;
        bool from_camera = false;
        if (fz < 0.0f) {
            // Before the first slice centre: blend from (0, 1) at the camera, linear in distance.
            const float w0 = 2.0f * w * float(slices_);  // distance / first centre = w0^2
            z0 = 0;
            tz = saturate(w0 * w0);
            from_camera = true;
        } else {
            z0 = std::min(int(fz), slices_ - 2);
            // (w^2 - a^2) / (b^2 - a^2) with a, b the two centres' w = (fz - z0) (w + a) / (b + a).
            const float wa = (float(z0) + 0.5f) * inv_slices_;
            tz = saturate((fz - float(z0)) * (w + wa) * inv_centre_sum_[z0]);
        }
        Froxel a = bilinear(z0, cx, cy, tx, ty);
        if (from_camera) {
            Froxel camera;
            for (int c = 0; c < 4; ++c) {
                camera.inscatter[c] = 0.0f;
                camera.transmittance[c] = 1.0f;
            }
            lerp(camera, a, tz, a);
        } else {
            lerp(a, bilinear(z0 + 1, cx, cy, tx, ty), tz, a);
        }
        ScatteringResult r;
        r.inscatter = glm::vec3(a.inscatter[0], a.inscatter[1], a.inscatter[2]);
        r.transmittance = glm::vec3(a.transmittance[0], a.transmittance[1], a.transmittance[2]);
        return r;
    }
    // Padded to 8 floats so a froxel is two aligned 4-lane loads.
    struct alignas(16) Froxel {
        float inscatter[4];
        float transmittance[4];
    };
    // out = a + t (b - a), lane by lane (the compiler vectorises the fixed-size loops).
    static void lerp(const Froxel &a, const Froxel &b, float t, Froxel &out)
    {
        for (int c = 0; c < 4; ++c) {
            out.inscatter[c] = a.inscatter[c] + t * (b.inscatter[c] - a.inscatter[c]);
            out.transmittance[c] =
                a.transmittance[c] + t * (b.transmittance[c] - a.transmittance[c]);
        }
    }
    friend struct AtmosphereKernels;
    Froxel bilinear(int z, int x0, int y0, float tx, float ty) const
    {
        const Froxel *p = &froxels_[(std::size_t(z) * height_ + y0) * width_ + x0];
        Froxel top, bottom;
        lerp(p[0], p[1], tx, top);
        lerp(p[width_], p[width_ + 1], tx, bottom);
        lerp(top, bottom, ty, top);
        return top;
    }

    AerialPerspectiveSettings settings_;
    CameraRays rays_;
    int width_ = 0, height_ = 0, slices_ = 0;
    float inv_max_distance_ = 0.0f;
    float inv_slices_ = 0.0f;
    std::vector<float> inv_centre_sum_;  // 1 / (w_k + w_{k+1}) per slice k

    std::vector<Froxel> froxels_;  // [slice][y][x]
    long long froxels_built_ = 0;

    void build(const Atmosphere &atmosphere, const std::vector<int> *last_slice);
};

/// The atmosphere for one parameter set: LUTs built in the constructor (in parallel), immutable
/// and thread-safe afterwards.
class Atmosphere {
   public:
    /// Validate (throws Error, exit code 2, naming the parameter) and build every LUT.
    explicit Atmosphere(const AtmosphereParams &params);

    /// The parameters it was built with.
    const AtmosphereParams &params() const { return params_; }
    /// Unit world-space direction towards the sun.
    const glm::vec3 &sun_direction() const { return sun_dir_; }

    /// Sky radiance seen from `camera_pos` (world, scene units) along the unit world direction
    /// `view_dir`, from the cached sky-view LUT (built for a camera at world y = sky_view_y; the
    /// camera position only matters for the sun disc). With `sun_disc`, adds the sun's radiance
    /// attenuated by the atmosphere inside the sun's angular radius.
    glm::vec3 sky_radiance(const glm::vec3 &view_dir,
                           const glm::vec3 &camera_pos,
                           bool sun_disc = true) const;
    /// A sky-view LUT for a camera at world position `camera_pos` (a few ms; use per frame when
    /// the camera moves hundreds of metres vertically).
    SkyView make_sky_view(const glm::vec3 &camera_pos) const;
    /// The sky-view LUT built at construction for a camera at (0, sky_view_y, 0).
    const SkyView &cached_sky_view() const { return sky_view_; }
    /// Radiance of the sun disc (0 outside it or when the planet blocks it) along view_dir.
    glm::vec3 sun_disc_radiance(const glm::vec3 &view_dir, const glm::vec3 &camera_pos) const;

    /// Transmittance from world position `pos` along unit `dir` to space, from the LUT; 0 when the
    /// ray hits the planet.
    glm::vec3 transmittance(const glm::vec3 &pos, const glm::vec3 &dir) const;
    /// Transmittance of sunlight reaching world position `pos`, with the earth's shadow softened
    /// over the sun disc: the sun's illuminance at the point is sun_illuminance * this (for the
    /// rasterizer's direct light). 0 for NaN positions.
    glm::vec3 sun_transmittance_at(const glm::vec3 &pos) const;
    /// Transmittance LUT lookup at altitude (metres above the planet surface) for a ray with the
    /// given cosine of the zenith angle; rays that would hit the ground read the horizon value.
    glm::vec3 transmittance_lut(float altitude_m, float cos_zenith) const;
    /// Multiple-scattering LUT lookup: Psi_ms of the paper per unit sun illuminance (the
    /// radiance of all orders >= 2 is Psi_ms * sigma_s * E_sun).
    glm::vec3 multi_scattering_lut(float altitude_m, float cos_sun_zenith) const;
    /// Optical depth (RGB, unitless) from the given altitude along cos_zenith to the atmosphere
    /// top by midpoint quadrature with `steps` steps; the reference for the transmittance LUT.
    glm::vec3 optical_depth_numeric(float altitude_m, float cos_zenith, int steps) const;

    /// Reference: in-scatter (single + multiple scattering via the multiple-scattering LUT) and
    /// transmittance from world `origin` along unit `dir` over max_distance (scene units; +inf:
    /// to the atmosphere top), stopping at the planet, by `steps` midpoint steps. The sun's
    /// transmittance comes from the LUT, or is integrated numerically with `sun_steps` > 0.
    ScatteringResult ray_march(const glm::vec3 &origin,
                               const glm::vec3 &dir,
                               float max_distance,
                               int steps,
                               int sun_steps = 0) const;

    /// The transmittance LUT (Bruneton's parametrisation, see transmittance_lut).
    const Lut2D &transmittance_table() const { return transmittance_; }
    /// The multiple-scattering LUT: u = cos sun zenith * 0.5 + 0.5, v = altitude / thickness.
    const Lut2D &multi_scattering_table() const { return multi_scattering_; }

    /// Planet-centric position (metres, double) of a world point.
    glm::dvec3 planet_position(const glm::vec3 &world) const;

   private:
    friend class AerialPerspective;
    struct Ray;
    struct Medium {
        glm::vec3 rayleigh, mie, extinction;  // scattering, scattering, extinction (per metre)
    };
    Medium medium(float altitude_m) const;
    glm::vec3 sun_transmittance(float altitude_m, float cos_sun_zenith) const;
    ScatteringResult integrate(const Ray &ray,
                               double t_begin,
                               double t_end,
                               int steps,
                               ScatteringResult start,
                               int sun_steps,
                               bool quadratic = false) const;
    void build_transmittance();
    void build_multi_scattering();
    /// The three tables: from the disk cache (core/disk_cache.h), else built and stored.
    void build_tables();
    /// make_sky_view, with the LUT taken from `cached` (moved from) when it is not null.
    SkyView make_sky_view(const glm::vec3 &camera_pos, Lut2D *cached) const;

    AtmosphereParams params_;
    glm::vec3 sun_dir_;
    double bottom_, top_;
    double horizon_distance_top_;  // sqrt(top^2 - bottom^2)
    double sin_sun_radius_;
    float inv_horizon_distance_top_, inv_rayleigh_height_, inv_mie_height_, inv_ozone_half_width_;
    float cos_sun_radius_;
    Lut2D transmittance_;
    Lut2D multi_scattering_;
    SkyView sky_view_;
};

/// Apply the atmosphere to a frame: aerial perspective (RGB = RGB * T + inscatter) on pixels with
/// a finite depth, and on pixels with +inf depth RGB replaced by the sky from `sky` (plus the sun
/// disc when `sun_disc`); alpha untouched, NaN depths left alone. `sky` is normally
/// atmosphere.cached_sky_view() or atmosphere.make_sky_view(camera position). color has >= 3
/// channels, depth 1 (camera-space z, scene units), same size. Parallel, thread-count independent.
void apply_atmosphere(const Atmosphere &atmosphere,
                      const SkyView &sky,
                      const AerialPerspective &ap,
                      const Image &depth,
                      Image &color,
                      bool sun_disc = true);

/// Apply aerial perspective to a frame: RGB = RGB * T + inscatter for every pixel with a finite
/// depth (camera-space z, scene units); sky pixels (+inf depth) are left alone. color has >= 3
/// channels, depth 1, same size. Parallel over tiles, thread-count independent.
void apply_aerial_perspective(const AerialPerspective &ap, const Image &depth, Image &color);

/// apply_atmosphere reading `source` and writing `color` (same size and channels; they may be the
/// same image): one sweep over memory instead of a copy and a sweep.
void apply_atmosphere(const Atmosphere &atmosphere,
                      const SkyView &sky,
                      const AerialPerspective &ap,
                      const Image &depth,
                      const Image &source,
                      Image &color,
                      bool sun_disc = true);

}  // namespace posthaste::shading
