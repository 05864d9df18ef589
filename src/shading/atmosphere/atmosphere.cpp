#include "shading/atmosphere/atmosphere.h"

#include <cassert>
#include <cstdint>
#include <cstring>
#include <limits>

#include "core/error.h"
#include "core/parallel.h"
#include "shading/atmosphere/atmosphere_kernels.h"
#include "shading/atmosphere/atmosphere_ray.h"

namespace posthaste::shading {
namespace {

constexpr double kPiD = 3.14159265358979323846;
constexpr float kPi = 3.14159265358979f;

// Near intersection with the planet; only meaningful when the ray hits it.
double distance_to_ground(double r, double mu, double bottom)
{
    const double disc = r * r * (mu * mu - 1.0) + bottom * bottom;
    return std::max(0.0, -r * mu - std::sqrt(std::max(disc, 0.0)));
}

// Cosine of the horizon's zenith angle at altitude h: rays with a smaller cosine hit the planet.
double horizon_cos(double h, double bottom)
{
    h = std::max(h, 0.0);
    return -std::sqrt(h * (2.0 * bottom + h)) / (bottom + h);
}

double smoothstep(double e0, double e1, double x)
{
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

glm::vec3 exp3(const glm::vec3 &v)
{
    return {std::exp(v.x), std::exp(v.y), std::exp(v.z)};
}

// Hillaire's analytic step (paper section 4, after Hillaire 2015): over dt with constant source
// and extinction, the in-scatter is T * S * (1 - exp(-sigma_t dt)) / sigma_t. Returns that
// integral factor per channel and the segment transmittance in `seg`.
glm::vec3 step_integral(const glm::vec3 &extinction, float dt, glm::vec3 &seg)
{
    // (1 - exp(-x)) / sigma_t with x = sigma_t dt; a series for thin steps, where 1 - exp(-x)
    // would cancel to 0 in float.
    glm::vec3 integral;
    for (int c = 0; c < 3; ++c) {
        const float x = extinction[c] * dt;
        seg[c] = fast_exp(-x);
        integral[c] = std::fabs(x) < 0.03f ? dt * (1.0f - x * (0.5f - x * (1.0f / 6.0f)))
                                           : (1.0f - seg[c]) / extinction[c];
    }
    return integral;
}

void accumulate(ScatteringResult &acc,
                const glm::vec3 &source,
                const glm::vec3 &extinction,
                float dt)
{
    glm::vec3 seg;
    const glm::vec3 integral = step_integral(extinction, dt, seg);
    acc.inscatter += acc.transmittance * source * integral;
    acc.transmittance *= seg;
}

template <typename T>
void check_param(bool ok, const char *name, const char *expected, T got)
{
    if (!ok) {
        throw_usage("atmosphere: param \"", name, "\": expected ", expected, ", got ", got);
    }
}

bool finite3(const glm::vec3 &v)
{
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool non_negative3(const glm::vec3 &v)
{
    return finite3(v) && v.x >= 0.0f && v.y >= 0.0f && v.z >= 0.0f;
}

}  // namespace

// The same ray evaluated in float for the integration loops: rho^2 = r^2 - R^2 grows as
// rho0^2 + t (t + 2 r0 mu0), and the altitude rho^2 / (r + R) keeps full relative precision.
struct FloatRay {
    float rho0_sq, two_r0_mu0, r0_mus0, nu, bottom, bottom_sq;

    FloatRay(double r0, double mu0, double mus0, double nu_, double bottom_radius)
        : rho0_sq(float((r0 - bottom_radius) * (r0 + bottom_radius))),
          two_r0_mu0(float(2.0 * r0 * mu0)),
          r0_mus0(float(r0 * mus0)),
          nu(float(nu_)),
          bottom(float(bottom_radius)),
          bottom_sq(float(bottom_radius * bottom_radius))
    {
    }
    void at(float t, float &altitude, float &mus) const
    {
        const float rho_sq = std::max(rho0_sq + t * (t + two_r0_mu0), 0.0f);
        const float r = std::sqrt(bottom_sq + rho_sq);
        altitude = rho_sq / (r + bottom);
        mus = std::clamp((r0_mus0 + t * nu) / r, -1.0f, 1.0f);
    }
};

Atmosphere::Atmosphere(const AtmosphereParams &p) : params_(p)
{
    check_param(std::isfinite(p.bottom_radius_m) && p.bottom_radius_m > 0.0f,
                "bottom_radius_m",
                "number > 0",
                p.bottom_radius_m);
    check_param(std::isfinite(p.top_radius_m) && p.top_radius_m > p.bottom_radius_m,
                "top_radius_m",
                "number > bottom_radius_m",
                p.top_radius_m);
    check_param(p.rayleigh_scale_height_m > 0.0f,
                "rayleigh_scale_height_m",
                "number > 0",
                p.rayleigh_scale_height_m);
    check_param(
        p.mie_scale_height_m > 0.0f, "mie_scale_height_m", "number > 0", p.mie_scale_height_m);
    check_param(p.ozone_width_m > 0.0f, "ozone_width_m", "number > 0", p.ozone_width_m);
    check_param(p.mie_g > -1.0f && p.mie_g < 1.0f, "mie_g", "number in (-1, 1)", p.mie_g);
    check_param(non_negative3(p.rayleigh_scattering), "rayleigh_scattering", "finite >= 0", "");
    check_param(non_negative3(p.mie_scattering), "mie_scattering", "finite >= 0", "");
    check_param(non_negative3(p.mie_extinction - p.mie_scattering),
                "mie_extinction",
                ">= mie_scattering",
                "");
    check_param(non_negative3(p.ozone_absorption), "ozone_absorption", "finite >= 0", "");
    check_param(non_negative3(p.ground_albedo), "ground_albedo", "finite >= 0", "");
    check_param(non_negative3(p.sun_illuminance), "sun_illuminance", "finite >= 0", "");
    check_param(finite3(p.sun_direction) && glm::length(p.sun_direction) > 0.0f,
                "sun_direction",
                "finite non-zero vector",
                "");
    check_param(p.sun_angular_radius_rad > 0.0f && p.sun_angular_radius_rad < 0.5f,
                "sun_angular_radius_rad",
                "number in (0, 0.5)",
                p.sun_angular_radius_rad);
    check_param(std::isfinite(p.ground_altitude_m) && std::isfinite(p.camera_offset_m),
                "ground_altitude_m",
                "finite number",
                p.ground_altitude_m);
    check_param(p.metres_per_unit > 0.0f && std::isfinite(p.metres_per_unit),
                "metres_per_unit",
                "number > 0",
                p.metres_per_unit);
    check_param(std::isfinite(p.sky_view_y), "sky_view_y", "finite number", p.sky_view_y);
    const auto check_size = [](int v, const char *name) {
        check_param(v >= 2 && v <= 4096, name, "integer in [2, 4096]", v);
    };
    check_size(p.transmittance_width, "transmittance_width");
    check_size(p.transmittance_height, "transmittance_height");
    check_size(p.multi_scattering_size, "multi_scattering_size");
    check_size(p.sky_view_width, "sky_view_width");
    check_param(p.sky_view_height >= 4 && p.sky_view_height <= 4096,
                "sky_view_height",
                "integer in [4, 4096]",
                p.sky_view_height);
    check_size(p.transmittance_steps, "transmittance_steps");
    check_size(p.multi_scattering_directions, "multi_scattering_directions");
    check_size(p.multi_scattering_steps, "multi_scattering_steps");
    check_size(p.sky_view_steps, "sky_view_steps");

    sun_dir_ = glm::normalize(p.sun_direction);
    bottom_ = double(p.bottom_radius_m);
    top_ = double(p.top_radius_m);
    horizon_distance_top_ = std::sqrt(top_ * top_ - bottom_ * bottom_);
    sin_sun_radius_ = std::sin(double(p.sun_angular_radius_rad));
    inv_horizon_distance_top_ = float(1.0 / horizon_distance_top_);
    inv_rayleigh_height_ = 1.0f / p.rayleigh_scale_height_m;
    inv_mie_height_ = 1.0f / p.mie_scale_height_m;
    inv_ozone_half_width_ = 2.0f / p.ozone_width_m;
    cos_sun_radius_ = std::cos(p.sun_angular_radius_rad);
    build_tables();
}

glm::dvec3 Atmosphere::planet_position(const glm::vec3 &world) const
{
    const double s = params_.metres_per_unit;
    return {double(world.x) * s,
            double(world.y) * s + bottom_ + double(params_.ground_altitude_m) +
                double(params_.camera_offset_m),
            double(world.z) * s};
}

Atmosphere::Medium Atmosphere::medium(float altitude_m) const
{
    const float h = std::max(altitude_m, 0.0f);
    if (h > float(top_ - bottom_)) {
        return {glm::vec3(0.0f), glm::vec3(0.0f), glm::vec3(0.0f)};
    }
    const float rayleigh = fast_exp(-h * inv_rayleigh_height_);
    const float mie = fast_exp(-h * inv_mie_height_);
    const float ozone =
        std::max(0.0f, 1.0f - std::fabs(h - params_.ozone_center_m) * inv_ozone_half_width_);
    Medium m;
    m.rayleigh = params_.rayleigh_scattering * rayleigh;
    m.mie = params_.mie_scattering * mie;
    m.extinction = m.rayleigh + params_.mie_extinction * mie + params_.ozone_absorption * ozone;
    return m;
}

// Transmittance LUT parametrisation (Bruneton 2017, as in the paper's section 5.1): v is the
// radius as the horizon distance fraction, u the distance to the top between its extremes.
glm::vec3 Atmosphere::transmittance_lut(float altitude_m, float cos_zenith) const
{
    // Float throughout, written so that nothing cancels near the ground: r^2 - R^2 = h (2R + h)
    // and top^2 - r^2 = (T - h)(top + r), T the atmosphere's thickness.
    const float bottom = float(bottom_), top = float(top_), thickness = float(top_ - bottom_);
    const float h = std::isnan(altitude_m) ? 0.0f : std::clamp(altitude_m, 0.0f, thickness);
    const float mu = std::isnan(cos_zenith) ? 1.0f : std::clamp(cos_zenith, -1.0f, 1.0f);
    const float rho = std::sqrt(h * (2.0f * bottom + h));
    const float r = bottom + h;
    const float to_top = (thickness - h) * (top + r);  // top^2 - r^2
    const float root = std::sqrt(std::max(r * r * mu * mu + to_top, 0.0f));
    const float d = mu > 0.0f ? to_top / (r * mu + root) : root - r * mu;  // distance to the top
    const float d_min = thickness - h, d_max = rho + float(horizon_distance_top_);
    const float u = (d - d_min) / (d_max - d_min);
    const float v = rho * inv_horizon_distance_top_;
    return transmittance_.sample(u, v);
}

glm::vec3 Atmosphere::multi_scattering_lut(float altitude_m, float cos_sun_zenith) const
{
    return multi_scattering_.sample(cos_sun_zenith * 0.5f + 0.5f,
                                    altitude_m / float(top_ - bottom_));
}

glm::vec3 Atmosphere::optical_depth_numeric(float altitude_m, float cos_zenith, int steps) const
{
    const double h = std::clamp(double(altitude_m), 0.0, top_ - bottom_);
    Ray ray;
    ray.r0 = bottom_ + h;
    ray.mu0 = std::clamp(double(cos_zenith), -1.0, 1.0);
    const double t_end = distance_to_sphere(ray.r0, ray.mu0, top_);
    const double dt = t_end / std::max(steps, 1);
    glm::dvec3 tau(0.0);
    for (int i = 0; i < steps; ++i) {
        double r, mus;
        ray.at((i + 0.5) * dt, r, mus);
        tau += glm::dvec3(medium(float(r - bottom_)).extinction) * dt;
    }
    return glm::vec3(tau);
}

glm::vec3 Atmosphere::sun_transmittance(float altitude_m, float cos_sun_zenith) const
{
    // Soft earth shadow: the fraction of the sun disc above the horizon, as a smoothstep.
    const float h = std::max(altitude_m, 0.0f);
    const float bottom = float(bottom_);
    const float mu_h = -std::sqrt(h * (2.0f * bottom + h)) / (bottom + h);
    const float s = float(sin_sun_radius_);
    const float x = std::clamp((cos_sun_zenith - (mu_h - s)) * (0.5f / s), 0.0f, 1.0f);
    const float visible = x * x * (3.0f - 2.0f * x);
    if (!(visible > 0.0f)) {
        return glm::vec3(0.0f);
    }
    return visible * transmittance_lut(h, cos_sun_zenith);
}

void Atmosphere::build_transmittance()
{
    const int w = params_.transmittance_width, h = params_.transmittance_height;
    transmittance_ = Lut2D(w, h);
    const double big_h = std::sqrt(top_ * top_ - bottom_ * bottom_);
    parallel_for(0, h, [&](int y) {
        const double rho = big_h * double(y) / double(h - 1);
        const double r = std::sqrt(rho * rho + bottom_ * bottom_);
        const double altitude = rho * rho / (r + bottom_);
        for (int x = 0; x < w; ++x) {
            const double d_min = top_ - r, d_max = rho + big_h;
            const double d = d_min + (d_max - d_min) * double(x) / double(w - 1);
            const double mu =
                d <= 0.0
                    ? 1.0
                    : std::clamp((big_h * big_h - rho * rho - d * d) / (2.0 * r * d), -1.0, 1.0);
            const glm::vec3 tau =
                optical_depth_numeric(float(altitude), float(mu), params_.transmittance_steps);
            transmittance_.at(x, y) = exp3(-tau);
        }
    });
}

// Paper section 5.2: per (sun zenith, altitude), the second-order radiance L_2 reaching the point
// from all directions with an isotropic phase (eq. 6, incl. the lit ground) and the transfer
// f_ms (eq. 7), summed over all orders as L_2 / (1 - f_ms) (eq. 9).
void Atmosphere::build_multi_scattering()
{
    const int n = params_.multi_scattering_size;
    const int dirs = params_.multi_scattering_directions;
    const int steps = params_.multi_scattering_steps;
    multi_scattering_ = Lut2D(n, n);
    const float isotropic = 1.0f / (4.0f * kPi);
    const double golden_angle = kPiD * (3.0 - std::sqrt(5.0));
    parallel_for(0, n, [&](int y) {
        const double altitude = (top_ - bottom_) * double(y) / double(n - 1);
        const double r = bottom_ + altitude;
        const double mu_h = horizon_cos(altitude, bottom_);
        for (int x = 0; x < n; ++x) {
            const double mus = -1.0 + 2.0 * double(x) / double(n - 1);
            const glm::dvec3 sun(std::sqrt(std::max(0.0, 1.0 - mus * mus)), 0.0, mus);
            glm::dvec3 l2(0.0), f_ms(0.0);
            for (int k = 0; k < dirs; ++k) {
                // Fibonacci sphere: near-uniform directions, up = +z.
                const double z = 1.0 - (2.0 * k + 1.0) / dirs;
                const double rad = std::sqrt(std::max(0.0, 1.0 - z * z));
                const double phi = golden_angle * k;
                const glm::dvec3 dir(rad * std::cos(phi), rad * std::sin(phi), z);
                Ray ray;
                ray.r0 = r;
                ray.mu0 = z;
                ray.mus0 = mus;
                ray.nu = glm::dot(dir, sun);
                const FloatRay fray(r, z, mus, ray.nu, bottom_);
                const bool ground = z < mu_h;
                const double t_end =
                    ground ? distance_to_ground(r, z, bottom_) : distance_to_sphere(r, z, top_);
                ScatteringResult acc;
                for (int i = 0; i < steps; ++i) {
                    // Quadratic step distribution, as in integrate().
                    const double s0 = double(i) / steps, s1 = double(i + 1) / steps;
                    const float dt = float((s1 * s1 - s0 * s0) * t_end);
                    float hi, musi;
                    fray.at(float(0.5 * (s0 * s0 + s1 * s1) * t_end), hi, musi);
                    const Medium m = medium(hi);
                    const glm::vec3 scattering = m.rayleigh + m.mie;
                    const glm::vec3 source = sun_transmittance(hi, musi) * scattering * isotropic;
                    glm::vec3 seg;
                    const glm::vec3 integral = step_integral(m.extinction, dt, seg);
                    f_ms += glm::dvec3(acc.transmittance * scattering * integral);
                    acc.inscatter += acc.transmittance * source * integral;
                    acc.transmittance *= seg;
                }
                if (ground) {
                    double rg, mus_g;
                    ray.at(t_end, rg, mus_g);
                    const glm::vec3 lit = sun_transmittance(0.0f, float(mus_g)) *
                                          float(std::max(mus_g, 0.0)) * params_.ground_albedo / kPi;
                    acc.inscatter += acc.transmittance * lit;
                }
                l2 += glm::dvec3(acc.inscatter);
            }
            l2 /= double(dirs);
            f_ms /= double(dirs);
            const glm::dvec3 psi = l2 / glm::max(glm::dvec3(1.0) - f_ms, glm::dvec3(1e-6));
            multi_scattering_.at(x, y) = glm::vec3(psi);
        }
    });
}

ScatteringResult Atmosphere::integrate(const Ray &ray,
                                       double t_begin,
                                       double t_end,
                                       int steps,
                                       ScatteringResult acc,
                                       int sun_steps,
                                       bool quadratic) const
{
    if (!(t_end > t_begin) || steps <= 0) {
        return acc;
    }
    const double length = t_end - t_begin;
    const glm::vec3 &sun = params_.sun_illuminance;
    const FloatRay fray(ray.r0, ray.mu0, ray.mus0, ray.nu, bottom_);
    for (int i = 0; i < steps; ++i) {
        // Step i spans [s_i, s_{i+1}] of the segment, s = i / steps (uniform) or (i / steps)^2
        // (quadratic: short steps near the start where the air is densest for a camera near the
        // ground, as the paper's variable sample count intends).
        double s0 = double(i) / steps, s1 = double(i + 1) / steps;
        if (quadratic) {
            s0 *= s0;
            s1 *= s1;
        }
        const double dt = (s1 - s0) * length;
        float altitude, mus;
        fray.at(float(t_begin + 0.5 * (s0 + s1) * length), altitude, mus);
        const Medium m = medium(altitude);
        glm::vec3 t_sun;
        if (sun_steps > 0) {
            const double mu_h = horizon_cos(altitude, bottom_);
            const double s = sin_sun_radius_;
            t_sun = float(smoothstep(mu_h - s, mu_h + s, mus)) *
                    exp3(-optical_depth_numeric(altitude, mus, sun_steps));
        } else {
            t_sun = sun_transmittance(altitude, mus);
        }
        const glm::vec3 ms = multi_scattering_lut(altitude, mus);
        const glm::vec3 source =
            sun * (t_sun * (m.rayleigh * ray.phase_rayleigh + m.mie * ray.phase_mie) +
                   ms * (m.rayleigh + m.mie));
        accumulate(acc, source, m.extinction, float(dt));
    }
    return acc;
}

SkyView Atmosphere::make_sky_view(const glm::vec3 &camera_pos) const
{
    return make_sky_view(camera_pos, nullptr);
}

SkyView Atmosphere::make_sky_view(const glm::vec3 &camera_pos, Lut2D *cached) const
{
    SkyView view;
    const int w = params_.sky_view_width, h = params_.sky_view_height;
    glm::dvec3 p = planet_position(camera_pos);
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))) {
        p = planet_position(glm::vec3(0.0f));
    }
    const double r = std::clamp(glm::length(p), bottom_, top_ - 1.0);
    const double altitude = r - bottom_;
    const glm::vec3 up = glm::vec3(glm::normalize(p));
    const float mus = glm::dot(up, sun_dir_);
    glm::vec3 tangent = sun_dir_ - up * mus;
    if (glm::length(tangent) < 1e-6f) {
        tangent = std::fabs(up.x) < 0.9f ? glm::cross(up, glm::vec3(1, 0, 0))
                                         : glm::cross(up, glm::vec3(0, 0, 1));
    }
    view.up_ = up;
    view.sun_tangent_ = glm::normalize(tangent);
    view.sun_side_ = glm::cross(up, view.sun_tangent_);
    const double mu_h = horizon_cos(altitude, bottom_);
    const double theta_h = std::acos(mu_h);
    view.mu_horizon_ = float(mu_h);
    view.theta_horizon_ = float(theta_h);
    view.inv_theta_above_ = float(1.0 / theta_h);
    view.inv_theta_below_ = float(1.0 / (kPiD - theta_h));
    if (cached) {
        view.lut_ = std::move(*cached);
        return view;
    }
    view.lut_ = Lut2D(w, h);
    const double sin_sun = std::sqrt(std::max(0.0, 1.0 - double(mus) * double(mus)));
    const int half = h / 2;
    parallel_for(0, h, [&](int y) {
        const bool below = y >= half;
        double theta;
        if (!below) {
            const double s = double(y) / double(half - 1);
            theta = theta_h * (1.0 - (1.0 - s) * (1.0 - s));
        } else {
            const double s = double(y - half) / double(h - half - 1);
            theta = theta_h + (kPiD - theta_h) * s * s;
        }
        const double mu = std::cos(theta), sin_theta = std::sin(theta);
        const double t_end =
            below ? distance_to_ground(r, mu, bottom_) : distance_to_sphere(r, mu, top_);
        for (int x = 0; x < w; ++x) {
            const double azimuth = 2.0 * std::asin(double(x) / double(w - 1));
            Ray ray;
            ray.r0 = r;
            ray.mu0 = mu;
            ray.mus0 = mus;
            ray.nu = sin_theta * std::cos(azimuth) * sin_sun + mu * double(mus);
            ray.phase_rayleigh = rayleigh_phase(float(ray.nu));
            ray.phase_mie = cornette_shanks_phase(float(ray.nu), params_.mie_g);
            view.lut_.at(x, y) =
                integrate(ray, 0.0, t_end, params_.sky_view_steps, ScatteringResult{}, 0, true)
                    .inscatter;
        }
    });
    return view;
}

glm::vec3 Atmosphere::sun_disc_radiance(const glm::vec3 &view_dir,
                                        const glm::vec3 &camera_pos) const
{
    if (!(glm::dot(view_dir, sun_dir_) >= cos_sun_radius_)) {
        return glm::vec3(0.0f);
    }
    const float solid_angle = 2.0f * kPi * (1.0f - cos_sun_radius_);
    return params_.sun_illuminance / solid_angle * transmittance(camera_pos, view_dir);
}

glm::vec3 Atmosphere::sky_radiance(const glm::vec3 &view_dir,
                                   const glm::vec3 &camera_pos,
                                   bool sun_disc) const
{
    glm::vec3 l = sky_view_.radiance(view_dir);
    if (sun_disc) {
        l += sun_disc_radiance(view_dir, camera_pos);
    }
    return l;
}

glm::vec3 Atmosphere::transmittance(const glm::vec3 &pos, const glm::vec3 &dir) const
{
    const glm::dvec3 p = planet_position(pos);
    const double len = glm::length(p);
    if (!(len > 0.0) || !std::isfinite(len)) {
        return glm::vec3(0.0f);
    }
    const double r = std::clamp(len, bottom_, top_);
    const double mu = glm::dot(p / len, glm::dvec3(dir));
    if (!(mu >= horizon_cos(r - bottom_, bottom_))) {
        return glm::vec3(0.0f);  // hits the planet (or NaN direction)
    }
    return transmittance_lut(float(r - bottom_), float(mu));
}

glm::vec3 Atmosphere::sun_transmittance_at(const glm::vec3 &pos) const
{
    const glm::dvec3 p = planet_position(pos);
    const double len = glm::length(p);
    if (!(len > 0.0) || !std::isfinite(len)) {
        return glm::vec3(0.0f);
    }
    const double r = std::clamp(len, bottom_, top_);
    const double mus = glm::dot(p / len, glm::dvec3(sun_dir_));
    return sun_transmittance(float(r - bottom_), float(mus));
}

ScatteringResult Atmosphere::ray_march(const glm::vec3 &origin,
                                       const glm::vec3 &dir,
                                       float max_distance,
                                       int steps,
                                       int sun_steps) const
{
    const glm::dvec3 p = planet_position(origin);
    const double len = glm::length(p);
    const glm::dvec3 d(dir);
    if (!std::isfinite(len) || !(len > 0.0) || !std::isfinite(glm::length(d)) ||
        !(max_distance > 0.0f)) {
        return {};
    }
    const glm::dvec3 up = p / len;
    Ray ray;
    ray.r0 = std::clamp(len, bottom_, top_);
    ray.mu0 = std::clamp(glm::dot(up, d), -1.0, 1.0);
    ray.mus0 = glm::dot(up, glm::dvec3(sun_dir_));
    ray.nu = glm::dot(d, glm::dvec3(sun_dir_));
    ray.phase_rayleigh = rayleigh_phase(float(ray.nu));
    ray.phase_mie = cornette_shanks_phase(float(ray.nu), params_.mie_g);
    const double altitude = ray.r0 - bottom_;
    double t_end = ray.mu0 < horizon_cos(altitude, bottom_)
                       ? distance_to_ground(ray.r0, ray.mu0, bottom_)
                       : distance_to_sphere(ray.r0, ray.mu0, top_);
    t_end = std::min(t_end, double(max_distance) * params_.metres_per_unit);
    return integrate(ray, 0.0, t_end, steps, ScatteringResult{}, sun_steps);
}

}  // namespace posthaste::shading
