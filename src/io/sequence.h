#pragma once
// Frame-sequence file patterns: each '#' or '@' is one digit of the frame number, zero padded
// ("shot.####.exr" -> "shot.0012.exr"), and printf-style "%04d" / "%d" work too. A number wider
// than the pattern is written in full; negative frames get a leading '-'.

#include <string>
#include <vector>

namespace posthaste {

/// True if `pattern` contains a frame-number placeholder.
bool has_frame_placeholder(const std::string &pattern);
/// The file name of `frame` under `pattern` (the pattern itself if it has no placeholder).
std::string expand_frame_pattern(const std::string &pattern, int frame);
/// The frames whose files exist on disk for `pattern`, sorted (empty without a placeholder).
std::vector<int> find_frames_on_disk(const std::string &pattern);

}  // namespace posthaste
