#pragma once
// The lighting split's parameter shared by dof and motion_blur (shading/lighting/lighting_split.h).

#include "nodes/node.h"

namespace posthaste::nodes {

inline constexpr ParamSpec kSpecularKnee =
    ParamSpec::real("specular_knee", 1.0)
        .range(0.0, 1e6)
        .doc(
            "The lighting split blurs on its own only what a pixel's specular share holds above "
            "this (scene-linear, per channel); below it the share stays in color and is blurred "
            "with the rest, where a smooth, dim reflection loses little. 0: all of it apart "
            "(a second blur over every glossy surface).")
        .only_when("specular", "auto");

}  // namespace posthaste::nodes
