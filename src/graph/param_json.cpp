#include "graph/param_json.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/error.h"
#include "graph/graph.h"

namespace posthaste {

using json = nlohmann::json;

std::string json_kind(const json &v)
{
    switch (v.type()) {
        case json::value_t::null:
            return "null";
        case json::value_t::boolean:
            return v.get<bool>() ? "true" : "false";
        case json::value_t::string: {
            // Built by appending: GCC 12 warns (-Wrestrict, a false positive) on "\"" + s.
            std::string quoted(1, '"');
            quoted += v.get<std::string>();
            quoted += '"';
            return quoted;
        }
        case json::value_t::number_integer:
        case json::value_t::number_unsigned:
        case json::value_t::number_float:
            return v.dump();
        case json::value_t::array: {
            // A short array as written ("[1e38, 1, 1]"): the values are what was wrong.
            const std::string text = v.dump();
            return text.size() <= 60 ? text : str_cat("an array of ", v.size(), " values");
        }
        case json::value_t::object:
            return "an object";
        default:
            return "?";
    }
}

namespace {

/// Finite as the float a node computes with: JSON allows 1e300, which a float turns into inf.
bool float_finite(double x)
{
    return std::isfinite(x) && std::abs(x) <= double(std::numeric_limits<float>::max());
}

ParamValue convert_value(const ParamSpec &spec,
                         const json &v,
                         const std::string &path,
                         const std::string &who,
                         const std::string &label);

/// A Records value: an array of objects, each field converted by its declaration, defaults
/// filled, mandatory fields and the fields' only_when conditions checked.
std::shared_ptr<const std::vector<NodeParams>> convert_records(const ParamSpec &spec,
                                                               const json &v,
                                                               const std::string &path,
                                                               const std::string &who,
                                                               const std::string &label)
{
    const std::span<const ParamSpec> fields(spec.fields, spec.field_count);
    const auto field = [&](std::string_view name) -> const ParamSpec * {
        for (const ParamSpec &f : fields) {
            if (f.name == name) {
                return &f;
            }
        }
        return nullptr;
    };
    if (!v.is_array()) {
        throw_usage(path,
                    ": ",
                    who,
                    ": param \"",
                    label,
                    "\": expected a list of records, got ",
                    json_kind(v));
    }
    auto records = std::make_shared<std::vector<NodeParams>>();
    for (std::size_t i = 0; i < v.size(); ++i) {
        const json &e = v[i];
        const std::string at = path + "/" + std::to_string(i);
        std::string name = label;
        name += '[';
        name += std::to_string(i);
        name += ']';
        if (!e.is_object()) {
            throw_usage(at,
                        ": ",
                        who,
                        ": param \"",
                        name,
                        "\": expected a record (an object), got ",
                        json_kind(e));
        }
        std::map<std::string, ParamValue> values;
        for (const ParamSpec &f : fields) {
            values[std::string(f.name)] = default_param(f);
        }
        for (auto it = e.begin(); it != e.end(); ++it) {
            const ParamSpec *f = field(it.key());
            if (!f) {
                std::vector<std::string> names;
                for (const ParamSpec &k : fields) {
                    names.emplace_back(k.name);
                }
                throw_usage(at,
                            "/",
                            it.key(),
                            ": ",
                            who,
                            ": param \"",
                            name,
                            "\": unknown field \"",
                            it.key(),
                            "\"",
                            did_you_mean(it.key(), names));
            }
            values[it.key()] =
                convert_value(*f, it.value(), at + "/" + it.key(), who, name + "." + it.key());
        }
        for (const ParamSpec &f : fields) {
            const ParamValue &value = values.at(std::string(f.name));
            const ParamSpec *control = f.when_param.empty() ? nullptr : field(f.when_param);
            const bool applies =
                !control || condition_holds(f, *control, values.at(std::string(control->name)));
            if (applies && f.required && !value.given) {
                std::string needs = "needs \"";
                needs += f.name;
                needs += '"';
                if (control) {
                    needs += " when " + describe_condition(f);
                }
                throw_usage(at, ": ", who, ": param \"", name, "\": ", needs);
            }
            if (!applies && value.given) {
                throw_usage(at,
                            "/",
                            f.name,
                            ": ",
                            who,
                            ": param \"",
                            name,
                            ".",
                            f.name,
                            "\" applies only when ",
                            describe_condition(f),
                            ", not ",
                            condition_word(*control, values.at(std::string(control->name))));
            }
        }
        records->emplace_back(nullptr, std::move(values));
    }
    return records;
}

ParamValue convert_value(const ParamSpec &spec,
                         const json &v,
                         const std::string &path,
                         const std::string &who,
                         const std::string &label)
{
    std::string where = path;
    where += ": ";
    where += who;
    where += ": param \"";
    where += label;
    where += '"';
    ParamValue out;
    out.given = true;
    auto fail = [&](const std::string &expected) {
        throw_usage(where, ": expected ", expected, ", got ", json_kind(v));
    };
    auto check_range = [&](double x) {
        if (x < spec.min || x > spec.max) {
            // "integer in 1..256", "number >= 0" (it said "in >= 0").
            const std::string range = describe_range(spec);
            std::string text = describe_type(spec);
            text += range.find("..") != std::string::npos ? " in " : " ";
            text += range.empty() ? "range" : range;
            fail(text);
        }
    };
    // "integer in [0, 10]" (appended, not "..." + string: GCC 12's -Wrestrict false positive).
    const auto with_range = [&](const char *kind) {
        std::string text = kind;
        const std::string range = describe_range(spec);
        if (!range.empty()) {
            text += ' ';
            text += range;
        }
        return text;
    };
    switch (spec.type) {
        case ParamType::Int: {
            if (!v.is_number()) {
                fail(with_range("integer"));
            }
            const double x = v.get<double>();
            if (x != std::floor(x)) {
                fail("integer");
            }
            check_range(x);  // before int's own bounds: "integer in 0..2147483647, got 2147483648"
            if (std::abs(x) > 2147483647.0) {
                fail(with_range("integer"));
            }
            out.number = x;
            break;
        }
        case ParamType::Real: {
            if (!v.is_number()) {
                fail(with_range("number"));
            }
            const double x = v.get<double>();
            if (!float_finite(x)) {
                fail("finite number within a float's range");
            }
            check_range(x);
            out.number = x;
            break;
        }
        case ParamType::Bool:
            if (!v.is_boolean()) {
                fail("true or false");
            }
            out.number = v.get<bool>() ? 1.0 : 0.0;
            break;
        case ParamType::String:
            if (!v.is_string()) {
                fail("string");
            }
            out.text = v.get<std::string>();
            if (out.text.find('\0') != std::string::npos) {
                // A path with one would name another file ("a\0.exr" is "a" to the system).
                throw_usage(where, ": a null character in a string (\\u0000)");
            }
            break;
        case ParamType::Choice: {
            const std::vector<std::string> words = split_choices(spec.choices);
            if (!v.is_string()) {
                fail("one of " + std::string(spec.choices));
            }
            out.text = v.get<std::string>();
            if (std::find(words.begin(), words.end(), out.text) == words.end()) {
                throw_usage(where,
                            ": expected one of ",
                            spec.choices,
                            ", got \"",
                            out.text,
                            "\"",
                            did_you_mean(out.text, words));
            }
            break;
        }
        case ParamType::Vec: {
            const std::string expected = "array of " + std::to_string(spec.vec_size) + " numbers";
            if (v.is_number() && spec.vec_size > 0) {
                // A single number broadcasts: "color": 0.5 is [0.5, 0.5, 0.5].
                const double x = v.get<double>();
                if (!float_finite(x)) {
                    fail(expected);
                }
                check_range(x);
                out.vec.assign(std::size_t(spec.vec_size), x);
                break;
            }
            if (!v.is_array() || int(v.size()) != spec.vec_size) {
                fail(expected);
            }
            for (const json &e : v) {
                if (!e.is_number() || !std::isfinite(e.get<double>())) {
                    fail(expected);
                }
                if (!float_finite(e.get<double>())) {
                    fail(expected + " within a float's range");
                }
                check_range(e.get<double>());
                out.vec.push_back(e.get<double>());
            }
            break;
        }
        case ParamType::Json:
            out.text = v.dump();
            break;
        case ParamType::Records:
            out.records = convert_records(spec, v, path, who, label);
            out.text = v.dump();
            break;
    }
    return out;
}

}  // namespace

ParamValue convert_param(const ParamSpec &spec,
                         const json &v,
                         const std::string &path,
                         const std::string &who)
{
    return convert_value(spec, v, path, who, std::string(spec.name));
}

ParamValue default_param(const ParamSpec &spec)
{
    ParamValue out;
    out.number = spec.default_number;
    out.text = std::string(spec.default_text);
    for (int i = 0; i < spec.vec_size; ++i) {
        out.vec.push_back(spec.default_vec[std::size_t(i)]);
    }
    return out;
}

}  // namespace posthaste
