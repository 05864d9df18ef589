#include "nodes/material_params.h"

#include <cstdio>

namespace posthaste::nodes {

const Image &material_or_constant(NodeContext &ctx, std::string_view port, Image &storage)
{
    const Frame &in = ctx.input(port);
    if (in.has("material")) {
        if (ctx.params().given(kMaterialRoughness) || ctx.params().given(kMaterialMetallic)) {
            ctx.state().note_once(ctx.node().describe() +
                                  ": the frame's material pass is used; roughness and metallic "
                                  "apply only where a frame has none");
        }
        return in.image("material", ctx.where());
    }
    const float roughness = ctx.get_float(kMaterialRoughness);
    const float metallic = ctx.get_float(kMaterialMetallic);
    char text[96];
    std::snprintf(text,
                  sizeof text,
                  "no material pass: roughness %g and metallic %g for every surface",
                  double(roughness),
                  double(metallic));
    ctx.state().note_once(ctx.node().describe() + ": " + text);
    const Image &color = in.image("color", ctx.where());
    storage = Image::uninitialized(color.width(), color.height(), 3);
    float *p = storage.data();
    for (std::size_t i = 0; i < storage.pixel_count(); ++i) {
        p[3 * i] = roughness;
        p[3 * i + 1] = metallic;
        p[3 * i + 2] = 0.0f;
    }
    return storage;
}

}  // namespace posthaste::nodes
