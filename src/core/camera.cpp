#include "core/camera.h"

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/mat4x4.hpp>

#include "core/error.h"

namespace posthaste {
namespace {

template <typename T>
const T &require(const std::optional<T> &v, const char *attribute, const std::string &who)
{
    if (!v) {
        throw_runtime(who, ": camera attribute \"", attribute, "\" is missing from the header");
    }
    return *v;
}

/// The matrix, or an Error naming it when it cannot be used (a header may hold NaNs or zeros):
/// worldToCamera by camera_matrix_problem, worldToNDC by projection_matrix_problem. `origin`
/// empty: a previous frame's matrix, which only the header gives.
const glm::mat4 &usable(const glm::mat4 &m,
                        const char *attribute,
                        bool projection,
                        const std::string &who,
                        const std::string &origin)
{
    const std::string problem =
        projection ? projection_matrix_problem(m) : camera_matrix_problem(m);
    if (!problem.empty()) {
        throw_runtime(who,
                      ": camera attribute \"",
                      attribute,
                      "\" ",
                      problem,
                      origin.empty() ? " (the header's previous frame)"
                                     : " (" + origin +
                                           "); give the camera as read's \"camera\" "
                                           "parameter instead");
    }
    return m;
}

/// A matrix has three sources; the message names them all.
const glm::mat4 &require_matrix(const std::optional<glm::mat4> &m,
                                const char *attribute,
                                const std::string &who,
                                const std::string &origin)
{
    if (!m) {
        throw_runtime(who,
                      ": camera attribute \"",
                      attribute,
                      "\" is missing from the header",
                      origin.empty() ? "" : " (" + origin + ")",
                      "; give the camera in the header "
                      "(worldToCamera, worldToNDC), as read's \"camera\" parameter, or with "
                      "position and depth passes to solve it from");
    }
    return usable(*m, attribute, attribute == attr::kWorldToNDC, who, origin);
}

bool all_finite(const glm::mat4 &m)
{
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            if (!std::isfinite(m[c][r])) {
                return false;
            }
        }
    }
    return true;
}

}  // namespace

std::string camera_matrix_problem(const glm::mat4 &m)
{
    if (!all_finite(m)) {
        return "has an entry that is not finite";
    }
    const float det = glm::determinant(m);
    if (!std::isfinite(det) || std::abs(det) < 1e-12f) {
        return str_cat("is singular (determinant ", det, ")");
    }
    return "";
}

std::string projection_matrix_problem(const glm::mat4 &m)
{
    if (!all_finite(m)) {
        return "has an entry that is not finite";
    }
    // The directions' parts of the x, y and w outputs (row vectors: p * M): independent for any
    // perspective or orthographic camera, whatever the units or the translation.
    const glm::dvec3 x(m[0][0], m[1][0], m[2][0]), y(m[0][1], m[1][1], m[2][1]),
        w(m[0][3], m[1][3], m[2][3]);
    const double volume = std::abs(glm::dot(glm::cross(x, y), w));
    if (!(volume > 1e-6 * glm::length(x) * glm::length(y) * glm::length(w))) {
        return "projects onto less than a plane (its x, y and w rows are not independent)";
    }
    return "";
}

const glm::mat4 &Camera::require_world_to_camera(const std::string &who) const
{
    return require_matrix(world_to_camera, attr::kWorldToCamera, who, origin);
}
const glm::mat4 &Camera::require_world_to_ndc(const std::string &who) const
{
    return require_matrix(world_to_ndc, attr::kWorldToNDC, who, origin);
}
const glm::mat4 &Camera::require_prev_world_to_camera(const std::string &who) const
{
    return usable(require(prev_world_to_camera, attr::kPrevWorldToCamera, who),
                  attr::kPrevWorldToCamera,
                  false,
                  who,
                  "");
}
const glm::mat4 &Camera::require_prev_world_to_ndc(const std::string &who) const
{
    return usable(require(prev_world_to_ndc, attr::kPrevWorldToNDC, who),
                  attr::kPrevWorldToNDC,
                  true,
                  who,
                  "");
}
Camera Camera::for_window(const Rect &display, const Rect &data) const
{
    if (display == data || display.empty() || data.empty()) {
        return *this;
    }
    // NDC of the display window -> NDC of the data window: u' = a u + b (an affine map after
    // the divide, so it composes onto the clip-space matrix as A * M).
    const float ax = float(display.width()) / float(data.width());
    const float bx = float(display.x0 - data.x0) / float(data.width());
    const float ay = float(display.height()) / float(data.height());
    const float by = float(display.y0 - data.y0) / float(data.height());
    glm::mat4 remap(1.0f);
    remap[0][0] = ax;
    remap[3][0] = bx;
    remap[1][1] = ay;
    remap[3][1] = by;
    Camera c = *this;
    if (c.world_to_ndc) {
        c.world_to_ndc = remap * *c.world_to_ndc;
    }
    if (c.prev_world_to_ndc) {
        c.prev_world_to_ndc = remap * *c.prev_world_to_ndc;
    }
    if (c.sensor_width_mm) {
        *c.sensor_width_mm /= ax;
    }
    if (c.sensor_height_mm) {
        *c.sensor_height_mm /= ay;
    }
    return c;
}

float Camera::require_fstop(const std::string &who) const
{
    return require(fstop, attr::kAperture, who);
}
float Camera::require_focus_distance(const std::string &who) const
{
    return require(focus_distance, attr::kFocus, who);
}
float Camera::require_focal_length_mm(const std::string &who) const
{
    return require(focal_length_mm, attr::kFocalLength, who);
}
float Camera::require_sensor_width_mm(const std::string &who) const
{
    return require(sensor_width_mm, attr::kSensorWidth, who);
}

CameraMatrices make_camera_matrices(const glm::mat4 &camera_to_world,
                                    float focal_length_mm,
                                    float sensor_width_mm,
                                    float aspect,
                                    float near_clip)
{
    const glm::mat4 world_to_camera = glm::inverse(camera_to_world);
    // Camera space (x right, y up, z forward) to NDC ([0,1]^2, y down):
    //   u = 0.5 + (f / sw) * x / z,  v = 0.5 - (f / sw) * aspect * y / z.
    // As a projective matrix with w = z; the third row keeps z so NDC depth stays monotonic.
    const float sx = focal_length_mm / sensor_width_mm;
    const float sy = sx * aspect;
    glm::mat4 cam_to_ndc(0.0f);  // glm: m[column][row]
    cam_to_ndc[0][0] = sx;
    cam_to_ndc[1][1] = -sy;
    cam_to_ndc[2][0] = 0.5f;
    cam_to_ndc[2][1] = 0.5f;
    cam_to_ndc[2][2] = 1.0f;
    cam_to_ndc[3][2] = -near_clip;
    cam_to_ndc[2][3] = 1.0f;
    return {world_to_camera, cam_to_ndc * world_to_camera};
}

bool world_to_pixel(
    const glm::mat4 &world_to_ndc, const glm::vec3 &p, int width, int height, glm::vec2 &pixel)
{
    const glm::vec4 h = world_to_ndc * glm::vec4(p, 1.0f);
    if (!(h.w > 0.0f)) {
        return false;
    }
    pixel = glm::vec2(h.x / h.w * float(width), h.y / h.w * float(height));
    return true;
}

}  // namespace posthaste
