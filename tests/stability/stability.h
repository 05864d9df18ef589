#pragma once
// Stability harness: run one node type, as registered, on hostile frames (NaN and Inf in every
// pass, +inf sky depth, 1x1 and 1-row images, huge values, zero alpha, negative values) and
// check that its output stays finite and bounded; every run is recorded for
// stability.json (see record / write_records), which `posthaste bench`-style charts can read.
//
// The rule for "finite": an output value may be NaN or Inf only at a pixel where some input
// pass of the same size was already non-finite (propagation is allowed, spreading is not; a node
// that wants to clean such input does better). "Bounded": every finite output value has
// |v| <= bound (kDefaultBound unless a case says otherwise). A node may also refuse the input
// with a posthaste::Error (a clear message): that is recorded as "rejected" and passes.
//
// Adding a node's failure cases: add an entry to node_cases() in stability_cases.cpp (parameter
// sets to try, extra hostile frames for that node, known failures with a reason).

#include <functional>
#include <map>
#include <string>
#include <vector>

#include "core/frame.h"
#include "graph/node.h"

namespace posthaste::stability {

inline constexpr double kDefaultBound = 1e15;

struct HostileFrame {
    std::string name;
    std::string what;  ///< One line: what is hostile about it.
    Frame frame;
};

/// The standard hostile frames; every canonical pass is present in each.
std::vector<HostileFrame> hostile_frames();

/// A frame with every canonical pass, w x h, finite values typical of a render (color in
/// [0, 1] premultiplied, depth 1..50, unit normals, motion of a few pixels, ...).
Frame plain_frame(int w, int h, int number = 1);

/// Extra cases for one node type.
struct NodeCases {
    /// Parameter sets to run (name -> "param=value" list); the defaults always run as "defaults".
    std::vector<std::pair<std::string, std::vector<std::string>>> param_sets;
    /// Extra frames for this node only (e.g. disocclusion, fast rotation).
    std::function<std::vector<HostileFrame>()> extra_frames;
    /// "param set/frame" pairs known to fail, with the reason; recorded, not asserted.
    std::map<std::string, std::string> known_failures;
    double bound = kDefaultBound;
};

/// The cases of a node type (an empty NodeCases when the type has none of its own).
NodeCases node_cases(const std::string &type);
/// Node types the harness skips (sources and sinks need files), with the reason.
const std::map<std::string, std::string> &skipped_types();

struct StabilityResult {
    std::string node;
    std::string params;  ///< Param set name.
    std::string frame;   ///< Hostile frame name.
    std::string status;  ///< ok, rejected, unstable, crashed, known_failure.
    std::string message;
    long long nonfinite_in = 0;  ///< Input values that were NaN or Inf.
    long long nonfinite_out = 0;
    long long spread = 0;  ///< Non-finite output values at pixels whose inputs were finite.
    double max_abs = 0.0;  ///< Largest finite |output value|.
    double ms = 0.0;
};

/// Run `type` with its defaults overridden by `overrides` ("param=value") on `input` (given to
/// every input port), and classify the outcome.
StabilityResult run_case(const NodeType &type,
                         const std::vector<std::string> &overrides,
                         const Frame &input,
                         double bound);

/// Add a result to the process-wide record; the record is written to $POSTHASTE_STABILITY_JSON
/// (default "stability.json" in the working directory, build/ under ctest) when tests end.
void record(const StabilityResult &result);
/// Write the record now (also done at exit); returns the path, or "" when nothing was recorded.
std::string write_records();

}  // namespace posthaste::stability
