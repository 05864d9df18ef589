#pragma once
// Lookup over the explicit node list in nodes/registry.cpp.

#include <span>
#include <string_view>

#include "graph/node.h"

namespace posthaste {

/// Every node type, in a stable order.
std::span<const NodeType *const> all_node_types();
/// The node type named `type`, or nullptr.
const NodeType *find_node_type(std::string_view type);

}  // namespace posthaste
