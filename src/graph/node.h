#pragma once
// The node interface: a constexpr NodeSpec (type, summary, input ports, parameters, the passes it
// makes) and an execute function over a NodeContext. Edges carry whole frames: a port names the
// passes the node reads from that input, and the evaluator asks each source for exactly the
// passes that some node downstream reads (see docs/ARCHITECTURE.md).

#include <any>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/frame.h"
#include "graph/param.h"

namespace posthaste {

/// A set of pass names, or "every pass", plus passes wanted only if a source can give them
/// (`optional`: a read takes them when the file has them, render always makes them; a node that
/// asks for one this way must work without it).
struct PassSet {
    bool all = false;
    std::set<std::string> names;
    std::set<std::string> optional;  ///< Never holds a name of `names`.
    /// A consumer reads the camera: its matrices, or the lens values a solve gives (focal length,
    /// sensor). A read whose file has no matrices solves them from position + depth only then
    /// (or for `all`): a graph that never looks at the camera does not pay for the solve's
    /// passes (about 95 ms a frame at 1080p).
    bool camera = false;

    bool empty() const { return !all && names.empty(); }
    bool contains(const std::string &n) const { return all || names.count(n) != 0; }
    /// contains(n), or n asked for optionally.
    bool wants(const std::string &n) const { return contains(n) || optional.count(n) != 0; }
    void add(const std::string &n)
    {
        if (!all) {
            names.insert(n);
            optional.erase(n);
        }
    }
    void add_optional(const std::string &n)
    {
        if (!all && names.count(n) == 0) {
            optional.insert(n);
        }
    }
    void add(const PassSet &o)
    {
        camera = camera || o.camera;
        if (o.all) {
            all = true;
            names.clear();
            optional.clear();
        } else if (!all) {
            for (const std::string &n : o.names) {
                add(n);
            }
            for (const std::string &n : o.optional) {
                add_optional(n);
            }
        }
    }
    void remove(const std::string &n)
    {
        names.erase(n);
        optional.erase(n);
    }
    std::string to_string() const;
};

struct PortSpec {
    std::string_view name;
    std::string_view passes;  ///< Comma-separated passes this port always reads ("color,depth").
    bool optional = false;
    std::string_view help;
};

struct NodeSpec {
    std::string_view type;
    std::string_view summary;
    std::span<const PortSpec> inputs;
    std::span<const ParamSpec> params;
    std::string_view makes;  ///< Comma-separated passes it writes into its output frame.
    bool sink = false;       ///< Writes files: evaluated even though nothing reads it.
    /// Color and the specular pass stay consistent through it: it leaves color alone, maps both
    /// alike (crop, reformat, transform), or its new color keeps specular a fair share (dof: a
    /// sharp highlight's share of a defocused colour). Only such nodes pass an optional request
    /// for the specular shares upstream, and a node without it that replaces color and passes
    /// specular on unchanged has that pass dropped as stale.
    bool keeps_specular = false;
    /// Changes colour and takes graph/mask.h's mask: its inputs list kMaskPort and its params
    /// kMaskPass, kMaskChannel and kMaskInvert; the engine blends what it replaced by the mask.
    bool maskable = false;
};

class NodeContext;
class PlanContext;
class CheckContext;
class NodeParams;

struct NodeType {
    NodeSpec spec;
    void (*execute)(NodeContext &ctx) = nullptr;
    /// Optional: adjust the passes asked of each input (the default asks each port for its
    /// declared passes, and the first port also for what downstream reads that this node does
    /// not make).
    void (*plan)(PlanContext &ctx) = nullptr;
    /// Optional: checks that need more than the parameter declarations (files exist, passes
    /// exist in them, parameter combinations); runs before any pixel work.
    void (*check)(CheckContext &ctx) = nullptr;
    /// Optional, for sources: the frames available on disk (used when no frame list is given).
    std::vector<int> (*discover_frames)(const NodeParams &params) = nullptr;
    /// Optional, for nodes that bind parameters to settings fields (graph/param_bind.h): adds a
    /// line to `problems` for each binding that disagrees with its spec. The node catalog test
    /// runs it for every node.
    void (*audit)(std::vector<std::string> &problems) = nullptr;
    /// Optional: true when the node, with these parameters, evaluates earlier frames of the
    /// sequence (FrameHistory: auto exposure's adaptation), so a frame's cost depends on the
    /// frames evaluated before it in the same process (the farm keeps such chunks contiguous).
    bool (*looks_back)(const NodeParams &params) = nullptr;
};

/// Parameters of one node instance, validated and defaulted.
class NodeParams {
   public:
    NodeParams() = default;
    NodeParams(const NodeType *type, std::map<std::string, ParamValue> values)
        : type_(type), values_(std::move(values))
    {
    }
    int get_int(const ParamSpec &spec) const { return int(value(spec).number); }
    double get_real(const ParamSpec &spec) const { return value(spec).number; }
    float get_float(const ParamSpec &spec) const { return float(value(spec).number); }
    bool get_bool(const ParamSpec &spec) const { return value(spec).number != 0.0; }
    const std::string &get_string(const ParamSpec &spec) const { return value(spec).text; }
    /// Index of the chosen word among the spec's choices.
    int get_choice(const ParamSpec &spec) const;
    const std::vector<double> &get_vec(const ParamSpec &spec) const { return value(spec).vec; }
    /// JSON text of a Json parameter.
    const std::string &get_json(const ParamSpec &spec) const { return value(spec).text; }
    /// The records of a Records parameter, each read with the same getters and its fields'
    /// specs (validated and defaulted by the graph).
    const std::vector<NodeParams> &get_records(const ParamSpec &spec) const;
    /// True if the graph or --set gave this parameter (false: the default is in force).
    bool given(const ParamSpec &spec) const { return value(spec).given; }
    /// Whether the parameter's only_when holds (true without a condition, and for the fields of
    /// a record, whose conditions the graph checked when it read them).
    bool applies(const ParamSpec &spec) const;
    const std::map<std::string, ParamValue> &values() const { return values_; }

   private:
    const ParamValue &value(const ParamSpec &spec) const;
    const NodeType *type_ = nullptr;
    std::map<std::string, ParamValue> values_;
};

/// Identity of a node instance, for messages: `node "blur" (motion_blur)`.
struct NodeIdentity {
    std::string id;
    std::string type;
    std::string json_path;  ///< "graphs/a.json:/nodes/2"
    std::string describe() const { return "node \"" + id + "\" (" + type + ")"; }
};

/// Per-instance state that lives across frames (look-up tables, caches). Created once, on first
/// use, under a lock; afterwards shared read-only by every frame.
class NodeState {
   public:
    template <typename T, typename Make>
    const T &get_or_create(Make &&make)
    {
        std::lock_guard lock(mutex_);
        if (!value_.has_value()) {
            value_ = std::make_shared<const T>(make());
        }
        return *std::any_cast<std::shared_ptr<const T>>(value_);
    }

    /// Print "note: <text>" on stderr the first time this node instance says `text` (a constant
    /// a node stood in for a missing pass or header value, say): once a run, not once a frame.
    void note_once(const std::string &text);

   private:
    std::mutex mutex_;
    std::any value_;
    std::mutex notes_mutex_;
    std::set<std::string> notes_;
};

class PlanContext {
   public:
    const NodeParams &params;
    const NodeIdentity &node;
    const PassSet &downstream;     ///< What consumers read from this node's output.
    std::vector<PassSet> &inputs;  ///< What to ask of each input port (already defaulted).
    std::vector<bool> connected;   ///< Which input ports are connected.
};

class CheckContext {
   public:
    const NodeParams &params;
    const NodeIdentity &node;
    const PassSet &downstream;  ///< For sources: the passes to produce.
    std::vector<int> frames;    ///< The frames the run will evaluate.
    std::vector<bool> connected;
    /// A frame whose input is missing is an error now (--dry-run), not when the run reaches it.
    bool every_frame = false;
};

/// What the engine offers a node that looks at earlier frames (auto exposure's adaptation).
/// Set by Graph::evaluate; absent when a node is run on its own.
struct FrameHistory {
    /// The frames of the sequence: the graph's "frames", else what its sources find on disk.
    /// Independent of the frames a run (or a farm chunk) evaluates.
    std::function<const std::vector<int> &()> sequence;
    /// The frame on input port `port` at frame number `frame`, evaluated upstream (sinks
    /// upstream pass their input on without writing).
    std::function<std::shared_ptr<const Frame>(std::size_t port, int frame)> input_at;
};

class NodeContext {
   public:
    NodeContext(const NodeIdentity &node,
                const NodeParams &params,
                std::vector<std::shared_ptr<const Frame>> inputs,
                std::vector<std::string> port_names,
                const PassSet &requested,
                int frame_number,
                NodeState &state)
        : node_(node),
          params_(params),
          inputs_(std::move(inputs)),
          port_names_(std::move(port_names)),
          requested_(requested),
          frame_number_(frame_number),
          state_(state)
    {
        if (!inputs_.empty() && inputs_[0]) {
            output_ = *inputs_[0];  // shallow: passes are shared pointers
        }
        output_.number = frame_number;
    }

    int frame_number() const { return frame_number_; }
    const NodeIdentity &node() const { return node_; }
    /// "node "blur" (motion_blur), frame 12": prefix for error messages.
    std::string where() const;
    const NodeParams &params() const { return params_; }

    bool has_input(std::string_view port) const;
    /// The frame on input `port`; throws if the port is not connected.
    const Frame &input(std::string_view port) const;
    /// A pass of the frame on input `port`; throws naming the node, port and pass if absent.
    const Image &input_pass(std::string_view port, const std::string &pass) const;
    /// The passes consumers read from this node (sources produce exactly these).
    const PassSet &requested() const { return requested_; }

    /// The output frame: starts as a shallow copy of the first input (or empty for sources).
    Frame &output() { return output_; }
    Frame take_output() { return std::move(output_); }

    int get_int(const ParamSpec &s) const { return params_.get_int(s); }
    double get_real(const ParamSpec &s) const { return params_.get_real(s); }
    float get_float(const ParamSpec &s) const { return params_.get_float(s); }
    bool get_bool(const ParamSpec &s) const { return params_.get_bool(s); }
    const std::string &get_string(const ParamSpec &s) const { return params_.get_string(s); }
    int get_choice(const ParamSpec &s) const { return params_.get_choice(s); }
    const std::vector<double> &get_vec(const ParamSpec &s) const { return params_.get_vec(s); }

    NodeState &state() { return state_; }

    /// The engine's history hooks (Graph::evaluate sets them).
    void set_history(const FrameHistory *history) { history_ = history; }
    /// The frames of the sequence in [frame_number() - count, frame_number()), ascending;
    /// empty when the node runs outside a graph.
    std::vector<int> earlier_frames(int count) const;
    /// The frame on input `port` at another frame number; throws naming the node when the
    /// node runs outside a graph or the port is not connected.
    std::shared_ptr<const Frame> input_at(std::string_view port, int frame) const;

   private:
    int port_index(std::string_view port) const;

    const NodeIdentity &node_;
    const NodeParams &params_;
    std::vector<std::shared_ptr<const Frame>> inputs_;
    std::vector<std::string> port_names_;
    const PassSet &requested_;
    int frame_number_;
    NodeState &state_;
    Frame output_;
    const FrameHistory *history_ = nullptr;
};

/// Split "a,b,c" into words (empty words dropped, spaces trimmed).
std::vector<std::string> split_list(std::string_view list);

}  // namespace posthaste
