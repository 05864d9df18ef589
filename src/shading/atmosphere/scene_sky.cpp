#include "shading/atmosphere/scene_sky.h"

#include <cmath>
#include <glm/geometric.hpp>

namespace posthaste::shading {
namespace {

constexpr float kPi = 3.14159265358979f;

/// Real SH basis, bands 0-2, at unit direction d.
std::array<float, 9> sh_basis(const glm::vec3 &d)
{
    return {0.282095f,
            0.488603f * d.y,
            0.488603f * d.z,
            0.488603f * d.x,
            1.092548f * d.x * d.y,
            1.092548f * d.y * d.z,
            0.315392f * (3.0f * d.z * d.z - 1.0f),
            1.092548f * d.x * d.z,
            0.546274f * (d.x * d.x - d.y * d.y)};
}

/// Fibonacci-sphere direction i of n (uniform over the sphere).
glm::vec3 fibonacci(int i, int n)
{
    const float golden = 2.39996323f;
    const float y = 1.0f - 2.0f * (float(i) + 0.5f) / float(n);
    const float r = std::sqrt(std::max(0.0f, 1.0f - y * y));
    const float phi = golden * float(i);
    return {r * std::cos(phi), y, r * std::sin(phi)};
}

}  // namespace

SceneSky::SceneSky(const Atmosphere &atmosphere) : atmosphere_(&atmosphere)
{
    const AtmosphereParams &p = atmosphere.params();
    const glm::vec3 sun = atmosphere.sun_direction();
    const SkyView &view = atmosphere.cached_sky_view();
    const glm::vec3 cam(0.0f, p.sky_view_y, 0.0f);
    extinction_ = p.rayleigh_scattering + p.mie_extinction;

    // Ground: sun (through the atmosphere) plus the sky hemisphere, cosine-weighted.
    constexpr int kSamples = 2048;
    glm::vec3 sky_irradiance(0.0f);
    for (int i = 0; i < kSamples; ++i) {
        const glm::vec3 d = fibonacci(i, kSamples);
        if (d.y > 0.0f) {
            sky_irradiance += view.radiance(d) * d.y;
        }
    }
    sky_irradiance *= 4.0f * kPi / float(kSamples);
    const glm::vec3 sun_irradiance = p.sun_illuminance *
                                     atmosphere.sun_transmittance_at(glm::vec3(0.0f)) *
                                     std::max(sun.y, 0.0f);
    ground_radiance_ = p.ground_albedo / kPi * (sun_irradiance + sky_irradiance);

    // Ambient: project the full-sphere radiance (sky and ground) on SH, then convolve with the
    // clamped cosine (Ramamoorthi & Hanrahan 2001: A0 = pi, A1 = 2 pi / 3, A2 = pi / 4) and
    // divide by pi.
    std::array<glm::vec3, 9> coeff{};
    for (int i = 0; i < kSamples; ++i) {
        const glm::vec3 d = fibonacci(i, kSamples);
        const glm::vec3 l = radiance(d, cam, false);
        const std::array<float, 9> y = sh_basis(d);
        for (int k = 0; k < 9; ++k) {
            coeff[std::size_t(k)] += l * y[std::size_t(k)];
        }
    }
    const float band[9] = {kPi,
                           2.0f * kPi / 3.0f,
                           2.0f * kPi / 3.0f,
                           2.0f * kPi / 3.0f,
                           kPi / 4.0f,
                           kPi / 4.0f,
                           kPi / 4.0f,
                           kPi / 4.0f,
                           kPi / 4.0f};
    for (int k = 0; k < 9; ++k) {
        sh_[std::size_t(k)] =
            coeff[std::size_t(k)] * (4.0f * kPi / float(kSamples)) * band[k] / kPi;
    }
}

glm::vec3 SceneSky::ground(const glm::vec3 &dir, const glm::vec3 &camera_pos) const
{
    if (!(dir.y < 0.0f)) {
        return glm::vec3(0.0f);
    }
    const AtmosphereParams &p = atmosphere_->params();
    const float altitude_m = std::max(camera_pos.y * p.metres_per_unit + p.camera_offset_m, 0.01f);
    const float distance_m = std::min(altitude_m / std::max(-dir.y, 1e-4f), 1e6f);
    const glm::vec3 t(std::exp(-extinction_.x * distance_m),
                      std::exp(-extinction_.y * distance_m),
                      std::exp(-extinction_.z * distance_m));
    return ground_radiance_ * t;
}

glm::vec3 SceneSky::radiance(const glm::vec3 &dir, const glm::vec3 &camera_pos, bool sun_disc) const
{
    return atmosphere_->sky_radiance(dir, camera_pos, sun_disc) + ground(dir, camera_pos);
}

glm::vec3 SceneSky::ambient(const glm::vec3 &n) const
{
    const std::array<float, 9> y = sh_basis(n);
    glm::vec3 e(0.0f);
    for (int k = 0; k < 9; ++k) {
        e += sh_[std::size_t(k)] * y[std::size_t(k)];
    }
    return glm::max(e, glm::vec3(0.0f));
}

}  // namespace posthaste::shading
