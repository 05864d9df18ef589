#include "raster/sky.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace posthaste::raster {
namespace {

const glm::vec3 kZenith(0.25f, 0.45f, 0.95f);
const glm::vec3 kHorizon(0.75f, 0.85f, 1.0f);
const glm::vec3 kGround(0.25f, 0.23f, 0.2f);

}  // namespace

glm::vec3 sky_radiance(const glm::vec3 &dir, const glm::vec3 &sun_dir)
{
    const float y = dir.y;
    glm::vec3 c;
    if (y >= 0.0f) {
        const float m = 1.0f - std::min(y, 1.0f);
        const float t = m * m * m;
        c = glm::mix(kZenith, kHorizon, t);
    } else {
        c = glm::mix(kHorizon, kGround, std::min(1.0f, -y * 4.0f));
    }
    const float cs = std::max(glm::dot(dir, sun_dir), 0.0f);
    const float c2 = cs * cs, c4 = c2 * c2, c16 = (c4 * c4) * (c4 * c4);
    const float glow = 0.6f * (c16 * c16) * (c16 * c16) + 0.15f * c4;
    return c + glow * glm::vec3(1.0f, 0.9f, 0.7f);
}

glm::vec3 sky_ambient_radiance(const glm::vec3 &n, const glm::vec3 &)
{
    // Irradiance / pi of a sky that is kZenith-ish above and kGround below: blend on n.y.
    const float up = 0.5f + 0.5f * std::clamp(n.y, -1.0f, 1.0f);
    const glm::vec3 sky = 0.6f * kZenith + 0.4f * kHorizon;
    return glm::mix(kGround * 0.5f, sky, up);
}

}  // namespace posthaste::raster
