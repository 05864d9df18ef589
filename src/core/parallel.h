#pragma once
// The one parallel primitive. Nodes never create threads: they hand tiles to
// parallel_for_tiles, which runs on the oneTBB pool sized by set_thread_count (--threads).
// Each output pixel must have exactly one writer, so results do not depend on the thread count.

#include <functional>

#include "core/image.h"

namespace posthaste {

inline constexpr int kDefaultTileSize = 64;

/// Call fn once for each tile of `bounds` (tiles of tile_size x tile_size, the last ones
/// clipped), in parallel. fn must not throw; record failures and report them after the loop.
void parallel_for_tiles(const Rect &bounds,
                        const std::function<void(const Rect &)> &fn,
                        int tile_size = kDefaultTileSize);

/// Call fn(i) for i in [begin, end), in parallel.
void parallel_for(int begin, int end, const std::function<void(int)> &fn);

/// Limit the worker threads used by every parallel loop (0: all hardware threads). Call once,
/// before any parallel work; the limit lasts until the next call.
void set_thread_count(int threads);
/// The current limit on worker threads.
int thread_count();

}  // namespace posthaste
