#pragma once
// What atmosphere.cpp (the Atmosphere's LUTs and integration) and atmosphere_aerial.cpp (the
// aerial-perspective volume and the frame pass) share: the planet-space ray. Internal.

#include <algorithm>
#include <cmath>

#include "shading/atmosphere/atmosphere.h"

namespace posthaste::shading {

// Distance from radius r along cos-zenith mu to the sphere of radius `radius` (far intersection).
inline double distance_to_sphere(double r, double mu, double radius)
{
    const double disc = r * r * (mu * mu - 1.0) + radius * radius;
    return std::max(0.0, -r * mu + std::sqrt(std::max(disc, 0.0)));
}

// A ray in planet space described by the law of cosines, which keeps float-sized quantities
// accurate near the surface (Bruneton 2008).
struct Atmosphere::Ray {
    double r0 = 0, mu0 = 0, mus0 = 0, nu = 0;  // radius, cos zenith, cos sun zenith, dot(dir, sun)
    float phase_rayleigh = 0, phase_mie = 0;

    void at(double t, double &r, double &mus) const
    {
        r = std::sqrt(std::max(r0 * r0 + t * t + 2.0 * r0 * mu0 * t, 0.0));
        mus = r > 0.0 ? std::clamp((r0 * mus0 + t * nu) / r, -1.0, 1.0) : mus0;
    }
};

}  // namespace posthaste::shading
