#pragma once
// Everything a node file needs: the node interface, images, frames, passes, parallel loops,
// errors, and parameters bound to settings fields (graph/param_bind.h). Each nodes/<type>.cpp
// defines one `extern const NodeType k<Type>` listed in nodes/registry.cpp.

#include <glm/vec3.hpp>
#include <string>

#include "core/error.h"
#include "core/frame.h"
#include "core/image.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "graph/node.h"
#include "graph/param_bind.h"

namespace posthaste::nodes {

/// Pass `name` of the frame on input "image", for a node that works on its R, G, B (and alpha):
/// a runtime error naming the node, the pass and `what` (the node's noun) when it is missing or
/// has fewer than 3 channels.
inline const Pass &rgb_pass(const NodeContext &ctx, const std::string &name, const char *what)
{
    const Pass &in = ctx.input("image").pass(name, ctx.where());
    if (in.image->channels() < 3) {
        throw_runtime(ctx.where(),
                      ": pass \"",
                      name,
                      "\" has ",
                      in.image->channels(),
                      " channels; ",
                      what,
                      " needs 3 or 4");
    }
    return in;
}

extern const NodeType kRead;
extern const NodeType kWrite;
extern const NodeType kOcio;
extern const NodeType kGrade;
extern const NodeType kMerge;
extern const NodeType kChannels;
extern const NodeType kRender;
extern const NodeType kFog;
extern const NodeType kRelight;
extern const NodeType kMotionBlur;
extern const NodeType kHatching;
extern const NodeType kDof;
extern const NodeType kBloom;
extern const NodeType kExposure;
extern const NodeType kGrain;
extern const NodeType kLens;
extern const NodeType kTonemap;
extern const NodeType kReformat;
extern const NodeType kTransform;
extern const NodeType kCrop;
extern const NodeType kBlur;
extern const NodeType kSharpen;
extern const NodeType kAo;
extern const NodeType kSsr;
extern const NodeType kCryptomatte;
extern const NodeType kSsgi;

}  // namespace posthaste::nodes
