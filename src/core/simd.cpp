#include "core/simd.h"

#include <atomic>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#endif
#include <cstdlib>
#include <cstring>

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

Level initial()
{
    const char *env = std::getenv("POSTHASTE_SIMD");
    if (env && std::strcmp(env, "scalar") == 0) {
        return Level::Scalar;
    }
    return detected();  // unset, "avx2", or unknown (refused by the CLI: environment_error)
}

std::atomic<int> &current()
{
    static std::atomic<int> level{int(initial())};
    return level;
}

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

Level active()
{
    return Level(current().load(std::memory_order_relaxed));
}

void set_level(Level level)
{
    current().store(int(level) < int(detected()) ? int(level) : int(detected()),
                    std::memory_order_relaxed);
}

}  // namespace posthaste::simd
