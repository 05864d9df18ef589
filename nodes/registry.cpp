// The explicit list of node types (nodes/registry.h says why).

#include "nodes/registry.h"

#include <string>
#include <vector>

#include "core/error.h"
#include "graph/graph.h"
#include "nodes/node.h"

namespace posthaste {

namespace {
const NodeType *const kAllNodes[] = {
    &nodes::kRead,       &nodes::kRender,  &nodes::kHatching, &nodes::kWrite,     &nodes::kOcio,
    &nodes::kGrade,      &nodes::kMerge,   &nodes::kChannels, &nodes::kFog,       &nodes::kRelight,
    &nodes::kMotionBlur, &nodes::kDof,     &nodes::kBloom,    &nodes::kExposure,  &nodes::kGrain,
    &nodes::kLens,       &nodes::kTonemap, &nodes::kReformat, &nodes::kTransform, &nodes::kCrop,
    &nodes::kBlur,       &nodes::kSharpen, &nodes::kAo,       &nodes::kSsr,       &nodes::kCryptomatte,
    &nodes::kSsgi,
};
}  // namespace

const NodeCatalog &nodes::catalog()
{
    static const NodeCatalog kCatalog{kAllNodes};
    return kCatalog;
}

std::span<const NodeType *const> all_node_types()
{
    return nodes::catalog().all();
}

const NodeType *find_node_type(std::string_view type)
{
    return nodes::catalog().find(type);
}

const NodeType &require_node_type(std::string_view type)
{
    const NodeType *t = find_node_type(type);
    if (!t) {
        std::vector<std::string> known;
        for (const NodeType *k : all_node_types()) {
            known.emplace_back(k->spec.type);
        }
        throw_usage("unknown node type \"", type, "\"", did_you_mean(type, known));
    }
    return *t;
}

}  // namespace posthaste
