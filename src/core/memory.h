#pragma once
// Large buffers (pass images, per-pixel scratch) are written once per frame, so their first-touch
// page faults are a real share of a pass: a 1080p RGBA float image is 8,100 pages of 4 KiB.
// advise_huge_pages asks Linux for transparent huge pages (2 MiB) on the buffer's interior, which
// cuts the faults 512-fold where the system allows it (THP "madvise" or "always"); elsewhere it
// does nothing. The contents are unaffected.

#include <cstddef>
#include <memory>
#include <string>

namespace posthaste {

/// Buffers smaller than this are left alone (a huge page would mostly hold other data).
inline constexpr std::size_t kHugePageAdviceMinBytes = std::size_t(4) << 20;

/// Advise huge pages for the 2 MiB-aligned part of [data, data + bytes). Never fails.
void advise_huge_pages(void *data, std::size_t bytes);

/// The memory budget for pass images, process-wide (every frame in flight together): 0 means
/// none. Set from --max-memory (default: a share of the machine's available memory).
void set_image_memory_budget(std::size_t bytes);
std::size_t image_memory_budget();
/// Bytes held by live pass images now.
std::size_t image_memory_in_use();
/// The most bytes pass images held at once since the last reset_image_memory_peak.
std::size_t image_memory_peak();
/// Start a new high-water mark from what is in use now.
void reset_image_memory_peak();
/// Count `bytes` against the budget; throws Error (exit 1) naming the image, what is in use and
/// the budget when it would be exceeded, instead of letting the kernel's OOM killer end the run.
void reserve_image_memory(std::size_t bytes, int width, int height, int channels);
/// Give back what reserve_image_memory counted.
void release_image_memory(std::size_t bytes);
/// "1 byte", "100 bytes", "64 KiB", "512 MiB", "39936 MiB": whole units, bytes below 1 KiB,
/// KiB below 1 MiB.
std::string format_bytes(std::size_t bytes);
/// MemAvailable from /proc/meminfo, in bytes (0 when unknown).
std::size_t available_memory_bytes();
/// Parse "8G", "512M", "1.5g", "0" (bytes, K, M, G, T; powers of 1024); throws a usage Error
/// naming `where`.
std::size_t parse_memory_size(const std::string &text, const std::string &where);

/// Scratch blocks kept between frames. A filter's per-pixel scratch is tens of megabytes written
/// once per frame, and fresh memory costs the kernel a page clear (and a fault) per page on first
/// touch (perf: about 5 % of the motion blur node, 3.6 % of dof). A freed block goes back to a
/// process-wide pool (at most 256 MiB kept, the oldest blocks freed first, mutex-guarded);
/// taking reuses the smallest kept block of at least `bytes`, its size in `*got`. Blocks are
/// 2 MiB-aligned whole multiples of 2 MiB with huge pages advised; their contents are stale, so
/// the caller must write before it reads. Throws std::bad_alloc.
void *scratch_take(std::size_t bytes, std::size_t *got = nullptr);
/// Returns a block from scratch_take (its size: `*got`) to the pool, or frees it.
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
    std::size_t got = bytes;
    T *p = static_cast<T *>(scratch_take(bytes, &got));
    return ScratchArray<T>(p, ScratchDeleter{got});
}

}  // namespace posthaste
