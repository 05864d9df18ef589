#pragma once
// ParamSpec: a node parameter declared once (name, type, default, range or choices, unit, help).
// Validation, defaults, `--set node.param=value` overrides and `posthaste nodes` all read it;
// no default exists anywhere else.

#include <array>
#include <cstddef>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

namespace posthaste {

enum class ParamType {
    Int,      ///< integer number
    Real,     ///< floating-point number
    Bool,     ///< true / false
    String,   ///< free text (paths, color-space names, ...)
    Choice,   ///< one of a fixed list of words
    Vec,      ///< fixed-size array of numbers (colors, directions)
    Json,     ///< structured value (mappings), checked by the node
    Records,  ///< a list of records, each field declared as a ParamSpec (lights)
};

class NodeParams;

struct ParamSpec {
    std::string_view name;
    ParamType type = ParamType::Real;
    double default_number = 0.0;
    std::string_view default_text;
    std::array<double, 4> default_vec{};
    int vec_size = 0;
    double min = -std::numeric_limits<double>::infinity();
    double max = std::numeric_limits<double>::infinity();
    std::string_view choices;  ///< "a|b|c" for Choice
    std::string_view unit;
    std::string_view help;
    bool required = false;  ///< no default: the graph must give it
    bool file = false;      ///< a file path or pattern: relative values in a graph file resolve
                            ///< against the graph's folder (its "base_dir")
    bool passes = false;    ///< names passes (comma-separated) the node reads from its first input
    /// Applies only while the node's parameter `when_param` (a Choice or a Bool of the same node)
    /// has one of `when_values` ("a|b"; "true" or "false" for a Bool). Giving it otherwise is an
    /// error: a value that would be ignored is a mistake in the graph (pbrt's unused-parameter
    /// rule).
    std::string_view when_param;
    std::string_view when_values;
    /// Unless given, the value comes from this header attribute ("aperture"); the node reads
    /// the header when `NodeParams::given()` is false. `header_only`: there is no fallback, a
    /// frame without the attribute is an error; otherwise the default stands in for it.
    std::string_view header;
    bool header_only = false;
    /// Records: the fields of each record, each declared like a parameter (type, default,
    /// range, choices, mandatory, only_when another field of the same record).
    const ParamSpec *fields = nullptr;
    std::size_t field_count = 0;

    static constexpr ParamSpec integer(std::string_view n, int def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Int;
        p.default_number = def;
        return p;
    }
    static constexpr ParamSpec real(std::string_view n, double def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Real;
        p.default_number = def;
        return p;
    }
    static constexpr ParamSpec boolean(std::string_view n, bool def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Bool;
        p.default_number = def ? 1.0 : 0.0;
        return p;
    }
    static constexpr ParamSpec string(std::string_view n, std::string_view def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::String;
        p.default_text = def;
        return p;
    }
    /// A choice among `options` ("over|add|multiply"); `def` must be one of them.
    static constexpr ParamSpec choice(std::string_view n,
                                      std::string_view options,
                                      std::string_view def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Choice;
        p.choices = options;
        p.default_text = def;
        return p;
    }
    static constexpr ParamSpec vec3(std::string_view n, double x, double y, double z)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Vec;
        p.vec_size = 3;
        p.default_vec = {x, y, z, 0.0};
        return p;
    }
    static constexpr ParamSpec vec4(std::string_view n, double x, double y, double z, double w)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Vec;
        p.vec_size = 4;
        p.default_vec = {x, y, z, w};
        return p;
    }
    /// Structured JSON; `def` is JSON text ("[]", "{}").
    static constexpr ParamSpec json(std::string_view n, std::string_view def)
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Json;
        p.default_text = def;
        return p;
    }

    /// A list of records (JSON objects) whose fields are `f`: validated, defaulted, shown by
    /// `posthaste nodes` and read by the node through NodeParams::get_records. The default is
    /// the empty list.
    template <std::size_t N>
    static constexpr ParamSpec records(std::string_view n, const ParamSpec (&f)[N])
    {
        ParamSpec p;
        p.name = n;
        p.type = ParamType::Records;
        p.default_text = "[]";
        p.fields = f;
        p.field_count = N;
        return p;
    }

    constexpr ParamSpec range(double lo, double hi) const
    {
        ParamSpec p = *this;
        p.min = lo;
        p.max = hi;
        return p;
    }
    constexpr ParamSpec at_least(double lo) const
    {
        ParamSpec p = *this;
        p.min = lo;
        return p;
    }
    constexpr ParamSpec units(std::string_view u) const
    {
        ParamSpec p = *this;
        p.unit = u;
        return p;
    }
    constexpr ParamSpec doc(std::string_view h) const
    {
        ParamSpec p = *this;
        p.help = h;
        return p;
    }
    /// A file path or pattern (String only).
    constexpr ParamSpec file_path() const
    {
        ParamSpec p = *this;
        p.file = true;
        return p;
    }
    /// Names the passes (comma-separated; String only) the node reads from its first input: the
    /// planner asks that input for them, so the node needs no plan hook of its own for it.
    constexpr ParamSpec reads_passes() const
    {
        ParamSpec p = *this;
        p.passes = true;
        return p;
    }
    /// Applies only while parameter `param` of the same node is one of `values` ("a|b"; "true" or
    /// "false" for a boolean): given with any other, the graph is refused.
    constexpr ParamSpec only_when(std::string_view param, std::string_view values) const
    {
        ParamSpec p = *this;
        p.when_param = param;
        p.when_values = values;
        return p;
    }
    /// Unless given, the frame header's attribute `attribute`, and the default where the header
    /// has none.
    constexpr ParamSpec from_header(std::string_view attribute) const
    {
        ParamSpec p = *this;
        p.header = attribute;
        return p;
    }
    /// Unless given, the frame header's attribute `attribute`; a frame without it is an error.
    constexpr ParamSpec from_header_only(std::string_view attribute) const
    {
        ParamSpec p = from_header(attribute);
        p.header_only = true;
        return p;
    }
    /// No default: the graph (or --set) must give a value.
    constexpr ParamSpec mandatory() const
    {
        ParamSpec p = *this;
        p.required = true;
        return p;
    }
};

/// A validated parameter value. Which member is meaningful follows the spec's type.
struct ParamValue {
    double number = 0.0;      ///< Int, Real, Bool (0/1)
    std::string text;         ///< String, Choice; JSON text for Json
    std::vector<double> vec;  ///< Vec
    bool given = false;       ///< set by the graph or --set (not the default)
    /// Records: each record's fields, validated and defaulted (null for none).
    std::shared_ptr<const std::vector<NodeParams>> records;
};

/// The words of a Choice spec, in order.
std::vector<std::string> split_choices(std::string_view choices);
/// Human-readable type name ("integer", "number", "one of over|add", ...).
std::string describe_type(const ParamSpec &spec);
/// The default rendered as JSON text ("32", "0.5", "\"over\"", "[1, 1, 1]").
std::string describe_default(const ParamSpec &spec);
/// The range as text ("1..256", ">= 0", "" when unbounded).
std::string describe_range(const ParamSpec &spec);
/// When the parameter applies, as text ("model is linear or height"; "" when always).
std::string describe_condition(const ParamSpec &spec);
/// The value of a Choice or Bool parameter as only_when() names it ("linear", "true").
std::string condition_word(const ParamSpec &spec, const ParamValue &value);
/// Whether `spec`'s only_when holds when its controlling parameter `control` has `value`
/// (true for a spec without a condition).
bool condition_holds(const ParamSpec &spec, const ParamSpec &control, const ParamValue &value);

}  // namespace posthaste
