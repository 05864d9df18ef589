#pragma once
// The evaluation order of a parsed graph (Graph::parse's last step, graph_parse.cpp).

#include <vector>

#include "graph/graph.h"

namespace posthaste {

/// Fill each node's consumers, refuse a cycle (a usage error naming the node at
/// /inputs and spelling the cycle out), and return the order in which nodes run: of the nodes
/// whose inputs are ready, the one with the fewest nodes downstream first.
std::vector<int> evaluation_order(std::vector<GraphNode> &nodes);

}  // namespace posthaste
