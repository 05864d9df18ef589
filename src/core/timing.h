#pragma once
// Stage timers for the statistics that filters, the rasterizer and `posthaste bench` report:
// wall milliseconds since a steady-clock time point, and the CPU time of the whole process (all
// threads). On a shared machine a stage's wall time also counts waiting for a core; its CPU time
// much less.

#include <chrono>
#include <ctime>

namespace posthaste {

using SteadyClock = std::chrono::steady_clock;

/// Wall milliseconds since t0.
inline double ms_since(SteadyClock::time_point t0)
{
    return std::chrono::duration<double, std::milli>(SteadyClock::now() - t0).count();
}

/// CPU time of the whole process (every thread), milliseconds.
inline double process_cpu_ms()
{
    timespec ts{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return double(ts.tv_sec) * 1e3 + double(ts.tv_nsec) * 1e-6;
}

}  // namespace posthaste
