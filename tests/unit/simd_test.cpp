// The dispatch switch: the level kernels use, and the Highway targets it leaves them.
#include "core/simd.h"

#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <cstdint>
#include <cstdlib>

namespace posthaste {
namespace {

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
