#pragma once
// The PNG encoder of the previews: 8-bit RGB or RGBA rows, filtered and deflated in parallel.
//
// A PNG's pixels are one zlib stream, which one thread compresses from start to end (libpng, and
// OpenImageIO through it). Here the filtered rows are cut into pieces of a fixed size, each piece
// is deflated on its own (primed with the 32 KiB of filtered bytes before it, ended on a byte
// boundary by a sync flush) and the pieces are joined into one stream, as pigz does for gzip.
// The pieces depend only on the image's size, never on the thread count: the file is the same
// bytes whatever the threads.

#include <cstdint>
#include <string>
#include <vector>

namespace posthaste {

/// The PNG row filters, in the order of the write node's png_filter choice (the first five are
/// also their filter-type bytes); `adaptive` picks, per row, the filter whose output has the
/// smallest sum of absolute values (taking bytes as signed), the heuristic the PNG
/// specification suggests and libpng's default.
enum class PngFilter { none, sub, up, average, paeth, adaptive };

/// Filtered bytes one piece holds (rounded up to whole rows).
inline constexpr std::size_t kPngPieceBytes = std::size_t(1) << 18;

/// The PNG file of `width` x `height` interleaved 8-bit pixels of `channels` (3: RGB, 4: RGBA)
/// at zlib `level` (0-9), tagged sRGB. `what` names the image in errors.
std::vector<std::uint8_t> encode_png(const std::uint8_t *pixels,
                                     int width,
                                     int height,
                                     int channels,
                                     int level,
                                     PngFilter filter,
                                     const std::string &what);

}  // namespace posthaste
