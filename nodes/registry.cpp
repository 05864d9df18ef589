// The explicit list of node types (not self-registering statics: static libraries may drop
// them, and their order would be undefined).

#include "graph/node_registry.h"
#include "nodes/node.h"

namespace posthaste {

std::span<const NodeType *const> all_node_types()
{
    static const NodeType *const kAllNodes[] = {
        &nodes::kRead,
        &nodes::kRender,
        &nodes::kHatching,
        &nodes::kWrite,
        &nodes::kOcio,
        &nodes::kGrade,
        &nodes::kMerge,
        &nodes::kChannels,
        &nodes::kFog,
        &nodes::kRelight,
        &nodes::kMotionBlur,
        &nodes::kDof,
        &nodes::kBloom,
        &nodes::kExposure,
        &nodes::kGrain,
        &nodes::kLens,
        &nodes::kTonemap,
        &nodes::kReformat,
        &nodes::kTransform,
        &nodes::kCrop,
        &nodes::kBlur,
        &nodes::kSharpen,
        &nodes::kAo,
    };
    return kAllNodes;
}

const NodeType *find_node_type(std::string_view type)
{
    for (const NodeType *t : all_node_types()) {
        if (t->spec.type == type) {
            return t;
        }
    }
    return nullptr;
}

}  // namespace posthaste
