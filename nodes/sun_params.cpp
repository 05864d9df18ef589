// The sun's direction and irradiance, read and checked once (sun_params.h).

#include "nodes/sun_params.h"

#include <cmath>
#include <glm/geometric.hpp>

#include "core/sanitize.h"
#include "graph/param_bind.h"

namespace posthaste::nodes {

glm::vec3 sun_direction(NodeContext &ctx, const ParamSpec &spec, const Frame &in)
{
    const glm::vec3 d = rescaled_direction(param_value<glm::vec3>(ctx, spec, HeaderSource::of(in)));
    const float len = glm::length(d);
    if (!(len > 0.0f) || !std::isfinite(len)) {
        throw_runtime(ctx.where(),
                      ": param \"",
                      spec.name,
                      "\" (header ",
                      spec.header,
                      ") must be a non-zero finite vector");
    }
    return d;
}

void check_sun_irradiance(const NodeContext &ctx, const ParamSpec &spec, const glm::vec3 &e)
{
    for (int c = 0; c < 3; ++c) {
        if (!std::isfinite(e[c]) || e[c] < 0.0f) {
            throw_runtime(ctx.where(),
                          ": param \"",
                          spec.name,
                          "\" (header ",
                          spec.header,
                          ") must be finite and >= 0");
        }
    }
}

}  // namespace posthaste::nodes
