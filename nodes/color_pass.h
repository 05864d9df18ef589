#pragma once
// Shared by the point color nodes (ocio, grade): apply one ColorProcessor to one pass of the
// "image" input. A no-op processor leaves the output sharing the input pass.

#include <string>

#include "io/color.h"
#include "nodes/node.h"

namespace posthaste::nodes {

inline void apply_to_pass(NodeContext &ctx,
                          const ColorProcessor &proc,
                          const std::string &name,
                          bool unpremultiply,
                          const char *what)
{
    const Pass &in = ctx.input("image").pass(name, ctx.where());
    if (proc.is_noop()) {
        return;  // the output already shares the input pass
    }
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
    Image out = *in.image;
    proc.apply(out, unpremultiply);
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

}  // namespace posthaste::nodes
