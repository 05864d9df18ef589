#include "core/parallel.h"

#include <OpenImageIO/imageio.h>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <thread>

namespace posthaste {
namespace {

std::mutex g_control_mutex;
std::unique_ptr<tbb::global_control> g_control;
int g_threads = 0;

}  // namespace

void parallel_for_tiles(const Rect &bounds,
                        const std::function<void(const Rect &)> &fn,
                        int tile_size)
{
    if (bounds.empty()) {
        return;
    }
    const int tiles_x = (bounds.width() + tile_size - 1) / tile_size;
    const int tiles_y = (bounds.height() + tile_size - 1) / tile_size;
    tbb::parallel_for(
        tbb::blocked_range<int>(0, tiles_x * tiles_y), [&](const tbb::blocked_range<int> &r) {
            for (int i = r.begin(); i != r.end(); ++i) {
                const int tx = i % tiles_x, ty = i / tiles_x;
                const Rect tile{bounds.x0 + tx * tile_size,
                                bounds.y0 + ty * tile_size,
                                std::min(bounds.x0 + (tx + 1) * tile_size, bounds.x1),
                                std::min(bounds.y0 + (ty + 1) * tile_size, bounds.y1)};
                fn(tile);
            }
        });
}

void parallel_for(int begin, int end, const std::function<void(int)> &fn)
{
    if (end <= begin) {
        return;
    }
    tbb::parallel_for(begin, end, [&](int i) { fn(i); });
}

void set_thread_count(int threads)
{
    std::lock_guard lock(g_control_mutex);
    g_control.reset();
    if (threads > 0) {
        g_control = std::make_unique<tbb::global_control>(
            tbb::global_control::max_allowed_parallelism, std::size_t(threads));
    }
    g_threads = threads;
    // OpenImageIO's own pool and OpenEXR's (which compresses and decompresses a file's blocks)
    // follow: a job given two threads on a 64-core farm node compresses on two, not on 64.
    // 0: both take the hardware's count, as they do by default.
    OIIO::attribute("threads", std::max(threads, 0));
    OIIO::attribute("exr_threads", std::max(threads, 0));
}

int thread_count()
{
    std::lock_guard lock(g_control_mutex);
    if (g_threads > 0) {
        return g_threads;
    }
    return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

}  // namespace posthaste
