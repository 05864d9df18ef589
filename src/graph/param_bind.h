#pragma once
// Each parameter bound to the settings field it fills. A node declares its ParamSpecs once and
// binds each to a member of the settings struct its method takes:
//
//     constexpr Binding<DofSettings> kFields[] = {bind<&DofSettings::samples>(kSamples), ...};
//     DofSettings s = fill(ctx, kFields);
//
// fill() is the one place where a validated value becomes a field: numbers convert to the
// field's type, a Choice becomes the field's enum (the enum's order is the choices' order), an
// integer parsed from its word, or a bool that is true for one word; a parameter whose only_when
// does not hold leaves the field alone; a parameter declared from_header() and not given takes
// the frame's header value (an absent one leaves the default, with a note, or is an error for
// from_header_only(); an invalid one is an error). audit() tells where a settings struct's own
// default differs from its parameter's, and a unit test runs it over the whole node catalog, so
// tests and benchmarks that start from `Settings{}` run what a graph with defaults runs.

#include <cmath>
#include <glm/vec3.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "core/error.h"
#include "core/frame.h"
#include "graph/node.h"

namespace posthaste {

/// Every parameter error has this shape: `<where>: param "<name>": <problem>` (a usage error:
/// the graph asked for something the node cannot do).
[[noreturn]] void throw_param(const std::string &where,
                              std::string_view param,
                              std::string_view problem);

/// `<where>: param "<name>": expected <allowed>, got <value>`.
template <typename V>
[[noreturn]] void throw_param_expected(const std::string &where,
                                       std::string_view param,
                                       std::string_view allowed,
                                       const V &got)
{
    throw_param(where, param, str_cat("expected ", allowed, ", got ", got));
}

/// The same, for a check() hook: located at the parameter in the graph file
/// (`g.json:/nodes/2/params/blades: node "d" (dof): param "blades": ...`).
[[noreturn]] void throw_param(const CheckContext &ctx,
                              const ParamSpec &spec,
                              std::string_view problem);
template <typename V>
[[noreturn]] void throw_param_expected(const CheckContext &ctx,
                                       const ParamSpec &spec,
                                       std::string_view allowed,
                                       const V &got)
{
    throw_param(ctx, spec, str_cat("expected ", allowed, ", got ", got));
}

/// A header value a parameter declared from_header() falls back on: the camera's scalar (for the
/// camera's own attributes: aperture, focus, focalLength, ...) or the frame's other attributes.
struct HeaderSource {
    const Camera *camera = nullptr;
    const OIIO::ParamValueList *attributes = nullptr;

    static HeaderSource of(const Frame &f) { return {&f.camera, &f.attributes}; }
    /// A number (float, int or double attribute), or nothing.
    std::optional<double> number(std::string_view attribute) const;
    /// Three floats (an OIIO vector, point, normal or float[3]), or nothing.
    std::optional<glm::vec3> vec3(std::string_view attribute) const;
};

namespace bind_detail {

template <typename M>
struct member_of;
template <typename S, typename F>
struct member_of<F S::*> {
    using owner = S;
    using field = F;
};

/// The value of a header attribute as the field's type, or nothing (absent or of another kind).
template <typename F>
std::optional<F> header_value(const HeaderSource &h, std::string_view attribute)
{
    if constexpr (std::is_same_v<F, glm::vec3>) {
        return h.vec3(attribute);
    } else if constexpr (std::is_arithmetic_v<F> && !std::is_same_v<F, bool>) {
        if (const std::optional<double> v = h.number(attribute)) {
            return F(*v);
        }
        return std::nullopt;
    } else {
        return std::nullopt;
    }
}

/// Whether a header value lies within the spec's range (finite, every component).
template <typename F>
bool in_range(const ParamSpec &spec, const F &v)
{
    const auto ok = [&](double x) { return std::isfinite(x) && x >= spec.min && x <= spec.max; };
    if constexpr (std::is_same_v<F, glm::vec3>) {
        return ok(double(v.x)) && ok(double(v.y)) && ok(double(v.z));
    } else if constexpr (std::is_arithmetic_v<F>) {
        return ok(double(v));
    } else {
        return true;  // no header holds such a field (header_value gives nothing)
    }
}

/// A field's value as a message shows it.
template <typename F>
std::string show(const F &v)
{
    if constexpr (std::is_same_v<F, glm::vec3>) {
        return str_cat("[", v.x, ", ", v.y, ", ", v.z, "]");
    } else if constexpr (std::is_array_v<F>) {
        std::string s = "[";
        for (std::size_t i = 0; i < std::extent_v<F>; ++i) {
            s += (i ? ", " : "") + str_cat(v[i]);
        }
        return s + "]";
    } else if constexpr (std::is_same_v<F, std::string>) {
        return quoted(v);
    } else if constexpr (std::is_same_v<F, std::vector<std::string>>) {
        std::string s = "[";
        for (std::size_t i = 0; i < v.size(); ++i) {
            s += (i ? ", " : "") + quoted(v[i]);
        }
        return s + "]";
    } else if constexpr (std::is_enum_v<F>) {
        return str_cat("enum value ", int(v));
    } else if constexpr (std::is_same_v<F, bool>) {
        return v ? "true" : "false";
    } else {
        return str_cat(+v);
    }
}

/// Why a field of type F cannot hold `spec`'s values, or "" when it can (`word`: the Choice
/// word a bool field is true for).
template <typename F>
std::string misfit(const ParamSpec &spec, std::string_view word)
{
    const bool choice = spec.type == ParamType::Choice;
    if constexpr (std::is_same_v<F, bool>) {
        if (spec.type == ParamType::Bool && word.empty()) {
            return "";
        }
        if (choice && !word.empty()) {
            for (const std::string &w : split_choices(spec.choices)) {
                if (w == word) {
                    return "";
                }
            }
            return str_cat("\"", word, "\" is not one of ", spec.choices);
        }
        return "a bool field takes a boolean, or a choice with the word that makes it true";
    } else if constexpr (std::is_enum_v<F>) {
        return choice && word.empty() ? "" : "an enum field takes a choice";
    } else if constexpr (std::is_integral_v<F>) {
        if (spec.type == ParamType::Int || spec.type == ParamType::Bool) {
            return "";
        }
        if (choice) {
            for (const std::string &w : split_choices(spec.choices)) {
                if (w.empty() || w.find_first_not_of("0123456789") != std::string::npos) {
                    return "an integer field takes a choice only among whole numbers";
                }
            }
            return "";
        }
        return "an integer field takes an integer";
    } else if constexpr (std::is_floating_point_v<F>) {
        return spec.type == ParamType::Real || spec.type == ParamType::Int
                   ? ""
                   : "a number field takes a number";
    } else if constexpr (std::is_same_v<F, std::string>) {
        return spec.type == ParamType::String || choice || spec.type == ParamType::Json
                   ? ""
                   : "a string field takes a string or a choice";
    } else if constexpr (std::is_same_v<F, std::vector<std::string>>) {
        return spec.type == ParamType::String ? "" : "a list field takes a comma-separated string";
    } else if constexpr (std::is_same_v<F, glm::vec3>) {
        return spec.type == ParamType::Vec && spec.vec_size == 3 ? "" : "a vec3 field takes a vec3";
    } else if constexpr (std::is_array_v<F> && std::is_arithmetic_v<std::remove_extent_t<F>>) {
        return spec.type == ParamType::Vec && spec.vec_size == int(std::extent_v<F>)
                   ? ""
                   : str_cat("an array field of ", std::extent_v<F>, " takes a vec of as many");
    } else {
        static_assert(sizeof(F) == 0, "no conversion from a parameter to this field type");
    }
}

/// The parameter's validated value as the field's type.
template <typename F>
F convert(const ParamSpec &spec, std::string_view word, const NodeParams &p)
{
    if constexpr (std::is_same_v<F, bool>) {
        return word.empty() ? p.get_bool(spec) : p.get_string(spec) == word;
    } else if constexpr (std::is_enum_v<F>) {
        return F(p.get_choice(spec));
    } else if constexpr (std::is_integral_v<F>) {
        if (spec.type == ParamType::Choice) {
            return F(std::stoll(p.get_string(spec)));
        }
        return F(p.get_int(spec));
    } else if constexpr (std::is_same_v<F, float>) {
        return p.get_float(spec);
    } else if constexpr (std::is_floating_point_v<F>) {
        return F(p.get_real(spec));
    } else if constexpr (std::is_same_v<F, std::string>) {
        return p.get_string(spec);
    } else if constexpr (std::is_same_v<F, std::vector<std::string>>) {
        return split_list(p.get_string(spec));
    } else if constexpr (std::is_same_v<F, glm::vec3>) {
        const std::vector<double> &v = p.get_vec(spec);
        return glm::vec3(float(v[0]), float(v[1]), float(v[2]));
    } else {
        static_assert(sizeof(F) == 0, "no conversion from a parameter to this field type");
    }
}

}  // namespace bind_detail

/// One parameter bound to the member of S it fills (made by bind<&S::member>(spec)).
template <typename S>
struct Binding {
    const ParamSpec *spec = nullptr;
    std::string_view word;  ///< a bool field bound to a Choice is true for this word
    /// Set the field from the parameter's value.
    void (*assign)(S &, const Binding &, const NodeParams &) = nullptr;
    /// Set the field from the header; false (the field untouched) when the header has no valid
    /// value, and then `found` holds what it had instead ("" when absent).
    bool (*assign_header)(S &, const Binding &, const HeaderSource &, std::string &found) = nullptr;
    /// Whether two structs hold the same value in the field.
    bool (*same)(const S &, const S &) = nullptr;
    /// The field's value as text.
    std::string (*show)(const S &) = nullptr;
    /// Why the field's type cannot hold the spec's values ("" when it can).
    std::string (*misfit)(const Binding &) = nullptr;
    /// False for a field the struct leaves to its caller (a transport struct shared by nodes whose
    /// parameters default differently): audit() then does not compare defaults.
    bool own_default = true;

    /// The same binding, for a field without a default of its own (see own_default).
    constexpr Binding without_default() const
    {
        Binding b = *this;
        b.own_default = false;
        return b;
    }
};

/// Bind `spec` to `Member` (a pointer to a member of a settings struct). A bool member bound to
/// a Choice names the word that makes it true.
template <auto Member>
constexpr auto bind(const ParamSpec &spec, std::string_view word = {})
{
    using S = typename bind_detail::member_of<decltype(Member)>::owner;
    using F = typename bind_detail::member_of<decltype(Member)>::field;
    Binding<S> b;
    b.spec = &spec;
    b.word = word;
    if constexpr (std::is_array_v<F>) {
        // A fixed array of numbers (a Vec of as many): element by element, no header fallback.
        using E = std::remove_extent_t<F>;
        b.assign = [](S &s, const Binding<S> &self, const NodeParams &p) {
            const std::vector<double> &v = p.get_vec(*self.spec);
            for (std::size_t i = 0; i < std::extent_v<F> && i < v.size(); ++i) {
                (s.*Member)[i] = E(v[i]);
            }
        };
        b.assign_header = [](S &, const Binding<S> &, const HeaderSource &, std::string &found) {
            found.clear();
            return false;
        };
        b.same = [](const S &x, const S &y) {
            for (std::size_t i = 0; i < std::extent_v<F>; ++i) {
                if (!((x.*Member)[i] == (y.*Member)[i])) {
                    return false;
                }
            }
            return true;
        };
    } else {
        b.assign = [](S &s, const Binding<S> &self, const NodeParams &p) {
            s.*Member = bind_detail::convert<F>(*self.spec, self.word, p);
        };
        b.assign_header =
            [](S &s, const Binding<S> &self, const HeaderSource &h, std::string &found) {
                const std::optional<F> v = bind_detail::header_value<F>(h, self.spec->header);
                found.clear();
                if (!v) {
                    return false;
                }
                if (!bind_detail::in_range(*self.spec, *v)) {
                    found = bind_detail::show(*v);
                    return false;
                }
                s.*Member = *v;
                return true;
            };
        b.same = [](const S &x, const S &y) { return x.*Member == y.*Member; };
    }
    b.show = [](const S &s) { return bind_detail::show(s.*Member); };
    b.misfit = [](const Binding<S> &self) { return bind_detail::misfit<F>(*self.spec, self.word); };
    return b;
}

namespace bind_detail {
/// The header fallback of one from_header() binding that was not given; see fill().
void header_missing(NodeContext &ctx,
                    const ParamSpec &spec,
                    const std::string &found,
                    const std::string &shown_default);
}  // namespace bind_detail

/// Fill the bound fields of `s` from the node's parameters: every binding whose only_when holds.
template <typename S>
void fill_into(S &s, const NodeParams &p, std::span<const Binding<S>> bindings)
{
    for (const Binding<S> &b : bindings) {
        if (p.applies(*b.spec)) {
            b.assign(s, b, p);
        }
    }
}

/// Fill as above; a from_header() parameter that was not given then takes the header's value
/// from `header`. A header value outside the parameter's range (or not finite) is an error naming
/// the parameter, the attribute and the value; a header without one is an error for a
/// from_header_only() parameter, and otherwise leaves the default, with a note (once per node).
template <typename S>
void fill_into(S &s,
               NodeContext &ctx,
               std::span<const Binding<S>> bindings,
               const HeaderSource &header)
{
    const NodeParams &p = ctx.params();
    for (const Binding<S> &b : bindings) {
        if (!p.applies(*b.spec)) {
            continue;
        }
        b.assign(s, b, p);
        if (b.spec->header.empty() || p.given(*b.spec)) {
            continue;
        }
        std::string found;
        if (!b.assign_header(s, b, header, found)) {
            bind_detail::header_missing(ctx, *b.spec, found, b.show(s));
        }
    }
}

/// A settings struct from its defaults and the node's parameters.
template <typename S, std::size_t N>
S fill(const NodeParams &p, const Binding<S> (&bindings)[N])
{
    S s{};
    fill_into(s, p, std::span<const Binding<S>>(bindings));
    return s;
}

/// A settings struct from its defaults, the node's parameters and the frame's header.
template <typename S, std::size_t N>
S fill(NodeContext &ctx, const Binding<S> (&bindings)[N], const HeaderSource &header)
{
    S s{};
    fill_into(s, ctx, std::span<const Binding<S>>(bindings), header);
    return s;
}

namespace bind_detail {
template <typename F>
struct Holder {
    F value{};
};
}  // namespace bind_detail

/// One parameter's value by fill()'s rules, header fallback included (a parameter whose only_when
/// does not hold gives its default): for a value the node derives others from before any
/// settings field takes it.
template <typename F>
F param_value(NodeContext &ctx, const ParamSpec &spec, const HeaderSource &header)
{
    const Binding<bind_detail::Holder<F>> b = bind<&bind_detail::Holder<F>::value>(spec);
    bind_detail::Holder<F> h;
    b.assign(h, b, ctx.params());
    if (!spec.header.empty() && !ctx.params().given(spec) && ctx.params().applies(spec)) {
        std::string found;
        if (!b.assign_header(h, b, header, found)) {
            bind_detail::header_missing(ctx, spec, found, b.show(h));
        }
    }
    return h.value;
}

/// The parameters of `node` at their defaults (what a graph that gives none runs).
NodeParams default_params(const NodeType &node);

/// What is wrong with the bindings of `node`, one line each: a bound parameter the node does not
/// declare, a field type that cannot hold the parameter's values, or a field whose own default
/// (in `S{}`) differs from the parameter's default (but for from_header_only() parameters, whose
/// default never stands in).
/// The parameters of a record parameter (`records` spec) at their fields' defaults.
NodeParams default_record(const ParamSpec &records);

/// What is wrong with the bindings of `node`, one line each: a bound parameter the node does not
/// declare (as a parameter, or as a field of a records parameter), a field type that cannot hold
/// the parameter's values, or a field whose own default (in `S{}`) differs from the parameter's
/// default (but for from_header_only() parameters, whose default never stands in, and fields
/// bound without_default()).
template <typename S, std::size_t N>
void audit(const NodeType &node,
           const Binding<S> (&bindings)[N],
           std::vector<std::string> &problems)
{
    const NodeParams defaults = default_params(node);
    const S own{};
    for (const Binding<S> &b : bindings) {
        const std::string head = str_cat(node.spec.type, ": param \"", b.spec->name, "\": ");
        const NodeParams *from = nullptr;
        NodeParams record;
        for (const ParamSpec &d : node.spec.params) {
            if (d.name == b.spec->name) {
                from = &defaults;
            }
            for (std::size_t i = 0; !from && i < d.field_count; ++i) {
                if (d.fields[i].name == b.spec->name) {
                    record = default_record(d);
                    from = &record;
                }
            }
        }
        if (!from) {
            problems.push_back(head + "bound but not declared by the node");
            continue;
        }
        if (const std::string why = b.misfit(b); !why.empty()) {
            problems.push_back(head + why);
            continue;
        }
        if (b.spec->header_only || !b.own_default) {
            continue;
        }
        S from_spec{};
        b.assign(from_spec, b, *from);
        if (!b.same(own, from_spec)) {
            problems.push_back(head + "default " + b.show(from_spec) +
                               ", but its settings field starts at " + b.show(own));
        }
    }
}

}  // namespace posthaste
