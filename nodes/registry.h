#pragma once
// The node types this build knows: an explicit list in nodes/registry.cpp (not self-registering
// statics: static libraries may drop them, and their order would be undefined).

#include <span>
#include <string_view>

#include "graph/node_catalog.h"

namespace posthaste {

namespace nodes {
/// Every node type of this build, for Graph::load and Graph::parse.
const NodeCatalog &catalog();
}  // namespace nodes

/// nodes::catalog().all(): every node type, in a stable order.
std::span<const NodeType *const> all_node_types();
/// nodes::catalog().find(type): the node type named `type`, or nullptr.
const NodeType *find_node_type(std::string_view type);
/// The node type named `type`; a usage error "unknown node type ..." with a "did you mean"
/// hint otherwise (`posthaste nodes TYPE`, Python's posthaste.node).
const NodeType &require_node_type(std::string_view type);

}  // namespace posthaste
