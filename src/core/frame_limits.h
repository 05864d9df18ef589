#pragma once
// The frame numbers and counts a run takes, one bound for every place frames are listed: the
// command line's --frames, a graph's "frames" and a scene's frame_range.

namespace posthaste {

/// A frame number lies in -kMaxFrameNumber..kMaxFrameNumber.
inline constexpr int kMaxFrameNumber = 100000000;
/// A run or a scene holds at most this many frames.
inline constexpr int kMaxFrameCount = 1000000;

}  // namespace posthaste
