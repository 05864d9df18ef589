#pragma once
// CPU dispatch for the vectorized kernels. The build targets baseline x86-64. Every kernel is
// written once over Google Highway's lane types (the *_kernels.cpp files), compiled for every
// x86 target and dispatched at run time to the best the CPU has. Some keep a scalar reference
// (a per-pixel loop the vector rows follow, or a different algorithm where the rows lack an
// option). Tests lower the level with simd::set_level (Scalar: the references, and Highway's
// portable one-lane target of the same source) or pick a Highway target, and check that the
// results agree: bit for bit where a kernel promises it, else within a stated tolerance; each
// level alone is bit-stable for any thread count.
//
// Environment: POSTHASTE_SIMD=scalar disables the vector paths (to compare or to debug);
// POSTHASTE_SIMD=avx2 uses them up to AVX2 (Highway kernels skip AVX-512); unset, the best the
// CPU has.

#include <string>

namespace posthaste::simd {

/// True when the CPU has F16C (half-float conversions); cpuid, so that GCC and clang agree
/// (clang 14's __builtin_cpu_supports does not know "f16c").
bool cpu_has_f16c();

enum class Level { Scalar = 0, Avx2 = 1 };

/// The best level this CPU (and build) supports.
Level detected();
/// The level kernels use: detected(), lowered by POSTHASTE_SIMD=scalar or set_level.
Level active();
/// The level asked for (POSTHASTE_SIMD, set_level), whatever the CPU has. A kernel whose vector
/// path is a Highway kernel (which runs on every CPU, on its best target) and that keeps a
/// scalar reference checks this instead of active(): Scalar asks for the reference.
Level requested();
/// Use at most `level` from now on (clamped to detected()). Not thread-safe against running
/// kernels: call between frames (tests, the CLI).
void set_level(Level level);

/// "" when POSTHASTE_SIMD is unset, empty, "scalar" or "avx2" (the best the CPU has, up to
/// AVX2); otherwise a one-line message naming the variable and the value. Kernels ignore an
/// unknown value (they use detected()); the CLI refuses it with exit code 2.
std::string environment_error();

/// Whether the CPU has AVX2 + FMA + F16C and the level allows it.
inline bool avx2()
{
    return active() == Level::Avx2;
}

/// Scoped override, for tests: restores the previous level on destruction.
class ScopedLevel {
   public:
    explicit ScopedLevel(Level level) : previous_(active()) { set_level(level); }
    ~ScopedLevel() { set_level(previous_); }
    ScopedLevel(const ScopedLevel &) = delete;
    ScopedLevel &operator=(const ScopedLevel &) = delete;

   private:
    Level previous_;
};

}  // namespace posthaste::simd

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#define POSTHASTE_HAVE_AVX2_TARGET 1
#else
#define POSTHASTE_HAVE_AVX2_TARGET 0
#endif
