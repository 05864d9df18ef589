#pragma once
// A parameter's JSON value converted and checked against its declaration (graph/param.h): the
// graph file's "params" and the command line's --set go through the same function.

#include <nlohmann/json.hpp>
#include <string>

#include "graph/param.h"

namespace posthaste {

/// How a JSON value reads in a message: null, true, "text", 3.5, an array, an object.
std::string json_kind(const nlohmann::json &v);

/// Convert and check one parameter value; `where` prefixes the one-line usage error.
ParamValue convert_param(const ParamSpec &spec, const nlohmann::json &v, const std::string &where);

/// The declared default of a parameter.
ParamValue default_param(const ParamSpec &spec);

}  // namespace posthaste
