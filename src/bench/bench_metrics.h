#pragma once
// The bench's measuring (bench.h): one untimed evaluation of a setting over every frame gives
// its errors against the truth and its thumbnails, and checks what the spec asks of the node's
// output (the pass, the depth that `exclude` needs, RGB for FLIP) before any timing.

#include <string>
#include <string_view>
#include <vector>

#include "bench/bench.h"
#include "core/frame.h"
#include "core/image.h"

namespace posthaste {
class Graph;
}

namespace posthaste::bench {

/// The part of `image` (a pass of `frame`) inside the frame's display window: what the metrics
/// measure.
ImagePtr display_part(const Frame &frame, const ImagePtr &image);

/// A frame's pass names, for messages.
std::string listed(const Frame &frame);

/// Errors of one frame against its truth (same size and channels). `depth`, when given, leaves
/// out the pixels whose depth is not finite (the sky) from all three metrics; FLIP, a filter over
/// the image, then sees the truth's values in the sky (no difference there) and is averaged over
/// the kept pixels. Throws a usage Error, prefixed with `where`, when no pixel is left.
struct FrameErrors {
    double rmse = 0.0, psnr = 0.0, flip = kNaN;
};
FrameErrors frame_errors(
    const Image &ref, const Image &test, const Image *depth, bool flip, const std::string &where);

/// One untimed evaluation of setting `setting` (graph `graph`, capturing spec.node) over
/// `frames`: its errors (averaged over frames) and thumbnails, timings left empty. The checks
/// are usage errors naming the spec's key, the setting and the frame.
SettingResult measure_setting(const BenchSpec &spec,
                              const BenchSetting &setting,
                              const Graph &graph,
                              const std::vector<int> &frames,
                              const std::vector<ImagePtr> &truth);

/// `text` with every byte that is not part of well-formed UTF-8 replaced by U+FFFD, for text
/// outputs declared UTF-8 (a spec path may hold any byte).
std::string valid_utf8(std::string_view text);

}  // namespace posthaste::bench
