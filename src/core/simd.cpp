#include "core/simd.h"

#include <hwy/targets.h>

#include <atomic>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif

namespace posthaste::simd {

bool cpu_has_f16c()
{
#if defined(__x86_64__) || defined(__i386__)
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    return __get_cpuid(1, &eax, &ebx, &ecx, &edx) && (ecx & bit_F16C) != 0;
#else
    return false;
#endif
}

namespace {

Level detect()
{
#if POSTHASTE_HAVE_AVX2_TARGET
    __builtin_cpu_init();
    if (__builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && cpu_has_f16c()) {
        return Level::Avx2;
    }
#endif
    return Level::Scalar;
}

/// Whether POSTHASTE_SIMD is set to `value`.
bool env_says(const char *value)
{
    const char *env = std::getenv("POSTHASTE_SIMD");
    return env && std::strcmp(env, value) == 0;
}

/// The level asked for at start: Scalar for POSTHASTE_SIMD=scalar, otherwise the best there is
/// (unset, "avx2", or an unknown value, which the CLI refuses: environment_error).
Level requested_at_start()
{
    return env_says("scalar") ? Level::Scalar : Level::Avx2;
}

// The Highway kernels follow the level asked for: Scalar leaves them only the portable scalar
// target (the same source compiled for one lane); otherwise they dispatch to the best target the
// CPU has (SSE4 on a CPU without AVX2, AVX-512 where it is there), or at most AVX2 when
// POSTHASTE_SIMD=avx2 says so (to measure that target on an AVX-512 machine).
void apply_to_highway(Level requested)
{
    std::int64_t disabled = 0;
    if (requested == Level::Scalar) {
        disabled = ~std::int64_t(HWY_SCALAR | HWY_EMU128);
    } else if (env_says("avx2")) {
        disabled = std::int64_t(HWY_AVX3) | std::int64_t(HWY_AVX3_DL);
    }
    hwy::DisableTargets(disabled);
}

/// The level last asked for (POSTHASTE_SIMD, then set_level), before clamping to the CPU's.
std::atomic<int> &asked()
{
    static std::atomic<int> level{int(requested_at_start())};
    return level;
}

std::atomic<int> &current()
{
    static std::atomic<int> level{[] {
        const Level requested = Level(asked().load());
        apply_to_highway(requested);
        return int(requested) < int(detected()) ? int(requested) : int(detected());
    }()};
    return level;
}

// POSTHASTE_SIMD=scalar reaches the Highway kernels before any of them runs.
[[maybe_unused]] const int g_initial_level = current().load();

}  // namespace

std::string environment_error()
{
    const char *env = std::getenv("POSTHASTE_SIMD");
    if (!env || !*env || std::strcmp(env, "scalar") == 0 || std::strcmp(env, "avx2") == 0) {
        return "";
    }
    return std::string("environment variable POSTHASTE_SIMD: unknown value \"") + env +
           "\" (expected \"scalar\" or \"avx2\")";
}

Level detected()
{
    static const Level level = detect();
    return level;
}

Level requested()
{
    return Level(asked().load(std::memory_order_relaxed));
}

Level active()
{
    return Level(current().load(std::memory_order_relaxed));
}

void set_level(Level level)
{
    asked().store(int(level), std::memory_order_relaxed);
    current().store(int(level) < int(detected()) ? int(level) : int(detected()),
                    std::memory_order_relaxed);
    apply_to_highway(level);
}

}  // namespace posthaste::simd
