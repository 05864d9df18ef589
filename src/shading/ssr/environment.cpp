// Latitude-longitude environment maps (see environment.h).

#include "shading/ssr/environment.h"

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <limits>

#include "shading/fast_math.h"

namespace posthaste::shading {

namespace {
constexpr float kPi = 3.14159265358979323846f;
}

glm::vec2 latlong_uv(const glm::vec3 &d)
{
    // The polynomial arctangent and arccosine (about 1e-7 rad: libm's within a few ulps).
    const float u = 0.5f + fast_atan2(d.x, -d.z) * (0.5f / kPi);
    const float v = fast_acos(std::clamp(d.y, -1.0f, 1.0f)) * (1.0f / kPi);
    return {std::clamp(u, 0.0f, 1.0f), v};
}

glm::vec3 latlong_direction(float u, float v)
{
    const float phi = (u - 0.5f) * (2.0f * kPi);
    const float theta = v * kPi;
    const float s = std::sin(theta);
    return {s * std::sin(phi), std::cos(theta), -s * std::cos(phi)};
}

glm::vec3 LatLongMap::radiance(const glm::vec3 &d) const
{
    const Image &im = *image_;
    const int w = im.width(), h = im.height();
    const glm::vec2 uv = latlong_uv(d);
    // Texel centres at (i + 0.5) / w: x wraps around, y stops at the first and last rows.
    const float fx = uv.x * float(w) - 0.5f;
    const float fy = std::clamp(uv.y * float(h) - 0.5f, 0.0f, float(h - 1));
    const float x0f = std::floor(fx), y0f = std::floor(fy);
    const float tx = fx - x0f, ty = fy - y0f;
    const int x0 = ((int(x0f) % w) + w) % w, x1 = (x0 + 1) % w;
    const int y0 = int(y0f), y1 = std::min(y0 + 1, h - 1);
    glm::vec3 c(0.0f);
    const auto add = [&](int x, int y, float wgt) {
        const float *px = im.pixel(x, y);
        c += glm::vec3(px[0], px[1], px[2]) * wgt;
    };
    add(x0, y0, (1.0f - tx) * (1.0f - ty));
    add(x1, y0, tx * (1.0f - ty));
    add(x0, y1, (1.0f - tx) * ty);
    add(x1, y1, tx * ty);
    return c;
}

DistanceCube::DistanceCube(const Image &latlong, int size)
    : cube_(
          latlong, size > 0 ? size : std::clamp(latlong.width() / 4, 1, 128), [](const float *px) {
              return std::isnan(px[0]) ? std::numeric_limits<float>::infinity() : px[0];
          })
{
    for (std::size_t i = 0; i < latlong.value_count(); i += std::size_t(latlong.channels())) {
        const float dist = latlong.data()[i];
        if (std::isfinite(dist)) {
            reach_ = std::max(reach_, dist);
        }
    }
}

glm::vec3 Probe::seen(const glm::vec3 &origin, const glm::vec3 &dir) const
{
    const LatLongMap map(*radiance);
    if (!distance) {
        return map.radiance(dir);
    }
    // March the ray through the probe's distances: sample k at s = end (k / n)^2 (closer near
    // the origin); a crossing is a sample behind the probe's surface (farther from the position
    // than the surface it sees in that direction) after one in front of it, by at most
    // `thickness` plus the step (else the ray passed behind what the probe saw: go on).
    const glm::vec3 rel = origin - position;
    const auto depth_gap = [&](float s) {
        const glm::vec3 x = rel + dir * s;
        return std::sqrt(glm::dot(x, x)) - distance->at(x);  // -inf for the sky: in front
    };
    // Past the sphere of the farthest distance around the position there is nothing to meet.
    const float reach = distance->reach();
    const float b = glm::dot(rel, dir), c = glm::dot(rel, rel) - reach * reach;
    const float disc = b * b - c;
    if (!(disc >= 0.0f) || (c > 0.0f && b >= 0.0f)) {
        return map.radiance(dir);  // the ray never enters the sphere
    }
    const float end = std::min(max_distance, -b + std::sqrt(disc));
    float prev_s = 0.0f;
    bool in_front = false;
    for (int k = 1; k <= march_steps; ++k) {
        const float f = float(k) / float(march_steps);
        const float s = end * f * f;
        const float gap = depth_gap(s);
        if (!(gap >= 0.0f)) {
            in_front = true;
            prev_s = s;
            continue;
        }
        if (in_front && gap <= thickness + (s - prev_s)) {
            float lo = prev_s, hi = s;  // in front at lo, behind at hi
            for (int i = 0; i < refine_steps; ++i) {
                const float mid = 0.5f * (lo + hi);
                (depth_gap(mid) >= 0.0f ? hi : lo) = mid;
            }
            const glm::vec3 x = rel + dir * hi;
            const float r = std::sqrt(glm::dot(x, x));
            return map.radiance(r > 0.0f ? x / r : dir);
        }
        in_front = false;
        prev_s = s;
    }
    return map.radiance(dir);  // nothing met: what lies beyond, infinitely far
}

}  // namespace posthaste::shading
