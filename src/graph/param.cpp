#include "graph/param.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace posthaste {
namespace {

std::string format_number(double v)
{
    if (std::isinf(v)) {
        return v > 0 ? "inf" : "-inf";
    }
    std::ostringstream os;
    os << v;
    return os.str();
}

}  // namespace

std::vector<std::string> split_choices(std::string_view choices)
{
    std::vector<std::string> words;
    std::size_t start = 0;
    while (start <= choices.size()) {
        std::size_t end = choices.find('|', start);
        if (end == std::string_view::npos) {
            end = choices.size();
        }
        if (end > start) {
            words.emplace_back(choices.substr(start, end - start));
        }
        start = end + 1;
    }
    return words;
}

std::string describe_type(const ParamSpec &spec)
{
    switch (spec.type) {
        case ParamType::Int:
            return "integer";
        case ParamType::Real:
            return "number";
        case ParamType::Bool:
            return "boolean";
        case ParamType::String:
            return "string";
        case ParamType::Choice:
            return "one of " + std::string(spec.choices);
        case ParamType::Vec:
            return "array of " + std::to_string(spec.vec_size) + " numbers";
        case ParamType::Json:
            return "JSON";
        case ParamType::Records:
            return "list of records";
    }
    return "?";
}

namespace {

std::string describe_own_default(const ParamSpec &spec)
{
    switch (spec.type) {
        case ParamType::Int:
        case ParamType::Real:
            return format_number(spec.default_number);
        case ParamType::Bool:
            return spec.default_number != 0.0 ? "true" : "false";
        case ParamType::String:
        case ParamType::Choice:
            return std::string(1, '"').append(spec.default_text).append(1, '"');
        case ParamType::Vec: {
            std::string s = "[";
            for (int i = 0; i < spec.vec_size; ++i) {
                if (i > 0) {
                    s += ", ";
                }
                s += format_number(spec.default_vec[std::size_t(i)]);
            }
            return s + "]";
        }
        case ParamType::Json:
        case ParamType::Records:
            return std::string(spec.default_text);
    }
    return "";
}

}  // namespace

std::string describe_default(const ParamSpec &spec)
{
    if (spec.required) {
        return "(required)";
    }
    if (!spec.header.empty()) {
        std::string text = "the header's ";
        text += spec.header;
        if (spec.header_only) {
            return text + " (required there)";
        }
        return text + ", else " + describe_own_default(spec);
    }
    return describe_own_default(spec);
}

std::string describe_range(const ParamSpec &spec)
{
    // An integer's bounds exactly: 2147483647 read "2.14748e+09".
    const auto bound = [&](double v) {
        return spec.type == ParamType::Int ? std::to_string(static_cast<long long>(v))
                                           : format_number(v);
    };
    const bool lo = std::isfinite(spec.min), hi = std::isfinite(spec.max);
    if (lo && hi) {
        return bound(spec.min) + ".." + bound(spec.max);
    }
    if (lo) {
        return ">= " + bound(spec.min);
    }
    if (hi) {
        return "<= " + bound(spec.max);
    }
    return "";
}

std::string describe_condition(const ParamSpec &spec)
{
    if (spec.when_param.empty()) {
        return "";
    }
    std::string text(spec.when_param);
    text += " is ";
    const std::vector<std::string> words = split_choices(spec.when_values);
    for (std::size_t i = 0; i < words.size(); ++i) {
        if (i > 0) {
            text += i + 1 == words.size() ? " or " : ", ";
        }
        text += words[i];
    }
    return text;
}

std::string condition_word(const ParamSpec &spec, const ParamValue &value)
{
    if (spec.type == ParamType::Bool) {
        return value.number != 0.0 ? "true" : "false";
    }
    return value.text;
}

bool condition_holds(const ParamSpec &spec, const ParamSpec &control, const ParamValue &value)
{
    if (spec.when_param.empty()) {
        return true;
    }
    const std::vector<std::string> words = split_choices(spec.when_values);
    return std::find(words.begin(), words.end(), condition_word(control, value)) != words.end();
}

}  // namespace posthaste
