#pragma once
// The sun a node shades with (fog's in-scattering, ssr's and ssgi's re-shading): its direction
// and irradiance come from a parameter or the frame's header (posthaste:sunDirection,
// posthaste:sunIrradiance), read and checked here once for every node, with one message.

#include <glm/vec3.hpp>

#include "nodes/node.h"

namespace posthaste::nodes {

/// The direction towards the sun from `spec` (the parameter, else the header), not normalised:
/// each node keeps its own normalisation's rounding (a vector whose float length over- or
/// underflows, such as [1e-30, 0, 0], comes divided by its largest component). One line naming
/// the parameter and the header when it is zero or not finite.
glm::vec3 sun_direction(NodeContext &ctx, const ParamSpec &spec, const Frame &in);

/// One line naming the parameter and the header unless every component of the sun's
/// irradiance is finite and >= 0.
void check_sun_irradiance(const NodeContext &ctx,
                          const ParamSpec &spec,
                          const glm::vec3 &irradiance);

}  // namespace posthaste::nodes
