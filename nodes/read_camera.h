#pragma once
// nodes/read_camera.h: where a read frame's camera comes from. In order: the graph (read's
// `camera` parameter), the file's header (worldToCamera and worldToNDC), or a solve from the
// frame's position and depth passes (core/camera_solve.h) for files that carry no matrices
// (Blender's, and most renderers'). Camera::origin records which.

#include <glm/mat4x4.hpp>
#include <optional>
#include <string>

#include "core/camera_solve.h"
#include "core/frame.h"

namespace posthaste::nodes {

/// The camera a graph gives: matrices, or a camera-to-world transform with a lens.
struct GraphCamera {
    std::optional<glm::mat4> world_to_camera;
    std::optional<glm::mat4> world_to_ndc;
    std::optional<glm::mat4> camera_to_world;
    std::optional<float> focal_length_mm;
    std::optional<float> sensor_width_mm;
    std::optional<float> near_clip;
    bool given() const { return world_to_camera || world_to_ndc || camera_to_world; }
};

/// Where a parameter sits, for messages: its JSON path and the node ("node "in" (read)").
struct ParamWhere {
    std::string path;
    std::string who;
};

/// Parse read's `camera` parameter (JSON text; "null" or "{}" give none). Throws a usage Error
/// naming `where` for unknown keys, a matrix that is not 16 finite numbers or is
/// singular, a lens value out of range, or a combination that does not make a camera.
GraphCamera parse_graph_camera(const std::string &json_text, const ParamWhere &where);

/// Set the frame's matrices from the graph's camera (the display window gives the aspect).
void apply_graph_camera(const GraphCamera &camera, Frame &frame);

/// Solve the frame's camera from its position and depth passes (the near clip the header's, if
/// it has one; the focal length the header's, else Blender's stamp's) and put it in the frame's
/// camera; returns the solve. Throws the solve's runtime Error, naming `who`.
CameraSolve solve_frame_camera(Frame &frame, CameraSolveOptions options, const std::string &who);

/// The focal length in mm from Blender's stamp metadata (`Lens`, "50.00 mm"), if the header's
/// attributes have it.
std::optional<float> stamped_focal_length(const OIIO::ParamValueList &attributes);

}  // namespace posthaste::nodes
