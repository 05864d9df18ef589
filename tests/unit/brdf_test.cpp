// Tests for src/shading/brdf: hand-computed values, GGX normalisation, finiteness at the edges.
#include "shading/lighting/brdf.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

namespace posthaste::shading {
namespace {

TEST(Brdf, RoughnessToAlphaClamps)
{
    EXPECT_FLOAT_EQ(roughness_to_alpha(0.5f), 0.25f);
    EXPECT_FLOAT_EQ(roughness_to_alpha(0.0f), kMinRoughness * kMinRoughness);
    EXPECT_FLOAT_EQ(roughness_to_alpha(2.0f), 1.0f);
}

TEST(Brdf, GgxHandValues)
{
    // n.h = 1: D = 1 / (pi alpha^2).
    EXPECT_NEAR(d_ggx(1.0f, 0.5f), 1.0 / (M_PI * 0.25), 1e-6);
    // alpha = 1: D = 1 / pi everywhere.
    EXPECT_NEAR(d_ggx(0.3f, 1.0f), 1.0 / M_PI, 1e-6);
    // n.h = 0.8, alpha = 0.5: d = 0.64 * (0.25 - 1) + 1 = 0.52; D = 0.25 / (pi 0.2704).
    EXPECT_NEAR(d_ggx(0.8f, 0.5f), 0.25 / (M_PI * 0.2704), 1e-6);
    EXPECT_EQ(d_ggx(-0.1f, 0.5f), 0.0f);
    // Anisotropic with ax = ay reduces to isotropic.
    const float nh = 0.8f, th = 0.6f;
    EXPECT_NEAR(d_ggx_aniso(nh, th, 0.0f, 0.5f, 0.5f), d_ggx(nh, 0.5f), 1e-5);
}

TEST(Brdf, SmithHandValues)
{
    // G1(alpha = 1) = 2c / (c + 1).
    EXPECT_NEAR(g1_smith_ggx(0.5f, 1.0f), 2.0 * 0.5 / 1.5, 1e-6);
    // Normal incidence: G1 = 1, G2 = 1.
    EXPECT_NEAR(g1_smith_ggx(1.0f, 0.3f), 1.0, 1e-6);
    EXPECT_NEAR(g2_smith_correlated(1.0f, 1.0f, 0.3f), 1.0, 1e-6);
    // V = G2 / (4 nl nv) for the correlated closed form.
    for (float nv : {0.2f, 0.5f, 0.9f}) {
        for (float nl : {0.1f, 0.7f}) {
            for (float a : {0.05f, 0.3f, 1.0f}) {
                EXPECT_NEAR(v_smith_correlated(nv, nl, a),
                            g2_smith_correlated(nv, nl, a) / (4 * nv * nl),
                            1e-4 * v_smith_correlated(nv, nl, a));
                // Correlated masking hides no more than the separable form.
                EXPECT_GE(g2_smith_correlated(nv, nl, a) + 1e-6f, g2_smith_separable(nv, nl, a));
            }
        }
    }
    // Anisotropic V with ax = ay equals the isotropic V.
    const float nv = 0.6f, nl = 0.8f;
    EXPECT_NEAR(v_smith_correlated_aniso(nv, nl, 0.8f, 0.0f, 0.0f, 0.6f, 0.3f, 0.3f),
                v_smith_correlated(nv, nl, 0.3f),
                1e-5);
}

TEST(Brdf, CookTorranceExact)
{
    // min(1, 2 nh nv / vh, 2 nh nl / vh) with exact inputs.
    EXPECT_FLOAT_EQ(g_cook_torrance(0.9f, 0.2f, 0.5f, 0.6f), 2 * 0.9f * 0.2f / 0.6f);
    EXPECT_FLOAT_EQ(g_cook_torrance(0.9f, 0.5f, 0.1f, 0.6f), 2 * 0.9f * 0.1f / 0.6f);
    EXPECT_FLOAT_EQ(g_cook_torrance(1.0f, 0.9f, 0.9f, 0.9f), 1.0f);
}

TEST(Brdf, SchlickAndLambert)
{
    EXPECT_FLOAT_EQ(fresnel_schlick(0.04f, 1.0f), 0.04f);
    EXPECT_FLOAT_EQ(fresnel_schlick(0.04f, 0.0f), 1.0f);
    EXPECT_NEAR(fresnel_schlick(0.04f, 0.5f), 0.04 + 0.96 * std::pow(0.5, 5), 1e-7);
    EXPECT_NEAR(lambert(glm::vec3(1.0f)).x, 1.0 / M_PI, 1e-7);
}

// Integral over the hemisphere of D(h) (n.h) d omega = 1, by midpoint quadrature in
// (theta, phi); theta is sampled finely because D is narrow for small alpha.
double integrate_d(float ax, float ay)
{
    const int nt = 4000, np = ax == ay ? 1 : 256;
    double sum = 0.0;
    for (int i = 0; i < nt; ++i) {
        const double th = (i + 0.5) * (M_PI / 2) / nt;
        const double ct = std::cos(th), st = std::sin(th);
        for (int j = 0; j < np; ++j) {
            const double ph = (j + 0.5) * 2 * M_PI / np;
            const float d =
                ax == ay
                    ? d_ggx(float(ct), ax)
                    : d_ggx_aniso(
                          float(ct), float(st * std::cos(ph)), float(st * std::sin(ph)), ax, ay);
            sum += d * ct * st;
        }
    }
    return sum * (M_PI / 2 / nt) * (2 * M_PI / np);
}

TEST(Brdf, GgxNormalised)
{
    for (float r : {0.1f, 0.3f, 0.5f, 0.8f, 1.0f}) {
        const float a = roughness_to_alpha(r);
        EXPECT_NEAR(integrate_d(a, a), 1.0, 2e-3) << "roughness " << r;
    }
    EXPECT_NEAR(integrate_d(0.3f, 0.1f), 1.0, 2e-3);
    EXPECT_NEAR(integrate_d(0.05f, 0.5f), 1.0, 2e-3);
}

TEST(Brdf, EvaluateMatchesFormula)
{
    Surface s;
    s.albedo = glm::vec3(0.5f, 0.4f, 0.3f);
    s.roughness = 0.5f;
    s.metallic = 0.0f;
    const glm::vec3 n(0, 0, 1);
    const glm::vec3 v = glm::normalize(glm::vec3(0.3f, 0.0f, 1.0f));
    const glm::vec3 l = glm::normalize(glm::vec3(-0.5f, 0.2f, 1.0f));
    const glm::vec3 h = glm::normalize(v + l);
    const float a = 0.25f;
    const float spec =
        d_ggx(h.z, a) * v_smith_correlated(v.z, l.z, a) * fresnel_schlick(0.04f, glm::dot(v, h));
    const glm::vec3 expect = (s.albedo / kPi + glm::vec3(spec)) * l.z;
    const glm::vec3 got = evaluate(s, n, v, l);
    for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(got[c], expect[c], 1e-5 * expect[c]);
    }
    // Metal: no diffuse, F0 = albedo.
    s.metallic = 1.0f;
    EXPECT_EQ(diffuse_albedo(s), glm::vec3(0.0f));
    EXPECT_EQ(specular_f0(s), s.albedo);
    // Light below the horizon gives zero.
    EXPECT_EQ(evaluate(s, n, v, glm::vec3(0, 0, -1)), glm::vec3(0.0f));
}

TEST(Brdf, FiniteAtEdges)
{
    const glm::vec3 n(0, 0, 1);
    for (Geometry g :
         {Geometry::SmithCorrelated, Geometry::SmithSeparable, Geometry::CookTorrance}) {
        for (float r : {0.0f, 0.3f, 1.0f}) {
            for (float an : {0.0f, 0.8f, -1.0f}) {
                Surface s;
                s.roughness = r;
                s.anisotropy = an;
                s.metallic = 0.5f;
                for (float ev : {1.0f, 1e-7f, 0.0f, -0.01f}) {
                    for (float el : {1.0f, 1e-7f, 1e-3f}) {
                        const glm::vec3 v = glm::normalize(glm::vec3(1.0f, 0.0f, ev));
                        const glm::vec3 l = glm::normalize(glm::vec3(-1.0f, 0.1f, el));
                        const glm::vec3 f = evaluate(s, n, v, l, g);
                        EXPECT_TRUE(std::isfinite(f.x) && std::isfinite(f.y) && std::isfinite(f.z));
                        EXPECT_GE(f.x, 0.0f);
                    }
                }
                // Mirror direction at roughness 0: large but finite.
                const glm::vec3 m = evaluate(s, n, n, n, g);
                EXPECT_TRUE(std::isfinite(m.x));
            }
        }
    }
}

}  // namespace
}  // namespace posthaste::shading
