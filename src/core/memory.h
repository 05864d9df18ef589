#pragma once
// Large buffers (pass images, per-pixel scratch) are written once per frame, so their first-touch
// page faults are a real share of a pass: a 1080p RGBA float image is 8,100 pages of 4 KiB.
// advise_huge_pages asks Linux for transparent huge pages (2 MiB) on the buffer's interior, which
// cuts the faults 512-fold where the system allows it (THP "madvise" or "always"); elsewhere it
// does nothing. The contents are unaffected.

#include <cstddef>

namespace posthaste {

/// Buffers smaller than this are left alone (a huge page would mostly hold other data).
inline constexpr std::size_t kHugePageAdviceMinBytes = std::size_t(4) << 20;

/// Advise huge pages for the 2 MiB-aligned part of [data, data + bytes). Never fails.
void advise_huge_pages(void *data, std::size_t bytes);

}  // namespace posthaste
