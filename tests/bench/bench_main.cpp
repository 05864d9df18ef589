// The one main() of posthaste_benchmarks; each tests/bench/*.cpp only registers benchmarks.
// POSTHASTE_BENCH_KEEP_HEAP=1 keeps freed memory in the heap (no mmap, no trim), to separate the
// cost of page faults on fresh pass images from the work itself.

#include <benchmark/benchmark.h>
#include <malloc.h>

#include <cstdlib>

int main(int argc, char **argv)
{
    if (const char *keep = std::getenv("POSTHASTE_BENCH_KEEP_HEAP"); keep && keep[0] == '1') {
        mallopt(M_MMAP_MAX, 0);
        mallopt(M_TRIM_THRESHOLD, 1 << 30);
    }
    benchmark::Initialize(&argc, argv);
    if (benchmark::ReportUnrecognizedArguments(argc, argv)) {
        return 1;
    }
    benchmark::RunSpecifiedBenchmarks();
    benchmark::Shutdown();
    return 0;
}
