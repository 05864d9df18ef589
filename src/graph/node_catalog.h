#pragma once
// The node types a graph may name. The caller of Graph::load and Graph::parse hands one in (the
// CLI, bench and the tests pass nodes::catalog(), nodes/registry.h), so the graph floor needs
// nothing from the nodes floor above it.

#include <span>
#include <string_view>

#include "graph/node.h"

namespace posthaste {

class NodeCatalog {
   public:
    explicit NodeCatalog(std::span<const NodeType *const> types) : types_(types) {}

    /// Every node type, in the catalog's order.
    std::span<const NodeType *const> all() const { return types_; }
    /// The node type named `type`, or nullptr.
    const NodeType *find(std::string_view type) const
    {
        for (const NodeType *t : types_) {
            if (t->spec.type == type) {
                return t;
            }
        }
        return nullptr;
    }

   private:
    std::span<const NodeType *const> types_;
};

}  // namespace posthaste
