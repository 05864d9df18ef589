// Running a graph over frames (graph/run.h): several frames at once (jobs), tiles in parallel
// inside each node (threads), with a progress bar on a terminal and a summary.

#include "graph/run.h"

#include <tbb/parallel_pipeline.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>

#include "core/error.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/text.h"
#include "graph/graph.h"
#include "io/image_file.h"

namespace posthaste {
namespace {

std::string format_seconds(double s)
{
    char buf[32];
    if (s < 60.0) {
        std::snprintf(buf, sizeof(buf), "%.1fs", s);
    } else {
        std::snprintf(buf, sizeof(buf), "%dm%02ds", int(s) / 60, int(s) % 60);
    }
    return buf;
}

}  // namespace

std::vector<int> frames_done(const Graph &graph, const std::vector<int> &frames)
{
    std::vector<int> done;
    for (int f : frames) {
        const std::vector<std::string> outputs = graph.outputs(f);
        bool whole = !outputs.empty();
        for (const std::string &path : outputs) {
            std::error_code ec;
            whole = whole && std::filesystem::exists(path, ec) && verify_image_file(path).empty();
        }
        if (whole) {
            done.push_back(f);
        }
    }
    return done;
}

void apply_memory_budget(const std::string &max_memory)
{
    if (max_memory.empty()) {
        set_image_memory_budget(available_memory_bytes() / 10 * 8);
        return;
    }
    set_image_memory_budget(parse_memory_size(max_memory, "--max-memory"));
}

int default_jobs(int threads)
{
    return std::clamp(threads / 2, 1, 4);
}

int run_graph(Graph &graph, const RunSettings &o)
{
    set_thread_count(o.threads);
    apply_memory_budget(o.max_memory);
    std::vector<int> frames =
        o.frames.empty() ? graph.default_frames() : parse_frame_list(o.frames, "--frames");
    graph.check(frames, o.dry_run && !o.skip_bad_frames);
    if (o.skip_existing) {
        const std::vector<int> done = frames_done(graph, frames);
        std::erase_if(frames,
                      [&](int f) { return std::find(done.begin(), done.end(), f) != done.end(); });
        if (!o.quiet && !done.empty()) {
            std::fprintf(stderr, "%zu frame(s) already written and whole, skipped\n", done.size());
        }
    }
    if (o.dry_run) {
        if (!o.quiet) {
            std::printf("%s: valid; %zu frame(s)\n", graph.origin().c_str(), frames.size());
        }
        return 0;
    }
    // --jobs auto (o.jobs < 0) runs the first frame alone, then as many frames at once as the
    // threads, at most what the memory budget holds of the first frame's peak of pass images.
    // The default gives each frame at least two threads (docs/PERFORMANCE.md, "Cores, jobs and
    // threads": on two cores one job of two threads was 0.93x the time of two jobs, at 0.65x
    // the memory).
    const bool automatic = o.jobs < 0;
    int jobs = automatic ? 1 : o.jobs > 0 ? o.jobs : default_jobs(thread_count());
    NodeTimes times = graph.make_times();
    const bool terminal = stderr_is_terminal() && !o.quiet;
    std::mutex mutex;
    std::map<int, std::string> failures;  // frame -> message
    std::map<int, int> failure_codes;
    std::set<int> output_failures;  // frames whose outputs failed (never skipped)
    std::atomic<bool> stop{false};
    std::atomic<int> done{0};
    std::size_t next = 0;
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };

    // Frames queue[next, last) with `tokens` of them in flight. A frame the memory budget
    // refuses while others are in flight goes to `over_budget` and stops the round; the next
    // round runs it and the rest with half the frames at once (alone, a refusal fails it).
    std::vector<int> queue(frames.begin(), frames.end());
    std::vector<int> over_budget;
    std::atomic<bool> throttle{false};
    std::size_t last = queue.size();
    const auto run_frames = [&](int tokens) {
        tbb::parallel_pipeline(
            std::size_t(tokens),
            tbb::make_filter<void, int>(tbb::filter_mode::serial_in_order,
                                        [&](tbb::flow_control &fc) -> int {
                                            if (next >= last || stop.load() || throttle.load() ||
                                                (o.should_stop && o.should_stop())) {
                                                fc.stop();
                                                return 0;
                                            }
                                            return queue[next++];
                                        }) &
                tbb::make_filter<int, void>(tbb::filter_mode::parallel, [&](int frame) {
                    const auto t0 = std::chrono::steady_clock::now();
                    std::string error;
                    int code = 0;
                    bool output = false;  // a sink failed: no bad input to pass over
                    try {
                        graph.evaluate(frame, &times);
                    } catch (const MemoryBudgetError &e) {
                        if (tokens > 1) {
                            std::lock_guard lock(mutex);
                            over_budget.push_back(frame);
                            throttle = true;
                            return;
                        }
                        error = e.what();
                        code = e.exit_code();
                        output = e.output();
                    } catch (const OutputError &e) {
                        error = e.what();
                        code = e.exit_code();
                        output = true;
                    } catch (const Error &e) {
                        error = e.what();
                        code = e.exit_code();
                    } catch (const std::exception &e) {
                        error = e.what();
                        code = int(ExitCode::Runtime);
                    }
                    const double dt =
                        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
                            .count();
                    std::lock_guard lock(mutex);
                    const int n = ++done;
                    if (o.on_frame) {
                        const double started =
                            std::chrono::duration<double>(
                                std::chrono::system_clock::now().time_since_epoch())
                                .count() -
                            dt;
                        o.on_frame(frame, started, dt, error);
                    }
                    if (error.empty() && o.frames_written) {
                        o.frames_written->push_back(frame);
                    }
                    if (!error.empty()) {
                        failures[frame] = error;
                        failure_codes[frame] = code;
                        if (output) {
                            output_failures.insert(frame);
                        }
                        if ((!o.skip_bad_frames || output) && !o.keep_going) {
                            stop = true;
                        } else {
                            std::fprintf(stderr,
                                         "%swarning: frame %d skipped: %s\n",
                                         terminal ? "\r\033[K" : "",
                                         frame,
                                         printable_line(error).c_str());
                        }
                    }
                    if (o.quiet) {
                        return;
                    }
                    const double t = elapsed();
                    const double fps = n / std::max(t, 1e-9);
                    const double eta = (double(frames.size()) - n) / std::max(fps, 1e-9);
                    if (terminal) {
                        const int width = 30;
                        const int filled = int(width * double(n) / double(frames.size()));
                        // The node that has taken the most time so far, per frame done.
                        std::string slowest;
                        double slowest_ns = -1.0;
                        for (int i : graph.order()) {
                            const double ns = double(*times.nanoseconds[std::size_t(i)]);
                            if (ns > slowest_ns) {
                                slowest_ns = ns;
                                slowest = graph.nodes()[std::size_t(i)].identity.id;
                            }
                        }
                        std::fprintf(stderr,
                                     "\r[%s%s] %d/%zu frames  %.2f fps  ETA %s  slowest: %s %.0f "
                                     "ms/frame\033[K",
                                     std::string(std::size_t(filled), '#').c_str(),
                                     std::string(std::size_t(width - filled), '-').c_str(),
                                     n,
                                     frames.size(),
                                     fps,
                                     format_seconds(eta).c_str(),
                                     slowest.c_str(),
                                     slowest_ns * 1e-6 / n);
                    } else if (error.empty()) {
                        std::fprintf(stderr,
                                     "frame %d done in %.3fs (%d/%zu)\n",
                                     frame,
                                     dt,
                                     n,
                                     frames.size());
                    }
                }));
    };
    if (automatic && frames.size() > 1) {
        const std::size_t before = image_memory_in_use();
        reset_image_memory_peak();
        last = 1;
        run_frames(1);
        last = frames.size();
        const std::size_t per_frame = std::max<std::size_t>(image_memory_peak() - before, 1);
        const std::size_t budget = image_memory_budget();
        // Three quarters of the budget: later frames may peak higher than the first.
        const std::size_t by_memory =
            budget ? std::max<std::size_t>(budget / 4 * 3 / per_frame, 1) : 1024;
        jobs = int(std::clamp<std::size_t>(
            std::min(by_memory, std::size_t(std::max(1, thread_count()))), 1, 256));
        if (!o.quiet) {
            std::fprintf(
                stderr,
                "%s--jobs auto: %d (%d thread(s); a frame peaked at %s of pass images%s)\n",
                terminal ? "\r\033[K" : "",
                jobs,
                thread_count(),
                format_bytes(per_frame).c_str(),
                budget ? (", budget " + format_bytes(budget)).c_str() : "");
        }
    }
    run_frames(jobs);
    while (!over_budget.empty() && !stop.load() && !(o.should_stop && o.should_stop())) {
        // The refused frames first (in the order they were given), then those not started.
        std::vector<int> again;
        for (const int f : queue) {
            if (std::find(over_budget.begin(), over_budget.end(), f) != over_budget.end()) {
                again.push_back(f);
            }
        }
        again.insert(again.end(), queue.begin() + std::ptrdiff_t(next), queue.end());
        const int before = jobs;
        jobs = std::max(1, jobs / 2);
        std::fprintf(stderr,
                     "%swarning: over the memory budget (%s) with %d frames at once: the %zu "
                     "frame(s) left, from frame %d, run %d at once\n",
                     terminal ? "\r\033[K" : "",
                     format_bytes(image_memory_budget()).c_str(),
                     before,
                     again.size(),
                     again.front(),
                     jobs);
        queue = std::move(again);
        over_budget.clear();
        throttle = false;
        next = 0;
        last = queue.size();
        run_frames(jobs);
    }
    if (terminal) {
        std::fprintf(stderr, "\n");
    }
    const double wall = elapsed();
    if (o.node_seconds) {
        for (int i : graph.order()) {
            const GraphNode &gn = graph.nodes()[std::size_t(i)];
            (*o.node_seconds)[gn.identity.id + " (" + gn.identity.type + ")"] =
                double(*times.nanoseconds[std::size_t(i)]) * 1e-9;
        }
    }
    // --skip-bad-frames passes over bad inputs, not outputs that could not be written.
    if (!failures.empty() && (!o.skip_bad_frames || !output_failures.empty())) {
        const int frame = o.skip_bad_frames ? *output_failures.begin() : failures.begin()->first;
        const std::string &message = failures[frame];
        if (o.keep_going && failures.size() > 1) {
            throw Error(ExitCode(failure_codes[frame]),
                        message + " (and " + std::to_string(failures.size() - 1) +
                            " more failed frame(s))");
        }
        throw Error(ExitCode(failure_codes[frame]), message);
    }
    if (!o.quiet) {
        const int ok = done.load() - int(failures.size());
        std::printf(
            "%d frame(s) in %.3f s (%.2f frames/s, %d job(s), %d thread(s))%s\n",
            ok,
            wall,
            ok / std::max(wall, 1e-9),
            jobs,
            thread_count(),
            failures.empty() ? "" : (", " + std::to_string(failures.size()) + " skipped").c_str());
        std::printf("%-20s %-12s %12s %14s\n", "node", "type", "total s", "ms/frame");
        for (int i : graph.order()) {
            const GraphNode &gn = graph.nodes()[std::size_t(i)];
            const double s = double(*times.nanoseconds[std::size_t(i)]) * 1e-9;
            std::printf("%-20s %-12s %12.3f %14.2f\n",
                        gn.identity.id.c_str(),
                        gn.identity.type.c_str(),
                        s,
                        1000.0 * s / std::max(1, done.load()));
        }
    }
    return 0;
}

bool stderr_is_terminal()
{
    return ::isatty(2) != 0;
}

}  // namespace posthaste
