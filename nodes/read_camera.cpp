#include "nodes/read_camera.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <glm/matrix.hpp>
#include <nlohmann/json.hpp>

#include "core/camera.h"
#include "core/error.h"

namespace posthaste::nodes {
namespace {

using json = nlohmann::json;

/// 16 numbers in OpenEXR's order (points are row vectors, the translation is elements 12-14),
/// which is also glm's memory layout.
glm::mat4 parse_matrix(const json &j, const ParamWhere &where, const char *key)
{
    if (!j.is_array() || j.size() != 16) {
        throw_usage(where.path,
                    "/",
                    key,
                    ": ",
                    where.who,
                    ": a matrix is 16 numbers (OpenEXR's order, row vectors)");
    }
    float v[16];
    for (std::size_t i = 0; i < 16; ++i) {
        if (!j[i].is_number() || !std::isfinite(j[i].get<double>())) {
            throw_usage(where.path, "/", key, "/", i, ": ", where.who, ": not a finite number");
        }
        v[i] = j[i].get<float>();
    }
    glm::mat4 m;
    std::memcpy(&m, v, sizeof m);
    const std::string problem = std::string(key) == "world_to_ndc" ? projection_matrix_problem(m)
                                                                   : camera_matrix_problem(m);
    if (!problem.empty()) {
        throw_usage(where.path, "/", key, ": ", where.who, ": the matrix ", problem);
    }
    return m;
}

float parse_positive(const json &j, const ParamWhere &where, const char *key)
{
    if (!j.is_number() || !(j.get<double>() > 0.0) || !std::isfinite(j.get<double>())) {
        throw_usage(where.path, "/", key, ": ", where.who, ": must be a positive number");
    }
    return j.get<float>();
}

}  // namespace

GraphCamera parse_graph_camera(const std::string &json_text, const ParamWhere &where)
{
    GraphCamera c;
    const json j = json::parse(json_text, nullptr, false);
    if (j.is_discarded() || !(j.is_null() || j.is_object())) {
        throw_usage(where.path,
                    ": ",
                    where.who,
                    ": the camera is an object: {\"world_to_camera\", \"world_to_ndc\"} or "
                    "{\"camera_to_world\", \"focal_length\", \"sensor_width\"}");
    }
    if (j.is_null()) {
        return c;
    }
    for (const auto &[key, value] : j.items()) {
        if (key == "world_to_camera") {
            c.world_to_camera = parse_matrix(value, where, "world_to_camera");
        } else if (key == "world_to_ndc") {
            c.world_to_ndc = parse_matrix(value, where, "world_to_ndc");
        } else if (key == "camera_to_world") {
            c.camera_to_world = parse_matrix(value, where, "camera_to_world");
        } else if (key == "focal_length") {
            c.focal_length_mm = parse_positive(value, where, "focal_length");
        } else if (key == "sensor_width") {
            c.sensor_width_mm = parse_positive(value, where, "sensor_width");
        } else if (key == "near_clip") {
            c.near_clip = parse_positive(value, where, "near_clip");
        } else {
            throw_usage(where.path,
                        ": ",
                        where.who,
                        ": unknown camera field \"",
                        key,
                        "\" (known: world_to_camera, world_to_ndc, camera_to_world, focal_length, "
                        "sensor_width, near_clip)");
        }
    }
    if (c.camera_to_world && (c.world_to_camera || c.world_to_ndc)) {
        throw_usage(where.path,
                    ": ",
                    where.who,
                    ": give camera_to_world with a lens, or the two matrices, not both");
    }
    if (c.camera_to_world && !c.focal_length_mm) {
        throw_usage(where.path,
                    ": ",
                    where.who,
                    ": camera_to_world needs focal_length (mm; sensor_width defaults to 36)");
    }
    if (!c.camera_to_world && (c.world_to_camera.has_value() != c.world_to_ndc.has_value())) {
        throw_usage(where.path, ": ", where.who, ": give both world_to_camera and world_to_ndc");
    }
    return c;
}

void apply_graph_camera(const GraphCamera &g, Frame &frame)
{
    Camera &cam = frame.camera;
    if (g.near_clip) {
        cam.near_clip = g.near_clip;
    }
    if (g.focal_length_mm) {
        cam.focal_length_mm = g.focal_length_mm;
    }
    if (g.sensor_width_mm) {
        cam.sensor_width_mm = g.sensor_width_mm;
    }
    if (g.camera_to_world) {
        const float sensor = cam.sensor_width_mm.value_or(36.0f);
        const Rect &d = frame.display_window;
        const float aspect = float(d.width()) / float(std::max(1, d.height()));
        const CameraMatrices m = make_camera_matrices(
            *g.camera_to_world, *g.focal_length_mm, sensor, aspect, cam.near_clip.value_or(0.1f));
        cam.sensor_width_mm = sensor;
        cam.sensor_height_mm = sensor / aspect;
        cam.world_to_camera = m.world_to_camera;
        cam.world_to_ndc = m.world_to_ndc;
    } else {
        cam.world_to_camera = g.world_to_camera;
        cam.world_to_ndc = g.world_to_ndc;
    }
    cam.origin = "graph";
}

CameraSolve solve_frame_camera(Frame &frame, CameraSolveOptions options, const std::string &who)
{
    options.near_clip = frame.camera.near_clip;
    const CameraSolve solve = solve_camera(frame.image("position"),
                                           frame.image("depth"),
                                           frame.display_window,
                                           frame.data_window,
                                           who,
                                           options);
    apply_camera_solve(solve, stamped_focal_length(frame.attributes), frame.camera);
    return solve;
}

std::optional<float> stamped_focal_length(const OIIO::ParamValueList &attributes)
{
    const OIIO::ParamValue *p = attributes.find_pv("Lens", OIIO::TypeUnknown, false);
    if (!p || p->type() != OIIO::TypeString) {
        return std::nullopt;
    }
    const std::string text = p->get_string();
    char *end = nullptr;
    const float mm = std::strtof(text.c_str(), &end);
    if (end == text.c_str() || !(mm > 0.0f) || !std::isfinite(mm)) {
        return std::nullopt;
    }
    return mm;
}

}  // namespace posthaste::nodes
