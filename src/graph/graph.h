#pragma once
// Graph: a JSON graph file parsed, validated against the node declarations, planned (which
// passes each node asks of its inputs) and evaluated frame by frame.
//
// File format (docs/GRAPHS.md):
//   { "frames": "1-48",                       optional default frame list
//     "aliases": [ {...}, ... ],              optional channel aliases for every read node
//     "nodes": [ {"id": "src", "type": "read", "params": {"path": "in.####.exr"}},
//                {"id": "out", "type": "write", "inputs": {"image": "src"}, "params": {...}} ] }

#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "graph/node.h"
#include "graph/node_catalog.h"

namespace posthaste {

struct GraphNode {
    NodeIdentity identity;
    const NodeType *type = nullptr;
    NodeParams params;
    std::vector<int> inputs;            ///< Producer node index per input port; -1 unconnected.
    std::vector<PassSet> input_passes;  ///< Passes asked of each input port (after planning).
    PassSet requested;                  ///< Passes consumers read from this node.
    std::vector<int> consumers;         ///< Nodes that read this one (one entry per edge).
    std::unique_ptr<NodeState> state = std::make_unique<NodeState>();
};

/// Time spent per node, summed over frames (thread-safe).
struct NodeTimes {
    std::vector<std::unique_ptr<std::atomic<long long>>> nanoseconds;
};

class Graph {
   public:
    /// Read, parse and validate a graph file; `overrides` are "node.param=value" strings.
    /// Relative file parameters in the file resolve against the graph's folder (or its
    /// "base_dir"); --set values stay relative to the current folder.
    /// Node types are looked up in `types` (nodes::catalog() for this build's).
    /// Throws Error (exit code 2) naming the file, JSON path, node and parameter.
    static Graph load(const std::string &path,
                      const NodeCatalog &types,
                      const std::vector<std::string> &overrides = {});
    /// As load, from JSON text; `origin` names it in messages. Relative file parameters resolve
    /// against `base_dir` ("" leaves them relative to the current folder).
    static Graph parse(const std::string &text,
                       const std::string &origin,
                       const NodeCatalog &types,
                       const std::vector<std::string> &overrides = {},
                       const std::string &base_dir = "");

    Graph(Graph &&) noexcept = default;
    Graph &operator=(Graph &&) noexcept = default;

    const std::vector<GraphNode> &nodes() const { return nodes_; }
    const std::string &origin() const { return origin_; }
    /// The folder relative file parameters of the graph file resolved against ("" for none).
    const std::string &base_dir() const { return base_dir_; }
    /// Node indices in evaluation (topological) order.
    const std::vector<int> &order() const { return order_; }

    /// The frames to run when the command line gives none: the graph's "frames", else the
    /// frames a source finds on disk, else {1}.
    std::vector<int> default_frames() const;
    /// default_frames(), computed once: the sequence nodes that look at earlier frames see.
    const std::vector<int> &sequence_frames() const;
    /// The files the graph's live `write` nodes make for `frame` (their paths expanded).
    std::vector<std::string> outputs(int frame) const;
    /// Whether a live node evaluates earlier frames of the sequence (NodeType::looks_back).
    bool looks_back() const;
    /// Run every live node's check hook for these frames (files exist, passes exist, ...);
    /// `every_frame`: each frame's inputs must exist now (--dry-run), not when it is run.
    void check(const std::vector<int> &frames, bool every_frame = false) const;
    /// Run node `index`'s check hook alone (for a node run on frames held in memory).
    void check_node(int index, const std::vector<int> &frames, bool every_frame = false) const;
    /// Evaluate one frame through the whole graph. Sinks write their files. Thread-safe for
    /// different frames. Adds each node's time to `times` when given. Returns the output frame
    /// of the capture node (see set_capture), or an empty Frame.
    Frame evaluate(int frame, NodeTimes *times = nullptr) const;
    /// Node `index`'s own step, as evaluate() takes it (execute; an exception that is not an
    /// Error named by the node; a stale specular pass dropped), on frames held in memory: one
    /// frame per input port named in `ports`. No history: a node that looks at earlier frames
    /// sees none. For callers that hold frames themselves (the tests).
    Frame run_node(int index,
                   std::vector<std::shared_ptr<const Frame>> inputs,
                   std::vector<std::string> ports,
                   int frame) const;
    /// Evaluate one frame up to the given nodes and return each one's output, computing what
    /// they share once. A sink among them passes its input on without writing (the frame it
    /// would write). Thread-safe for different frames.
    std::vector<std::shared_ptr<const Frame>> evaluate_outputs(int frame,
                                                               const std::vector<int> &nodes) const;
    /// Keep the output of node `id` (all its passes) for evaluate() to return; re-plans.
    void set_capture(const std::string &id);
    /// Index of node `id`, or -1.
    int find(const std::string &id) const;
    /// A NodeTimes with one slot per node.
    NodeTimes make_times() const;

   private:
    friend struct GraphBuilder;  // the steps of parse (graph_parse.cpp)
    /// Execute node `gn` in `ctx` (see run_node).
    static void execute_step(const GraphNode &gn, NodeContext &ctx, const Frame *first_input);
    Graph() = default;
    void plan();
    /// Refuse two sinks that write one file for `frame`, however spelled (graph_parse.cpp).
    void check_sink_paths(int frame) const;
    /// Evaluate frame `frame`: every live node (no targets), or only the targets and what they
    /// read, sinks passing their input on (a history request, evaluate_outputs). Returns the
    /// targets' outputs.
    std::vector<std::shared_ptr<const Frame>> run_nodes(int frame,
                                                        NodeTimes *times,
                                                        const std::vector<int> &targets,
                                                        Frame *captured) const;

    struct SequenceCache {
        std::once_flag once;
        std::vector<int> frames;
    };

    std::string origin_;
    std::string base_dir_;
    std::vector<GraphNode> nodes_;
    std::vector<int> order_;
    std::vector<bool> live_;  ///< Nodes that feed a sink or the capture node.
    int capture_ = -1;
    std::string frames_;
    std::shared_ptr<SequenceCache> sequence_ = std::make_shared<SequenceCache>();
};

/// Parse a frame list ("1-48", "1-48x2", "1,5,10-20"); throws a usage Error naming `what`.
std::vector<int> parse_frame_list(const std::string &text, const std::string &what = "--frames");

/// Levenshtein distance, for "did you mean" hints.
int edit_distance(std::string_view a, std::string_view b);
/// ", did you mean \"x\"?" for the closest candidate within a small distance, or "".
std::string did_you_mean(std::string_view word, const std::vector<std::string> &candidates);

}  // namespace posthaste
