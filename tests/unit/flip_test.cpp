// Tests for src/metrics/flip.h: each stage against hand-computed values (reference numbers
// worked out in double precision from the formulas in the FLIP papers), then whole-image cases.

#include "metrics/flip.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "core/error.h"
#include "core/hash.h"
#include "core/parallel.h"

namespace posthaste::metrics {
namespace {

using namespace flip;

Image constant_image(int w, int h, glm::vec3 rgb)
{
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < 3; ++c) {
                img.at(x, y, c) = rgb[c];
            }
        }
    }
    return img;
}

Image noise_image(int w, int h, std::uint32_t seed)
{
    Image img(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < 3; ++c) {
                img.at(x, y, c) = 0.2f + 0.6f * hash_unit(x / 4, y / 4, c, seed);
            }
        }
    }
    return img;
}

void expect_vec_near(glm::vec3 got, glm::vec3 want, float tol)
{
    EXPECT_NEAR(got.x, want.x, tol);
    EXPECT_NEAR(got.y, want.y, tol);
    EXPECT_NEAR(got.z, want.z, tol);
}

TEST(Flip, ColorTransformsOnKnownColors)
{
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.2140411f, 1e-6f);
    EXPECT_NEAR(srgb_to_linear(0.04f), 0.04f / 12.92f, 1e-7f);
    EXPECT_NEAR(linear_to_srgb(srgb_to_linear(0.7f)), 0.7f, 1e-6f);
    // RGB (1, 1, 1) is the D65 white; it maps to Yy = 100, Cx = Cz = 0; black to Yy = -16.
    expect_vec_near(linear_rgb_to_xyz(glm::vec3(1.0f)), {0.9504285f, 1.0f, 1.0889004f}, 1e-6f);
    expect_vec_near(xyz_to_ycxcz(linear_rgb_to_xyz(glm::vec3(1.0f))), {100.0f, 0.0f, 0.0f}, 1e-4f);
    expect_vec_near(xyz_to_ycxcz(glm::vec3(0.0f)), {-16.0f, 0.0f, 0.0f}, 1e-6f);
    expect_vec_near(xyz_to_ycxcz(linear_rgb_to_xyz({1.0f, 0.0f, 0.0f})),
                    {8.665871f, 110.629284f, 38.976880f},
                    1e-3f);
    // sRGB red in CIELAB (D65): the textbook (53.24, 80.09, 67.20).
    expect_vec_near(
        xyz_to_lab(linear_rgb_to_xyz({1.0f, 0.0f, 0.0f})), {53.24f, 80.09f, 67.20f}, 0.01f);
    expect_vec_near(xyz_to_lab(linear_rgb_to_xyz(glm::vec3(1.0f))), {100.0f, 0.0f, 0.0f}, 1e-4f);
    // Round trips.
    const glm::vec3 c(0.3f, 0.6f, 0.1f);
    expect_vec_near(xyz_to_linear_rgb(linear_rgb_to_xyz(c)), c, 1e-6f);
    expect_vec_near(ycxcz_to_xyz(xyz_to_ycxcz(linear_rgb_to_xyz(c))), linear_rgb_to_xyz(c), 1e-6f);
}

TEST(Flip, HuntAdjustmentAndHyab)
{
    expect_vec_near(hunt_adjust({50.0f, 20.0f, -10.0f}), {50.0f, 10.0f, -5.0f}, 1e-6f);
    // |50 - 40| + sqrt(3^2 + 4^2)
    EXPECT_FLOAT_EQ(hyab({50.0f, 10.0f, -5.0f}, {40.0f, 13.0f, -1.0f}), 15.0f);
    EXPECT_EQ(hyab({1.0f, 2.0f, 3.0f}, {1.0f, 2.0f, 3.0f}), 0.0f);
    // Hunt-adjusted green vs blue: HyAB 203.3017, to the power 0.7: 41.2761.
    EXPECT_NEAR(max_color_distance(), 41.27610f, 2e-3f);
}

TEST(Flip, ColorDifferenceRemap)
{
    const float cmax = max_color_distance();
    EXPECT_EQ(remap_color_difference(0.0f, cmax), 0.0f);
    EXPECT_NEAR(remap_color_difference(kPc * cmax, cmax), kPt, 1e-6f);
    EXPECT_NEAR(remap_color_difference(0.5f * kPc * cmax, cmax), 0.5f * kPt, 1e-6f);
    EXPECT_NEAR(remap_color_difference(cmax, cmax), 1.0f, 1e-6f);
    // Black vs white: HyAB 100, 100^0.7 = 25.1189 above the knee 16.51: 0.96738.
    EXPECT_NEAR(remap_color_difference(std::pow(100.0f, kQc), cmax), 0.967380f, 1e-5f);
}

TEST(Flip, CsfKernelsNormalisedWithPpdRadius)
{
    // r = ceil(3 sqrt(0.04 / (2 pi^2)) ppd): 9.05 -> 10 at 67.02 ppd, 4.05 -> 5 at 30 ppd.
    for (int ch = 0; ch < 3; ++ch) {
        const CsfKernel k = csf_kernel(ch, kDefaultPixelsPerDegree);
        EXPECT_EQ(k.radius, 10);
        double sum = 0.0;
        for (int dy = -k.radius; dy <= k.radius; ++dy) {
            for (int dx = -k.radius; dx <= k.radius; ++dx) {
                sum += k.at(dx, dy);
                EXPECT_FLOAT_EQ(k.at(dx, dy), k.at(-dx, dy));
                EXPECT_FLOAT_EQ(k.at(dx, dy), k.at(dy, dx));
            }
        }
        EXPECT_NEAR(sum, 1.0, 1e-5) << "channel " << ch;
        EXPECT_GT(k.at(0, 0), k.at(1, 0));
        EXPECT_GT(k.at(1, 0), k.at(2, 0));
    }
    EXPECT_EQ(csf_kernel(0, 30.0f).radius, 5);
    EXPECT_EQ(csf_kernel(2, kDefaultPixelsPerDegree).weight.size(), 2u);  // two Gaussians
    EXPECT_EQ(csf_kernel(0, kDefaultPixelsPerDegree).weight.size(), 1u);
    // The achromatic CSF is narrower than the blue-yellow one.
    EXPECT_GT(csf_kernel(0, kDefaultPixelsPerDegree).at(0, 0),
              csf_kernel(2, kDefaultPixelsPerDegree).at(0, 0));
    EXPECT_THROW(csf_kernel(3, 67.0f), Error);
}

TEST(Flip, FeatureKernelsNormalised)
{
    // sd = 0.5 * 0.082 * 67.02 = 2.748, radius ceil(8.24) = 9.
    const FeatureKernels k = feature_kernels(kDefaultPixelsPerDegree);
    EXPECT_EQ(k.radius, 9);
    ASSERT_EQ(k.g.size(), 19u);
    double g = 0.0, d1p = 0.0, d1n = 0.0, d2p = 0.0, d2n = 0.0;
    for (std::size_t i = 0; i < k.g.size(); ++i) {
        g += k.g[i];
        (k.d1[i] > 0 ? d1p : d1n) += k.d1[i];
        (k.d2[i] > 0 ? d2p : d2n) += k.d2[i];
        EXPECT_FLOAT_EQ(k.d1[i], -k.d1[k.g.size() - 1 - i]);  // odd
        EXPECT_FLOAT_EQ(k.d2[i], k.d2[k.g.size() - 1 - i]);   // even
    }
    EXPECT_NEAR(g, 1.0, 1e-6);
    EXPECT_NEAR(d1p, 1.0, 1e-6);
    EXPECT_NEAR(d1n, -1.0, 1e-6);
    EXPECT_NEAR(d2p, 1.0, 1e-6);
    EXPECT_NEAR(d2n, -1.0, 1e-6);
    EXPECT_LT(k.d2[9], 0.0f);   // the point detector's centre is negative
    EXPECT_LT(k.d1[10], 0.0f);  // -x g(x): negative right of centre
}

TEST(Flip, ToneMapperAndExposureTarget)
{
    EXPECT_EQ(tone_map_aces(0.0f), 0.0f);
    EXPECT_EQ(tone_map_aces(1e6f), 1.0f);  // clamped
    EXPECT_NEAR(tone_target_input(), 2.1188723f, 1e-5f);
    EXPECT_NEAR(tone_map_aces(tone_target_input()), kToneTarget, 1e-6f);
}

TEST(Flip, IdenticalImagesGiveExactlyZero)
{
    const Image a = noise_image(40, 30, 3);
    FlipResult r = flip_ldr(a, a);
    EXPECT_EQ(r.mean, 0.0);
    EXPECT_EQ(r.max, 0.0f);
    r = flip_hdr(a, a);
    EXPECT_EQ(r.mean, 0.0);
    EXPECT_EQ(r.max, 0.0f);
    ASSERT_EQ(r.error_map.channels(), 1);
    for (std::size_t i = 0; i < r.error_map.value_count(); ++i) {
        ASSERT_EQ(r.error_map.data()[i], 0.0f);
    }
}

TEST(Flip, ConstantImagesGiveTheColorErrorAlone)
{
    // Flat images: CSF filtering keeps them, features vanish, so FLIP is the remapped HyAB.
    FlipResult r =
        flip_ldr(constant_image(8, 6, glm::vec3(0.0f)), constant_image(8, 6, glm::vec3(1.0f)));
    EXPECT_NEAR(r.mean, 0.967380, 2e-3);
    EXPECT_NEAR(r.max, 0.967380f, 2e-3f);
    // sRGB grey 0.5 vs 0.6: HyAB 9.8336 -> 0.285013.
    r = flip_ldr(constant_image(8, 6, glm::vec3(0.5f)), constant_image(8, 6, glm::vec3(0.6f)));
    EXPECT_NEAR(r.mean, 0.285013, 2e-3);
    // Red vs blue at sRGB 0.8: 0.954595.
    r = flip_ldr(constant_image(5, 5, {0.8f, 0.0f, 0.0f}),
                 constant_image(5, 5, {0.0f, 0.0f, 0.8f}));
    EXPECT_NEAR(r.mean, 0.954595, 2e-3);
}

TEST(Flip, LargerPerturbationGivesLargerError)
{
    const Image ref = noise_image(64, 48, 5);
    double previous = 0.0;
    for (float amount : {0.01f, 0.05f, 0.2f}) {
        Image test = ref;
        for (int y = 0; y < 48; ++y) {
            for (int x = 0; x < 64; ++x) {
                for (int c = 0; c < 3; ++c) {
                    test.at(x, y, c) += amount * (hash_unit(x, y, c, 77) - 0.5f);
                }
            }
        }
        const FlipResult r = flip_ldr(ref, test);
        EXPECT_GT(r.mean, previous) << "amount " << amount;
        EXPECT_LE(r.max, 1.0f);
        previous = r.mean;
    }
}

TEST(Flip, SinglePixelDifferenceIsLocal)
{
    const Image ref = constant_image(41, 41, glm::vec3(0.5f));
    Image test = ref;
    test.at(20, 20, 0) = 1.0f;
    const FlipResult r = flip_ldr(ref, test);
    EXPECT_EQ(r.max_x, 20);
    EXPECT_EQ(r.max_y, 20);
    EXPECT_GT(r.max, 0.05f);
    EXPECT_LT(r.error_map.at(0, 0, 0), 1e-3f);  // beyond both filter radii
}

TEST(Flip, HdrExposureRangeFromReference)
{
    // Luminance: 4 in one pixel, 1 elsewhere (median 1).
    Image ref = constant_image(5, 5, glm::vec3(1.0f));
    ref.at(2, 2, 0) = ref.at(2, 2, 1) = ref.at(2, 2, 2) = 4.0f;
    Image test = ref;
    test.at(1, 1, 1) = 1.5f;
    const FlipResult r = flip_hdr(ref, test);
    EXPECT_NEAR(r.start_exposure, std::log2(2.1188723f / 4.0f), 1e-4f);
    EXPECT_NEAR(r.stop_exposure, std::log2(2.1188723f), 1e-4f);
    EXPECT_EQ(r.num_exposures, 2);  // max(2, ceil(2))
    EXPECT_GT(r.max, 0.0f);
    EXPECT_EQ(r.max_x, 1);
    EXPECT_EQ(r.max_y, 1);
    FlipOptions o;
    o.start_exposure = -3.0f;
    o.stop_exposure = 2.5f;
    const FlipResult r2 = flip_hdr(ref, test, o);
    EXPECT_EQ(r2.num_exposures, 6);  // ceil(5.5)
    // More exposures take a max over more LDR maps, so the error cannot be smaller.
    EXPECT_GE(r2.mean, flip_ldr(ref, ref).mean);
}

TEST(Flip, ThreadCountIndependent)
{
    const Image ref = noise_image(150, 70, 8);
    const Image test = noise_image(150, 70, 9);
    set_thread_count(1);
    const FlipResult one = flip_hdr(ref, test);
    set_thread_count(2);
    const FlipResult two = flip_hdr(ref, test);
    set_thread_count(0);
    EXPECT_TRUE(one.error_map.bit_equal(two.error_map));
    EXPECT_EQ(one.mean, two.mean);
}

TEST(Flip, RejectsMismatchedInputs)
{
    EXPECT_THROW(flip_ldr(Image(4, 4, 3), Image(4, 5, 3)), Error);
    EXPECT_THROW(flip_ldr(Image(4, 4, 1), Image(4, 4, 1)), Error);
}

TEST(Flip, ColorMapDarkToBright)
{
    expect_vec_near(flip_color_map(0.0f), {0.00f, 0.00f, 0.02f}, 1e-6f);
    expect_vec_near(flip_color_map(1.0f), {0.99f, 0.99f, 0.75f}, 1e-6f);
    expect_vec_near(flip_color_map(2.0f), flip_color_map(1.0f), 0.0f);
    expect_vec_near(flip_color_map(std::nanf("")), flip_color_map(1.0f), 0.0f);
    // Halfway between control points 3/7 and 4/7.
    expect_vec_near(flip_color_map(3.5f / 7.0f), {0.615f, 0.17f, 0.49f}, 1e-5f);
    float previous = -1.0f;
    for (int i = 0; i <= 100; ++i) {
        const glm::vec3 c = flip_color_map(float(i) / 100.0f);
        const float luma = 0.2126f * srgb_to_linear(c.x) + 0.7152f * srgb_to_linear(c.y) +
                           0.0722f * srgb_to_linear(c.z);
        EXPECT_GT(luma, previous) << "t = " << i / 100.0;
        previous = luma;
    }
    Image e(2, 1, 1);
    e.at(1, 0, 0) = 1.0f;
    const Image h = flip_heatmap(e, false);
    ASSERT_EQ(h.channels(), 3);
    EXPECT_FLOAT_EQ(h.at(1, 0, 2), 0.75f);
    EXPECT_FLOAT_EQ(flip_heatmap(e, true).at(1, 0, 2), srgb_to_linear(0.75f));
}

}  // namespace
}  // namespace posthaste::metrics
