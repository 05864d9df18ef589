#pragma once
// The relight node's method (nodes/relight.cpp): a G-buffer shaded under a list of lights with
// the project's BRDF (brdf.h: Lambert or Burley diffuse, GGX with Smith or Cook-Torrance
// masking, anisotropic GGX, Kulla & Conty energy compensation) and the rasterizer's toon bands
// and sky light (lighting.h), with optional screen-space shadows. `shade` runs whole rows a
// vector of pixels at a time (relight_kernels.cpp, on the best Highway target) where the options
// allow, else the reference one pixel at a time (relight.cpp); both give the same bits.

#include <array>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <set>
#include <vector>

#include "core/hash.h"
#include "core/image.h"
#include "shading/lighting/brdf.h"
#include "shading/lighting/lighting.h"

namespace posthaste::shading::relight {

enum class LightType { Directional, Point, Spot };

struct Light {
    LightType type = LightType::Directional;
    glm::vec3 direction{0.0f, 1.0f, 0.0f};  // directional: toward the light; spot: where it points
    glm::vec3 position{0.0f};
    glm::vec3 power{1.0f};  // color * intensity
    float radius = 0.05f;
    float cos_inner = 0.0f, cos_outer = 0.0f;
};

struct Setup {
    std::vector<Light> lights;
    std::set<int> toon_ids;
    std::array<bool, 256> is_toon{};  // by material id
};

// Screen-space shadow march (see docs/nodes/relight.md for its limits).
struct ScreenShadows {
    const Image *depth = nullptr;
    glm::mat4 world_to_ndc{1.0f};
    glm::vec4 z_row{0.0f};  // camera-space z of a world point: dot(z_row, (p, 1))
    int steps = 16;
    float distance = 2.0f, thickness = 0.5f, bias = 0.02f;
    /// Where non-null, each pixel's own thickness as an occluder (occluder_thickness.h), at most
    /// `thickness`.
    const Image *occluder = nullptr;

    // 1 lit, 0 occluded: marches from p (pushed off along n) toward the light, up to
    // min(distance, max_t) metres, with a per-pixel hashed start offset.
    float visibility(const glm::vec3 &p,
                     const glm::vec3 &n,
                     const glm::vec3 &l,
                     float max_t,
                     int x,
                     int y,
                     int k) const
    {
        // Clip coordinates and camera z are linear along the segment: project its ends once.
        const glm::vec3 start = p + n * bias;
        const float dist = std::min(distance, max_t);
        const glm::vec3 end = start + l * dist;
        const glm::vec4 c0 = world_to_ndc * glm::vec4(start, 1.0f);
        const glm::vec4 dc = world_to_ndc * glm::vec4(end, 1.0f) - c0;
        const float z0 = glm::dot(z_row, glm::vec4(start, 1.0f));
        const float dz = glm::dot(z_row, glm::vec4(end, 1.0f)) - z0;
        const float jitter = hash_unit(x, y, k, 0x5eedu);
        const float w = float(depth->width()), h = float(depth->height());
        for (int i = 0; i < steps; ++i) {
            const float t = (float(i) + jitter) / float(steps);
            const glm::vec4 c = c0 + dc * t;
            if (!(c.w > 0.0f)) {
                break;
            }
            const float inv_w = 1.0f / c.w;
            const float px = c.x * inv_w * w, py = c.y * inv_w * h;
            if (!(px >= 0.0f && py >= 0.0f && px < w && py < h)) {
                break;
            }
            const float zb = depth->at(int(px), int(py), 0);
            const float zr = z0 + dz * t;
            const float deep = occluder ? occluder->at(int(px), int(py), 0) : thickness;
            if (std::isfinite(zb) && zb < zr - bias && zr - zb < deep) {
                return 0.0f;
            }
        }
        return 1.0f;
    }
};

// Everything the per-pixel code reads, fixed for one frame.
struct Inputs {
    const Setup *setup = nullptr;
    const Image *color = nullptr, *normal = nullptr, *albedo = nullptr, *material = nullptr;
    const Image *position = nullptr, *depth = nullptr, *tangent = nullptr, *id = nullptr;
    bool from_depth = false, shadows = false, replace = false;
    bool kernel_ok =
        false;  // options the vector rows cover (no shadows, Lambert, Smith correlated)
    const shading::EnergyTable *energy = nullptr;  // the Kulla-Conty table when compensating
    glm::mat4 c2w{1.0f}, cam_to_ndc{1.0f};
    glm::vec3 eye{0.0f}, sky_sun{0.0f};
    int width = 0, height = 0;
    float ambient = 0.0f, clamp = 0.0f;
    shading::DirectOptions base, toon;
    ScreenShadows ss;
    // Setup::is_toon as 256 bits in words 0..7; 8..15 stay zero, so that the vector rows load
    // the set as one vector of up to 16 lanes.
    std::array<std::uint32_t, 16> toon_words{};
};

/// Shade every pixel of `out` (the size of sh.color, its channel count): the lights' sum added
/// to the input color (or replacing it, sh.replace) where there is a surface; background and
/// unusable pixels keep the input color.
void shade(const Inputs &sh, Image &out);

}  // namespace posthaste::shading::relight
