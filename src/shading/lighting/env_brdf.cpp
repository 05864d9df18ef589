#include "shading/lighting/env_brdf.h"

#include <algorithm>
#include <array>
#include <glm/common.hpp>
#include <glm/geometric.hpp>

namespace posthaste::shading {
namespace {

constexpr int kSize = kGgxAlbedoTableSize;  // points along n.v and roughness, ends included
constexpr int kSamples = 256;  // lobe samples a point (specular_albedo's visible normals)

using Table = std::array<glm::vec2, kSize * kSize>;

const Table &table()
{
    // A + B is the lobe's albedo with F = 1, B the albedo with F0 = 0 (Schlick's weight alone).
    static const Table t = [] {
        Table r;
        for (int j = 0; j < kSize; ++j) {
            const float roughness = float(j) / float(kSize - 1);
            for (int i = 0; i < kSize; ++i) {
                const float nv = float(i) / float(kSize - 1);
                const float one =
                    specular_albedo(roughness, nv, Geometry::SmithSeparable, kSamples, 1.0f);
                const float b =
                    specular_albedo(roughness, nv, Geometry::SmithSeparable, kSamples, 0.0f);
                r[std::size_t(j * kSize + i)] = glm::vec2(one - b, b);
            }
        }
        return r;
    }();
    return t;
}

}  // namespace

glm::vec2 ggx_directional_albedo(float n_dot_v, float roughness)
{
    const Table &t = table();
    const float x = std::clamp(n_dot_v, 0.0f, 1.0f) * float(kSize - 1);
    const float y = std::clamp(roughness, 0.0f, 1.0f) * float(kSize - 1);
    const int i = std::min(int(x), kSize - 2), j = std::min(int(y), kSize - 2);
    const float fx = x - float(i), fy = y - float(j);
    const auto at = [&](int ii, int jj) { return t[std::size_t(jj * kSize + ii)]; };
    return glm::mix(
        glm::mix(at(i, j), at(i + 1, j), fx), glm::mix(at(i, j + 1), at(i + 1, j + 1), fx), fy);
}

glm::vec3 ggx_reflection_weight(const Surface &s, float n_dot_v)
{
    const glm::vec2 ab = ggx_directional_albedo(n_dot_v, s.roughness);
    return specular_f0(s) * ab.x + ab.y;
}

const float *ggx_albedo_table()
{
    static_assert(sizeof(glm::vec2) == 2 * sizeof(float), "the table's pairs are packed");
    return &table()[0].x;
}

glm::vec3 ggx_reflection_weight(const Surface &s, const glm::vec3 &n, const glm::vec3 &v)
{
    return ggx_reflection_weight(s, glm::dot(n, v));
}

}  // namespace posthaste::shading
