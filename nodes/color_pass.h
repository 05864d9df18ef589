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
    if (proc.is_noop()) {
        ctx.input("image").pass(name, ctx.where());  // still named when missing
        return;  // the output already shares the input pass
    }
    const Pass &in = rgb_pass(ctx, name, what);
    // Copy and transform a row at a time, in parallel (a whole-image copy first is serial).
    const Image &src = *in.image;
    Image out = Image::uninitialized(src.width(), src.height(), src.channels());
    const std::size_t row = std::size_t(src.width()) * std::size_t(src.channels());
    parallel_for(0, src.height(), [&](int y) {
        std::copy(src.pixel(0, y), src.pixel(0, y) + row, out.pixel(0, y));
        proc.apply_row(out.pixel(0, y), src.width(), src.channels(), unpremultiply);
    });
    ctx.output().set(name, std::make_shared<const Image>(std::move(out)), in.channels, in.storage);
}

}  // namespace posthaste::nodes
