#include "graph/node.h"

#include <algorithm>
#include <cstdio>

#include "core/error.h"

namespace posthaste {

std::string PassSet::to_string() const
{
    if (all) {
        return "*";
    }
    std::string s;
    for (const std::string &n : names) {
        s += (s.empty() ? "" : ",") + n;
    }
    for (const std::string &n : optional) {
        s += (s.empty() ? "" : ",") + n + "?";
    }
    return s;
}

std::vector<std::string> split_list(std::string_view list)
{
    std::vector<std::string> words;
    std::size_t start = 0;
    while (start <= list.size()) {
        std::size_t end = list.find(',', start);
        if (end == std::string_view::npos) {
            end = list.size();
        }
        std::string_view w = list.substr(start, end - start);
        while (!w.empty() && w.front() == ' ') {
            w.remove_prefix(1);
        }
        while (!w.empty() && w.back() == ' ') {
            w.remove_suffix(1);
        }
        if (!w.empty()) {
            words.emplace_back(w);
        }
        start = end + 1;
    }
    return words;
}

const ParamValue &NodeParams::value(const ParamSpec &spec) const
{
    auto it = values_.find(std::string(spec.name));
    if (it == values_.end()) {
        // A node reading a parameter it did not declare is a programming error.
        throw_runtime("internal: node type \"",
                      type_ ? type_->spec.type : "?",
                      "\" reads undeclared param \"",
                      spec.name,
                      "\"");
    }
    return it->second;
}

const std::vector<NodeParams> &NodeParams::get_records(const ParamSpec &spec) const
{
    static const std::vector<NodeParams> kNone;
    const ParamValue &v = value(spec);
    return v.records ? *v.records : kNone;
}

int NodeParams::get_choice(const ParamSpec &spec) const
{
    const std::vector<std::string> words = split_choices(spec.choices);
    const std::string &v = value(spec).text;
    auto it = std::find(words.begin(), words.end(), v);
    return it == words.end() ? 0 : int(it - words.begin());
}

bool NodeParams::applies(const ParamSpec &spec) const
{
    if (spec.when_param.empty() || !type_) {
        return true;
    }
    for (const ParamSpec &control : type_->spec.params) {
        if (control.name == spec.when_param) {
            return condition_holds(spec, control, value(control));
        }
    }
    // A condition on an undeclared parameter is a programming error.
    throw_runtime("internal: node type \"",
                  type_->spec.type,
                  "\": param \"",
                  spec.name,
                  "\" applies only when undeclared param \"",
                  spec.when_param,
                  "\" ...");
}

std::string NodeContext::where() const
{
    return node_.describe() + ", frame " + std::to_string(frame_number_);
}

int NodeContext::port_index(std::string_view port) const
{
    for (std::size_t i = 0; i < port_names_.size(); ++i) {
        if (port_names_[i] == port) {
            return int(i);
        }
    }
    return -1;
}

bool NodeContext::has_input(std::string_view port) const
{
    const int i = port_index(port);
    return i >= 0 && inputs_[std::size_t(i)] != nullptr;
}

const Frame &NodeContext::input(std::string_view port) const
{
    const int i = port_index(port);
    if (i < 0 || !inputs_[std::size_t(i)]) {
        throw_runtime(where(), ": input \"", port, "\" is not connected");
    }
    return *inputs_[std::size_t(i)];
}

const Image &NodeContext::input_pass(std::string_view port, const std::string &pass) const
{
    return input(port).image(pass, where() + ", input \"" + std::string(port) + "\"");
}

std::vector<int> NodeContext::earlier_frames(int count) const
{
    std::vector<int> out;
    if (!history_ || !history_->sequence || count <= 0) {
        return out;
    }
    for (int f : history_->sequence()) {
        if (f >= frame_number_ - count && f < frame_number_) {
            out.push_back(f);
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
}

std::shared_ptr<const Frame> NodeContext::input_at(std::string_view port, int frame) const
{
    const int p = port_index(port);
    if (p < 0) {
        throw_runtime(where(), ": no input port \"", port, "\"");
    }
    if (!history_ || !history_->input_at) {
        throw_runtime(where(), ": needs earlier frames, which only a graph run can give");
    }
    std::shared_ptr<const Frame> f = history_->input_at(std::size_t(p), frame);
    if (!f) {
        throw_runtime(where(), ": input \"", port, "\" is not connected");
    }
    return f;
}

void NodeState::note_once(const std::string &text)
{
    {
        std::lock_guard lock(notes_mutex_);
        if (!notes_.insert(text).second) {
            return;
        }
    }
    std::fprintf(stderr, "note: %s\n", text.c_str());
}

}  // namespace posthaste
