// The one main() of posthaste_benchmarks; each tests/bench/*.cpp only registers benchmarks.

#include <benchmark/benchmark.h>

BENCHMARK_MAIN();
