// The AVX2 math helpers against libm, and the dispatch switch.
#include "core/simd.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <vector>

#include "core/simd_avx2.h"

namespace posthaste {
namespace {

#if POSTHASTE_HAVE_AVX2_TARGET

using simd::v8::V;

POSTHASTE_AVX2 void apply(const std::vector<float> &in, std::vector<float> &out, int fn)
{
    out.resize(in.size());
    for (std::size_t i = 0; i + 8 <= in.size(); i += 8) {
        const V x = _mm256_loadu_ps(&in[i]);
        V y;
        switch (fn) {
            case 0:
                y = simd::v8::exp(x);
                break;
            case 1:
                y = simd::v8::log(x);
                break;
            case 2:
                y = simd::v8::rcp(x);
                break;
            default:
                y = simd::v8::rsqrt(x);
                break;
        }
        _mm256_storeu_ps(&out[i], y);
    }
}

/// Relative error in units of float epsilon, largest over the inputs.
template <class F>
double worst_ulps(const std::vector<float> &in, const std::vector<float> &out, F ref)
{
    double worst = 0.0;
    for (std::size_t i = 0; i < in.size(); ++i) {
        const double r = ref(double(in[i]));
        const double err = std::abs(double(out[i]) - r) / std::max(std::abs(r), 1e-300);
        worst = std::max(worst, err / double(std::numeric_limits<float>::epsilon()));
    }
    return worst;
}

TEST(Simd, ExpLogRcpRsqrtMatchLibm)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    std::vector<float> xs, out;
    for (int i = 0; i < 8000; ++i) {
        xs.push_back(-87.0f + 175.0f * float(i) / 8000.0f);
    }
    apply(xs, out, 0);
    EXPECT_LT(worst_ulps(xs, out, [](double x) { return std::exp(x); }), 4.0);

    std::vector<float> pos;
    for (int i = 0; i < 8000; ++i) {
        pos.push_back(std::ldexp(1.0f + float(i % 1000) / 1000.0f, i / 1000 * 9 - 36));
    }
    apply(pos, out, 1);
    double worst = 0.0;  // log near 1 is small: absolute error there, relative elsewhere
    for (std::size_t i = 0; i < pos.size(); ++i) {
        const double r = std::log(double(pos[i]));
        worst = std::max(worst, std::abs(out[i] - r) / std::max(std::abs(r), 1.0));
    }
    EXPECT_LT(worst, 4.0 * double(std::numeric_limits<float>::epsilon()));
    apply(pos, out, 2);
    EXPECT_LT(worst_ulps(pos, out, [](double x) { return 1.0 / x; }), 4.0);
    apply(pos, out, 3);
    EXPECT_LT(worst_ulps(pos, out, [](double x) { return 1.0 / std::sqrt(x); }), 4.0);
}

TEST(Simd, ExpLogEdges)
{
    if (simd::detected() != simd::Level::Avx2) {
        GTEST_SKIP() << "no AVX2 on this CPU";
    }
    const float inf = std::numeric_limits<float>::infinity(), nan = std::nanf("");
    std::vector<float> in = {-1000.0f, -inf, 0.0f, 88.7f, 1000.0f, inf, nan, 1.0f}, out;
    apply(in, out, 0);
    EXPECT_EQ(out[0], 0.0f);
    EXPECT_EQ(out[1], 0.0f);
    EXPECT_EQ(out[2], 1.0f);
    EXPECT_TRUE(std::isfinite(out[3]) && out[3] > 1e38f);
    EXPECT_TRUE(std::isfinite(out[4]) && out[4] > 1e38f);
    EXPECT_TRUE(std::isfinite(out[5]));
    EXPECT_TRUE(std::isnan(out[6]));
    EXPECT_NEAR(out[7], 2.7182818f, 1e-6f);
    in = {0.0f, -1.0f, nan, inf, 1.0f, 2.0f, 0.5f, 1e-30f};
    apply(in, out, 1);
    EXPECT_TRUE(std::isnan(out[0]) || out[0] < -80.0f);
    EXPECT_TRUE(std::isnan(out[1]));
    EXPECT_TRUE(std::isnan(out[2]));
    EXPECT_EQ(out[3], inf);
    EXPECT_EQ(out[4], 0.0f);
    EXPECT_NEAR(out[5], 0.6931472f, 1e-7f);
    EXPECT_NEAR(out[6], -0.6931472f, 1e-7f);
    EXPECT_NEAR(out[7], std::log(1e-30f), 1e-5f);
}

#endif

TEST(Simd, ScopedLevelForcesScalarAndRestores)
{
    const simd::Level before = simd::active();
    {
        simd::ScopedLevel scalar(simd::Level::Scalar);
        EXPECT_EQ(simd::active(), simd::Level::Scalar);
        EXPECT_FALSE(simd::avx2());
    }
    EXPECT_EQ(simd::active(), before);
    // Asking for more than the CPU has gives what it has.
    simd::set_level(simd::Level::Avx2);
    EXPECT_EQ(simd::active(), simd::detected());
    simd::set_level(before);
}

TEST(Simd, LevelSteersTheHighwayKernels)
{
    // Scalar leaves Highway only its portable one-lane target; back at the CPU's level, the
    // vector targets return (this CPU has at least SSE4 when it has AVX2).
    const std::int64_t portable = HWY_SCALAR | HWY_EMU128;
    {
        simd::ScopedLevel scalar(simd::Level::Scalar);
        EXPECT_EQ(hwy::SupportedTargets() & ~portable, 0);
        EXPECT_NE(hwy::SupportedTargets() & portable, 0);
    }
    if (simd::detected() == simd::Level::Avx2 && std::getenv("POSTHASTE_SIMD") == nullptr) {
        EXPECT_NE(hwy::SupportedTargets() & HWY_AVX2, 0);
    }
}

}  // namespace
}  // namespace posthaste
