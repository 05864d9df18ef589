#pragma once
// The material a frame lacks: most renderers write no roughness or metallic pass by default
// (Blender among them), so the nodes that shade with the material pass (relight, ssr) take it
// from these two parameters where the frame has none, and say so once. Declared once here for
// both.

#include "nodes/node.h"

namespace posthaste::nodes {

inline constexpr ParamSpec kMaterialRoughness =
    ParamSpec::real("roughness", 0.5)
        .range(0.0, 1.0)
        .doc(
            "Where the frame has no material pass: the GGX perceptual roughness of every "
            "surface (a note on stderr says so once).");
inline constexpr ParamSpec kMaterialMetallic =
    ParamSpec::real("metallic", 0.0)
        .range(0.0, 1.0)
        .doc("Where the frame has no material pass: the metallic of every surface.");

/// Ask for the material pass where the input can give it (plan hooks).
inline void plan_material(PlanContext &ctx, std::size_t port = 0)
{
    ctx.inputs[port].add_optional("material");
}

/// The input's material pass on `port`, or, where the frame has none, an image of the
/// parameters' roughness and metallic (anisotropy 0) the size of its colour, made into
/// `storage`.
const Image &material_or_constant(NodeContext &ctx, std::string_view port, Image &storage);

}  // namespace posthaste::nodes
