#include "graph/graph.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>
#include <unordered_set>

#include "core/error.h"
#include "core/frame_limits.h"
#include "core/json_error.h"
#include "core/passes.h"
#include "graph/mask.h"
#include "io/cryptomatte.h"
#include "io/sequence.h"

namespace posthaste {

using json = nlohmann::json;

int edit_distance(std::string_view a, std::string_view b)
{
    std::vector<int> prev(b.size() + 1), cur(b.size() + 1);
    for (std::size_t j = 0; j <= b.size(); ++j) {
        prev[j] = int(j);
    }
    for (std::size_t i = 1; i <= a.size(); ++i) {
        cur[0] = int(i);
        for (std::size_t j = 1; j <= b.size(); ++j) {
            const int sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
            cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
        }
        std::swap(prev, cur);
    }
    return prev[b.size()];
}

std::string did_you_mean(std::string_view word, const std::vector<std::string> &candidates)
{
    int best = 1 << 30;
    std::string best_word;
    for (const std::string &c : candidates) {
        const int d = edit_distance(word, c);
        if (d < best) {
            best = d;
            best_word = c;
        }
    }
    if (best_word.empty() || best > std::max<int>(2, int(word.size()) / 3)) {
        return "";
    }
    return " (did you mean \"" + best_word + "\"?)";
}

std::vector<int> parse_frame_list(const std::string &text, const std::string &what)
{
    std::vector<int> frames;
    auto bad = [&](const std::string &why) {
        throw_usage(what,
                    ": invalid frame list \"",
                    text,
                    "\": ",
                    why,
                    " (expected e.g. 1-48, 1-48x2, 1,5,10-20)");
    };
    auto parse_int = [&](const std::string &s) -> long long {
        if (s.empty()) {
            bad("missing number");
        }
        std::size_t pos = 0;
        long long v = 0;
        try {
            v = std::stoll(s, &pos);
        } catch (const std::exception &) {
            bad("\"" + s + "\" is not a number");
        }
        if (pos != s.size()) {
            bad("\"" + s + "\" is not a number");
        }
        if (v < -kMaxFrameNumber || v > kMaxFrameNumber) {
            bad("frame number " + s + " out of range");
        }
        return v;
    };
    for (const std::string &item : split_list(text)) {
        std::string range = item, step_text;
        if (auto x = item.find('x'); x != std::string::npos) {
            range = item.substr(0, x);
            step_text = item.substr(x + 1);
            if (step_text.empty()) {
                bad("missing step after \"x\"");
            }
        }
        // A '-' after the first character separates the range ends (allows "-5--1").
        const std::size_t dash = range.find('-', 1);
        const long long a = parse_int(dash == std::string::npos ? range : range.substr(0, dash));
        const long long b = dash == std::string::npos ? a : parse_int(range.substr(dash + 1));
        const long long step = step_text.empty() ? 1 : parse_int(step_text);
        if (step <= 0) {
            bad("step must be positive");
        }
        if (b < a) {
            bad("range end " + std::to_string(b) + " is before its start " + std::to_string(a));
        }
        if ((b - a) / step + frames.size() > 10 * std::size_t(kMaxFrameCount)) {
            bad(str_cat("more than ", 10 * kMaxFrameCount, " frames listed"));
        }
        for (long long f = a; f <= b; f += step) {
            frames.push_back(int(f));
        }
    }
    // A frame listed twice ("1-10,5") runs once, where it is first listed: run twice, two jobs
    // wrote its files at once.
    if (std::adjacent_find(frames.begin(), frames.end(), std::greater_equal<int>()) !=
        frames.end()) {
        std::unordered_set<int> seen;
        seen.reserve(frames.size());
        std::erase_if(frames, [&](int f) { return !seen.insert(f).second; });
    }
    if (frames.empty()) {
        bad("no frames");
    }
    if (frames.size() > std::size_t(kMaxFrameCount)) {
        bad(str_cat("more than ", kMaxFrameCount, " frames"));
    }
    return frames;
}

int Graph::find(const std::string &id) const
{
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        if (nodes_[i].identity.id == id) {
            return int(i);
        }
    }
    return -1;
}

void Graph::set_capture(const std::string &id)
{
    capture_ = find(id);
    if (capture_ < 0) {
        throw_usage(origin_, ": no node \"", id, "\"");
    }
    plan();
}

namespace {

// The specular pass is the view-dependent share *of the colour it came with*: a node that
// replaces color and passes specular on unchanged (a grade, fog, relight's added lights) would
// leave motion_blur splitting a colour by a share that no longer describes it, so the engine
// drops it there, unless the node declares keeps_specular (dof).
void drop_stale_specular(const NodeSpec &spec, const Frame *first_input, Frame &out)
{
    if (!first_input || spec.keeps_specular) {
        return;
    }
    const Frame &in = *first_input;
    if (!in.has(pass::kSpecular) || !out.has(pass::kSpecular) || !in.has(pass::kColor) ||
        !out.has(pass::kColor)) {
        return;
    }
    if (out.pass(pass::kColor).image != in.pass(pass::kColor).image &&
        out.pass(pass::kSpecular).image == in.pass(pass::kSpecular).image) {
        out.erase(pass::kSpecular);
    }
}

}  // namespace

void Graph::plan()
{
    const std::size_t count = nodes_.size();
    live_.assign(count, false);
    for (GraphNode &gn : nodes_) {
        gn.requested = PassSet{};
        gn.input_passes.assign(gn.inputs.size(), PassSet{});
    }
    // Reverse topological order: consumers are planned before their producers.
    for (auto it = order_.rbegin(); it != order_.rend(); ++it) {
        const int i = *it;
        GraphNode &gn = nodes_[std::size_t(i)];
        bool live = gn.type->spec.sink || i == capture_;
        for (int c : gn.consumers) {
            live = live || live_[std::size_t(c)];
        }
        live_[std::size_t(i)] = live;
        if (!live) {
            continue;
        }
        if (i == capture_) {
            gn.requested.all = true;
        }
        const NodeSpec &spec = gn.type->spec;
        std::vector<bool> connected;
        for (std::size_t p = 0; p < spec.inputs.size(); ++p) {
            connected.push_back(gn.inputs[p] >= 0);
            for (const std::string &pass : split_list(spec.inputs[p].passes)) {
                gn.input_passes[p].add(pass);
            }
        }
        if (!spec.inputs.empty()) {
            PassSet through = gn.requested;
            for (const std::string &made : split_list(spec.makes)) {
                through.remove(made);
            }
            if (!spec.keeps_specular) {
                // Its output would drop a specular pass as stale (drop_stale_specular) if it
                // changes color: asking for one optionally, and for the passes that go with it,
                // would be wasted work.
                for (const pass::CanonicalPass &p : pass::canonical_passes()) {
                    if (p.of_color_split) {
                        through.optional.erase(std::string(p.name));
                    }
                }
            }
            gn.input_passes[0].add(through);
            for (const ParamSpec &ps : spec.params) {
                if (ps.passes) {
                    for (const std::string &pass : split_list(gn.params.get_string(ps))) {
                        gn.input_passes[0].add(pass);
                    }
                }
            }
            for (std::size_t p = 0; spec.maskable && p < spec.inputs.size(); ++p) {
                if (spec.inputs[p].name == kMaskPort.name) {
                    const std::string mask_pass = fill(gn.params, kMaskFields).pass;
                    gn.input_passes[p].add(mask_pass);
                    // Another view's pass takes that view's mask where the mask's frame has one
                    // (apply_mask): ask for it, or a read never loads it and the pass took the
                    // chosen view's mask.
                    std::set<std::string> named(gn.input_passes[0].names);
                    named.insert(gn.input_passes[0].optional.begin(),
                                 gn.input_passes[0].optional.end());
                    for (const ParamSpec &ps : spec.params) {  // also when every pass is asked
                        if (ps.passes) {
                            for (const std::string &n : split_list(gn.params.get_string(ps))) {
                                named.insert(n);
                            }
                        }
                    }
                    for (const std::string &n : named) {
                        if (const auto at = n.find('@'); at != std::string::npos) {
                            gn.input_passes[p].add_optional(mask_pass + n.substr(at));
                        }
                    }
                }
            }
        }
        if (gn.type->plan) {
            PlanContext ctx{gn.params, gn.identity, gn.requested, gn.input_passes, connected};
            gn.type->plan(ctx);
        }
        for (std::size_t p = 0; p < gn.inputs.size(); ++p) {
            if (gn.inputs[p] >= 0) {
                nodes_[std::size_t(gn.inputs[p])].requested.add(gn.input_passes[p]);
            }
        }
    }
}

std::vector<std::string> Graph::outputs(int frame) const
{
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const GraphNode &gn = nodes_[i];
        if (!live_[i] || gn.identity.type != "write") {
            continue;
        }
        if (auto it = gn.params.values().find("path"); it != gn.params.values().end()) {
            paths.push_back(expand_frame_pattern(it->second.text, frame));
        }
    }
    return paths;
}

bool Graph::looks_back() const
{
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const GraphNode &gn = nodes_[i];
        if (live_[i] && gn.type->looks_back && gn.type->looks_back(gn.params)) {
            return true;
        }
    }
    return false;
}

std::vector<int> Graph::default_frames() const
{
    if (!frames_.empty()) {
        return parse_frame_list(frames_, origin_ + ":/frames");
    }
    for (int i : order_) {
        const GraphNode &gn = nodes_[std::size_t(i)];
        if (live_[std::size_t(i)] && gn.type->discover_frames) {
            std::vector<int> found = gn.type->discover_frames(gn.params);
            if (!found.empty()) {
                return found;
            }
        }
    }
    return {1};
}

void Graph::check(const std::vector<int> &frames, bool every_frame) const
{
    if (!frames.empty()) {
        const auto [lo, hi] = std::minmax_element(frames.begin(), frames.end());
        const int widest = std::abs(std::int64_t(*lo)) > std::abs(std::int64_t(*hi)) ? *lo : *hi;
        if (widest != 1) {
            check_sink_paths(widest);
        }
    }
    for (int i : order_) {
        if (live_[std::size_t(i)]) {
            check_node(i, frames, every_frame);
        }
    }
}

void Graph::check_node(int index, const std::vector<int> &frames, bool every_frame) const
{
    const GraphNode &gn = nodes_.at(std::size_t(index));
    if (!gn.type->check) {
        return;
    }
    std::vector<bool> connected;
    for (int src : gn.inputs) {
        connected.push_back(src >= 0);
    }
    CheckContext ctx{gn.params, gn.identity, gn.requested, frames, connected, every_frame};
    gn.type->check(ctx);
}

NodeTimes Graph::make_times() const
{
    NodeTimes t;
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        t.nanoseconds.push_back(std::make_unique<std::atomic<long long>>(0));
    }
    return t;
}

const std::vector<int> &Graph::sequence_frames() const
{
    std::call_once(sequence_->once, [&] { sequence_->frames = default_frames(); });
    return sequence_->frames;
}

void Graph::execute_step(const GraphNode &gn, NodeContext &ctx, const Frame *first_input)
{
    try {
        gn.type->execute(ctx);
        if (gn.type->spec.maskable && first_input && ctx.has_input(kMaskPort.name)) {
            apply_mask(
                ctx.where(), gn.params, *first_input, ctx.input(kMaskPort.name), ctx.output());
        }
    } catch (const Error &e) {
        if (const auto *m = dynamic_cast<const MemoryBudgetError *>(&e); m && !m->output()) {
            throw MemoryBudgetError(e.code(), e.what(), gn.type->spec.sink);
        }
        if (gn.type->spec.sink) {
            throw OutputError(e.code(), e.what());
        }
        throw;
    } catch (const std::exception &e) {
        if (gn.type->spec.sink) {
            throw OutputError(ExitCode::Runtime, str_cat(ctx.where(), ": ", e.what()));
        }
        throw_runtime(ctx.where(), ": ", e.what());
    }
    drop_stale_specular(gn.type->spec, first_input, ctx.output());
}

Frame Graph::run_node(int index,
                      std::vector<std::shared_ptr<const Frame>> inputs,
                      std::vector<std::string> ports,
                      int frame) const
{
    const GraphNode &gn = nodes_.at(std::size_t(index));
    const std::shared_ptr<const Frame> first_input = inputs.empty() ? nullptr : inputs[0];
    NodeContext ctx(gn.identity,
                    gn.params,
                    std::move(inputs),
                    std::move(ports),
                    gn.requested,
                    frame,
                    *gn.state);
    execute_step(gn, ctx, first_input.get());
    return ctx.take_output();
}

Frame Graph::evaluate(int frame, NodeTimes *times) const
{
    Frame captured;
    run_nodes(frame, times, {}, &captured);
    return captured;
}

std::vector<std::shared_ptr<const Frame>> Graph::evaluate_outputs(
    int frame, const std::vector<int> &nodes) const
{
    return run_nodes(frame, nullptr, nodes, nullptr);
}

std::vector<std::shared_ptr<const Frame>> Graph::run_nodes(int frame,
                                                           NodeTimes *times,
                                                           const std::vector<int> &targets,
                                                           Frame *captured) const
{
    const std::size_t count = nodes_.size();
    // The nodes to run: the live ones, or the targets and their ancestors.
    std::vector<bool> run = live_;
    if (!targets.empty()) {
        run.assign(count, false);
        std::vector<int> stack = targets;
        while (!stack.empty()) {
            const int i = stack.back();
            stack.pop_back();
            if (run[std::size_t(i)]) {
                continue;
            }
            run[std::size_t(i)] = true;
            for (int src : nodes_[std::size_t(i)].inputs) {
                if (src >= 0) {
                    stack.push_back(src);
                }
            }
        }
    }
    std::vector<std::shared_ptr<const Frame>> results(count);
    std::vector<int> remaining(count, 0);
    for (std::size_t i = 0; i < count; ++i) {
        for (int c : nodes_[i].consumers) {
            remaining[i] += run[std::size_t(c)] ? 1 : 0;
        }
    }
    for (int target : targets) {
        ++remaining[std::size_t(target)];  // kept for the caller
    }
    for (int i : order_) {
        const GraphNode &gn = nodes_[std::size_t(i)];
        if (!run[std::size_t(i)]) {
            continue;
        }
        std::vector<std::shared_ptr<const Frame>> inputs;
        std::vector<std::string> ports;
        for (std::size_t p = 0; p < gn.inputs.size(); ++p) {
            inputs.push_back(gn.inputs[p] >= 0 ? results[std::size_t(gn.inputs[p])] : nullptr);
            ports.emplace_back(gn.type->spec.inputs[p].name);
        }
        const std::shared_ptr<const Frame> first_input = inputs.empty() ? nullptr : inputs[0];
        NodeContext ctx(gn.identity,
                        gn.params,
                        std::move(inputs),
                        std::move(ports),
                        gn.requested,
                        frame,
                        *gn.state);
        const FrameHistory history{
            [this]() -> const std::vector<int> & { return sequence_frames(); },
            [this, i](std::size_t port, int other) -> std::shared_ptr<const Frame> {
                const int src = nodes_[std::size_t(i)].inputs[port];
                if (src < 0) {
                    return nullptr;
                }
                // Isolated: while this thread waits inside the upstream nodes' parallel loops it
                // must not pick up another frame's task, which could wait on what this one is
                // computing (a node's cache of earlier frames).
                std::shared_ptr<const Frame> out;
                tbb::this_task_arena::isolate(
                    [&] { out = run_nodes(other, nullptr, {src}, nullptr).front(); });
                return out;
            }};
        ctx.set_history(&history);
        const auto t0 = std::chrono::steady_clock::now();
        if (targets.empty() || !gn.type->spec.sink) {
            execute_step(gn, ctx, first_input.get());
        } else {
            drop_stale_specular(gn.type->spec, first_input.get(), ctx.output());
        }
        const auto t1 = std::chrono::steady_clock::now();
        if (times) {
            *times->nanoseconds[std::size_t(i)] +=
                std::chrono::duration_cast<std::chrono::nanoseconds>(t1 - t0).count();
        }
        if (captured && i == capture_) {
            *captured = ctx.output();
        }
        if (remaining[std::size_t(i)] > 0) {
            // Keep only the passes some consumer asked for (a view's "pass@view" goes with its
            // pass): a G-buffer pass nobody downstream reads is freed now, not when the last
            // frame that carried it along is.
            Frame out = ctx.take_output();
            // A sink asked for its frame (evaluate_outputs) keeps what it was given.
            const bool sink_target = !targets.empty() && gn.type->spec.sink;
            if (!gn.requested.all && !sink_target) {
                // A cryptomatte request keeps the rank layers the frame's header declares.
                const std::set<std::string> ranks =
                    gn.requested.optional.empty()
                        ? std::set<std::string>()
                        : cryptomatte::requested_ranks(gn.requested.optional,
                                                       cryptomatte::declarations(out),
                                                       out.pass_names());
                for (const std::string &name : out.pass_names()) {
                    const std::string base = name.substr(0, name.find('@'));
                    if (!gn.requested.wants(name) && !gn.requested.wants(base) &&
                        ranks.count(name) == 0) {
                        out.erase(name);
                    }
                }
            }
            results[std::size_t(i)] = std::make_shared<const Frame>(std::move(out));
        }
        // Free each input after its last consumer.
        for (int src : gn.inputs) {
            if (src >= 0 && --remaining[std::size_t(src)] == 0) {
                results[std::size_t(src)].reset();
            }
        }
    }
    std::vector<std::shared_ptr<const Frame>> outputs;
    for (int target : targets) {
        outputs.push_back(results[std::size_t(target)]);
    }
    return outputs;
}

}  // namespace posthaste
