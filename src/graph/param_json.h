#pragma once
// A parameter's JSON value converted and checked against its declaration (graph/param.h): the
// graph file's "params" and the command line's --set go through the same function.

#include <nlohmann/json.hpp>
#include <string>

#include "graph/param.h"

namespace posthaste {

/// How a JSON value reads in a message: null, true, "text", 3.5, an array, an object.
std::string json_kind(const nlohmann::json &v);

/// Convert and check one parameter value. `path` locates the value ("g.json:/nodes/2/params/x"
/// or the --set argument) and `who` names the node; both lead the one-line usage error. The
/// fields of a Records value are checked the same way, each located by its own path.
ParamValue convert_param(const ParamSpec &spec,
                         const nlohmann::json &v,
                         const std::string &path,
                         const std::string &who);

/// The declared default of a parameter.
ParamValue default_param(const ParamSpec &spec);

}  // namespace posthaste
