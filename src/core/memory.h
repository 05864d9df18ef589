#pragma once
// Large buffers (pass images, per-pixel scratch) are written once per frame, so their first-touch
// page faults are a real share of a pass: a 1080p RGBA float image is 8,100 pages of 4 KiB.
// advise_huge_pages asks Linux for transparent huge pages (2 MiB) on the buffer's interior, which
// cuts the faults 512-fold where the system allows it (THP "madvise" or "always"); elsewhere it
// does nothing. The contents are unaffected.

#include <cstddef>
#include <memory>

namespace posthaste {

/// Buffers smaller than this are left alone (a huge page would mostly hold other data).
inline constexpr std::size_t kHugePageAdviceMinBytes = std::size_t(4) << 20;

/// Advise huge pages for the 2 MiB-aligned part of [data, data + bytes). Never fails.
void advise_huge_pages(void *data, std::size_t bytes);

/// Scratch blocks kept between frames. A filter's per-pixel scratch is tens of megabytes written
/// once per frame, and fresh memory costs the kernel a page clear (and a fault) per page on first
/// touch (perf: about 5 % of the motion blur node, 3.6 % of dof). A freed block goes back to a
/// process-wide pool (at most 256 MiB kept, mutex-guarded); taking a block of the same size
/// reuses one. Blocks are 2 MiB-aligned whole multiples of 2 MiB with huge pages advised; their
/// contents are stale, so the caller must write before it reads. Throws std::bad_alloc.
void *scratch_take(std::size_t bytes);
/// Returns a block from scratch_take (same `bytes`) to the pool, or frees it.
void scratch_give(void *block, std::size_t bytes);

/// Deleter of scratch_array.
struct ScratchDeleter {
    std::size_t bytes = 0;
    void operator()(void *p) const { scratch_give(p, bytes); }
};
template <class T>
using ScratchArray = std::unique_ptr<T[], ScratchDeleter>;

/// Uninitialized storage for n trivial values from the scratch pool.
template <class T>
ScratchArray<T> scratch_array(std::size_t n)
{
    constexpr std::size_t kHuge = std::size_t(2) << 20;
    std::size_t bytes = (n * sizeof(T) + kHuge - 1) / kHuge * kHuge;
    bytes = bytes > 0 ? bytes : kHuge;
    return ScratchArray<T>(static_cast<T *>(scratch_take(bytes)), ScratchDeleter{bytes});
}

}  // namespace posthaste
