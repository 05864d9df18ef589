// graph/param_bind.cpp: the parts of parameter binding that need no settings type.

#include "graph/param_bind.h"

#include <map>

#include "graph/param_json.h"

namespace posthaste {

void throw_param(const std::string &where, std::string_view param, std::string_view problem)
{
    throw_usage(where, ": param \"", param, "\": ", problem);
}

void throw_param(const CheckContext &ctx, const ParamSpec &spec, std::string_view problem)
{
    throw_usage(ctx.node.json_path,
                "/params/",
                spec.name,
                ": ",
                ctx.node.describe(),
                ": param \"",
                spec.name,
                "\": ",
                problem);
}

std::optional<double> HeaderSource::number(std::string_view attribute) const
{
    if (camera) {
        for (const CameraScalarAttribute &a : kCameraScalarAttributes) {
            if (attribute == a.name) {
                const std::optional<float> &v = camera->*a.member;
                return v ? std::optional<double>(*v) : std::nullopt;
            }
        }
    }
    if (!attributes) {
        return std::nullopt;
    }
    const OIIO::ParamValue *p = attributes->find_pv(std::string(attribute));
    if (!p || p->type().aggregate != OIIO::TypeDesc::SCALAR || p->type().arraylen != 0) {
        return std::nullopt;
    }
    const OIIO::TypeDesc::BASETYPE t = OIIO::TypeDesc::BASETYPE(p->type().basetype);
    if (t != OIIO::TypeDesc::FLOAT && t != OIIO::TypeDesc::INT && t != OIIO::TypeDesc::DOUBLE &&
        t != OIIO::TypeDesc::HALF && t != OIIO::TypeDesc::UINT) {
        return std::nullopt;
    }
    return double(p->get_float());
}

std::optional<glm::vec3> HeaderSource::vec3(std::string_view attribute) const
{
    if (!attributes) {
        return std::nullopt;
    }
    const OIIO::ParamValue *p = attributes->find_pv(std::string(attribute));
    if (!p || p->type().basetype != OIIO::TypeDesc::FLOAT || p->type().basevalues() != 3) {
        return std::nullopt;
    }
    const float *h = static_cast<const float *>(p->data());
    return glm::vec3(h[0], h[1], h[2]);
}

NodeParams default_params(const NodeType &node)
{
    std::map<std::string, ParamValue> values;
    for (const ParamSpec &spec : node.spec.params) {
        values[std::string(spec.name)] = default_param(spec);
    }
    return NodeParams(&node, std::move(values));
}

NodeParams default_record(const ParamSpec &records)
{
    std::map<std::string, ParamValue> values;
    for (std::size_t i = 0; i < records.field_count; ++i) {
        values[std::string(records.fields[i].name)] = default_param(records.fields[i]);
    }
    return NodeParams(nullptr, std::move(values));
}

namespace bind_detail {

void header_missing(NodeContext &ctx,
                    const ParamSpec &spec,
                    const std::string &found,
                    const std::string &shown_default)
{
    const std::string header = quoted(std::string(spec.header));
    const std::string what =
        found.empty() ? str_cat("the frame's header has no ", header)
                      : str_cat("the frame's header ",
                                header,
                                " is ",
                                found,
                                describe_range(spec).empty() ? std::string(", not finite")
                                                             : ", outside " + describe_range(spec));
    if (spec.header_only || !found.empty()) {
        // The frame lacks what the node needs, or holds what it cannot take: an input error,
        // not the graph's.
        throw_runtime(ctx.where(),
                      ": param \"",
                      spec.name,
                      "\": not given, and ",
                      what,
                      found.empty() ? "" : str_cat(" (give ", spec.name, ")"));
    }
    ctx.state().note_once(str_cat(ctx.node().describe(),
                                  ": ",
                                  what,
                                  ": param \"",
                                  spec.name,
                                  "\" takes its default ",
                                  shown_default,
                                  " (give ",
                                  spec.name,
                                  " to choose)"));
}

}  // namespace bind_detail

}  // namespace posthaste
