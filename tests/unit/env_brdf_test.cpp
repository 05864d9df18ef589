// The GGX lobe's directional albedo split as F0 A + B (src/shading/lighting/env_brdf.h): a mirror
// by hand, an independent quadrature of the lobe, and the weight's use of F0.
#include "shading/lighting/env_brdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

namespace posthaste::shading {
namespace {

TEST(EnvBrdf, AMirrorReflectsAllWithSchlicksWeight)
{
    // Roughness 0 (alpha 0.045^2): h = n, so v.h = n.v, no masking: A + B = 1 and
    // B = (1 - n.v)^5.
    for (float nv : {0.15f, 0.3f, 0.5f, 0.8f, 1.0f}) {
        const glm::vec2 ab = ggx_directional_albedo(nv, 0.0f);
        EXPECT_NEAR(ab.x + ab.y, 1.0f, 5e-3f) << nv;
        EXPECT_NEAR(ab.y, std::pow(1.0f - nv, 5.0f), 3e-3f) << nv;
    }
}

/// F0 A + B by a midpoint rule over the hemisphere in (cos theta, phi) of D G F / (4 n.v):
/// the GGX lobe times n.l, Smith separable masking, Schlick on v.h; independent of the table's
/// importance sampling.
double quadrature(double nv, double roughness, double f0)
{
    const double alpha = std::max(roughness, 0.045) * std::max(roughness, 0.045);
    const double a2 = alpha * alpha;
    const glm::dvec3 v(std::sqrt(1.0 - nv * nv), 0.0, nv);
    auto g1 = [&](double c) { return 2.0 * c / (c + std::sqrt(a2 + (1.0 - a2) * c * c)); };
    const int n = 1024;
    double sum = 0.0;
    for (int i = 0; i < n; ++i) {
        const double ct = (i + 0.5) / n, st = std::sqrt(1.0 - ct * ct);
        for (int j = 0; j < n; ++j) {
            const double phi = 2.0 * M_PI * (j + 0.5) / n;
            const glm::dvec3 l(st * std::cos(phi), st * std::sin(phi), ct);
            const glm::dvec3 h = glm::normalize(v + l);
            const double nh = h.z, vh = glm::dot(v, h);
            const double d = a2 / (M_PI * std::pow(nh * nh * (a2 - 1.0) + 1.0, 2.0));
            const double f = f0 + (1.0 - f0) * std::pow(1.0 - vh, 5.0);
            sum += d * g1(nv) * g1(ct) * f / (4.0 * nv);  // times n.l / n.l: dl = d(cos) dphi
        }
    }
    return sum * (1.0 / n) * (2.0 * M_PI / n);
}

TEST(EnvBrdf, MatchesAQuadratureOfTheLobe)
{
    for (float r : {0.3f, 0.5f, 0.8f}) {
        for (float nv : {0.25f, 0.6f, 0.95f}) {
            const glm::vec2 ab = ggx_directional_albedo(nv, r);
            EXPECT_NEAR(ab.x + ab.y, quadrature(nv, r, 1.0), 0.01) << r << " " << nv;
            EXPECT_NEAR(ab.y, quadrature(nv, r, 0.0), 0.005) << r << " " << nv;
        }
    }
}

TEST(EnvBrdf, TheWeightTakesF0FromTheSurface)
{
    const glm::vec3 n(0.0f, 1.0f, 0.0f), v = glm::normalize(glm::vec3(0.0f, 0.6f, 0.8f));
    const glm::vec2 ab = ggx_directional_albedo(0.6f, 0.25f);
    Surface gold;
    gold.albedo = glm::vec3(1.0f, 0.75f, 0.35f);
    gold.metallic = 1.0f;
    gold.roughness = 0.25f;
    const glm::vec3 w = ggx_reflection_weight(gold, n, v);
    EXPECT_NEAR(w.x, 1.0f * ab.x + ab.y, 1e-6f);
    EXPECT_NEAR(w.z, 0.35f * ab.x + ab.y, 1e-6f);
    Surface plastic = gold;
    plastic.metallic = 0.0f;  // F0 0.04 whatever the colour
    const glm::vec3 p = ggx_reflection_weight(plastic, n, v);
    EXPECT_NEAR(p.x, 0.04f * ab.x + ab.y, 1e-6f);
    EXPECT_FLOAT_EQ(p.x, p.z);
    // Rougher lobes lose more to masking (single scattering): less at normal incidence.
    EXPECT_GT(ggx_directional_albedo(1.0f, 0.2f).x, ggx_directional_albedo(1.0f, 0.9f).x);
    // Out-of-range inputs clamp to the table's edges.
    EXPECT_EQ(ggx_directional_albedo(-1.0f, 2.0f), ggx_directional_albedo(0.0f, 1.0f));
}

}  // namespace
}  // namespace posthaste::shading
