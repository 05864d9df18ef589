#pragma once
// Camera: the matrices and lens of one frame, as read from (and written to) EXR headers.
//
// Conventions (docs/CONVENTIONS.md): matrices are OpenEXR's, points are row vectors (p * M). GLM
// and Imath share a memory layout, so a glm::mat4 copied from an Imath M44f applies as M * p with
// column vectors. Camera space is left-handed: +X right, +Y up, +Z forward (view direction); depth
// is camera-space z. NDC maps the display window to [0,1]^2, (0,0) top-left, (1,1) bottom-right.
// Scene units are metres.

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <optional>
#include <string>

#include "core/image.h"

namespace posthaste {

/// EXR header attribute names for the camera. The first two are OpenEXR standard attributes;
/// the previous-frame matrices and the lens extras are posthaste's, documented in
/// docs/CONVENTIONS.md.
namespace attr {
inline constexpr const char *kWorldToCamera = "worldToCamera";          // m44f
inline constexpr const char *kWorldToNDC = "worldToNDC";                // m44f
inline constexpr const char *kPrevWorldToCamera = "prevWorldToCamera";  // m44f
inline constexpr const char *kPrevWorldToNDC = "prevWorldToNDC";        // m44f
inline constexpr const char *kAperture = "aperture";                    // float, f-number
inline constexpr const char *kFocus = "focus";                          // float, metres
inline constexpr const char *kFocalLength = "focalLength";              // float, mm
inline constexpr const char *kSensorWidth = "sensorWidth";              // float, mm
inline constexpr const char *kSensorHeight = "sensorHeight";            // float, mm
inline constexpr const char *kShutter = "shutter";          // float, fraction of the frame interval
inline constexpr const char *kNearClip = "nearClip";        // float, scene units
inline constexpr const char *kFarClip = "farClip";          // float, scene units
inline constexpr const char *kFrameNumber = "frameNumber";  // int
}  // namespace attr

/// Why a worldToCamera cannot be used, or "" when it can: an entry that is not finite, or a
/// singular matrix (|determinant| < 1e-12; a rigid one has +-1). One rule for the header's
/// matrices and the graph's.
std::string camera_matrix_problem(const glm::mat4 &m);
/// Why a worldToNDC cannot be used, or "" when it can: an entry that is not finite, or x, y and
/// w rows whose direction parts are not independent (a zero matrix; a projection onto a line).
/// Scale- and translation-free, so scenes in millimetres or far from the origin pass; the depth
/// row is not judged (camera-only motion never reads it).
std::string projection_matrix_problem(const glm::mat4 &m);

struct Camera {
    std::optional<glm::mat4> world_to_camera;
    std::optional<glm::mat4> world_to_ndc;
    std::optional<glm::mat4> prev_world_to_camera;
    std::optional<glm::mat4> prev_world_to_ndc;
    std::optional<float> fstop;           ///< f-number (EXR `aperture`).
    std::optional<float> focus_distance;  ///< metres (EXR `focus`).
    std::optional<float> focal_length_mm;
    std::optional<float> sensor_width_mm;
    std::optional<float> sensor_height_mm;
    std::optional<float> shutter;  ///< fraction of the frame interval the shutter is open.
    std::optional<float> near_clip;
    std::optional<float> far_clip;
    /// Where the matrices came from, for `info` and messages: "header", "graph", or a solve's
    /// description ("solved from position + depth, residual ..."); "" when not known. Not part
    /// of the camera's value: two cameras with the same matrices and lens are equal.
    std::string origin;

    bool operator==(const Camera &o) const
    {
        return world_to_camera == o.world_to_camera && world_to_ndc == o.world_to_ndc &&
               prev_world_to_camera == o.prev_world_to_camera &&
               prev_world_to_ndc == o.prev_world_to_ndc && fstop == o.fstop &&
               focus_distance == o.focus_distance && focal_length_mm == o.focal_length_mm &&
               sensor_width_mm == o.sensor_width_mm && sensor_height_mm == o.sensor_height_mm &&
               shutter == o.shutter && near_clip == o.near_clip && far_clip == o.far_clip;
    }

    /// The value, or an Error naming the missing (or unusable: camera_matrix_problem) header
    /// attribute and who needed it.
    const glm::mat4 &require_world_to_camera(const std::string &who) const;
    const glm::mat4 &require_world_to_ndc(const std::string &who) const;
    const glm::mat4 &require_prev_world_to_camera(const std::string &who) const;
    const glm::mat4 &require_prev_world_to_ndc(const std::string &who) const;
    float require_fstop(const std::string &who) const;
    float require_focus_distance(const std::string &who) const;
    float require_focal_length_mm(const std::string &who) const;
    float require_sensor_width_mm(const std::string &who) const;

    /// The same camera for an image covering `data` instead of `display` (both absolute pixel
    /// rectangles): NDC [0,1]^2 and the sensor size then span `data`. The identity when they are
    /// equal. Used to give nodes, which map pixels over their images, the data window's view.
    Camera for_window(const Rect &display, const Rect &data) const;
};

/// The camera's scalar header attributes and the members they fill, each once: the reader, the
/// writer and a parameter's header fallback (graph/param_bind.h) walk the same table.
struct CameraScalarAttribute {
    const char *name;
    std::optional<float> Camera::*member;
};
inline constexpr CameraScalarAttribute kCameraScalarAttributes[] = {
    {attr::kAperture, &Camera::fstop},
    {attr::kFocus, &Camera::focus_distance},
    {attr::kFocalLength, &Camera::focal_length_mm},
    {attr::kSensorWidth, &Camera::sensor_width_mm},
    {attr::kSensorHeight, &Camera::sensor_height_mm},
    {attr::kShutter, &Camera::shutter},
    {attr::kNearClip, &Camera::near_clip},
    {attr::kFarClip, &Camera::far_clip},
};

/// A pinhole camera's matrices from a camera-to-world transform and lens. `view_to_world` maps
/// camera space (left-handed, +Z forward) to world space. Returns {worldToCamera, worldToNDC}.
struct CameraMatrices {
    glm::mat4 world_to_camera;
    glm::mat4 world_to_ndc;
};
CameraMatrices make_camera_matrices(const glm::mat4 &camera_to_world,
                                    float focal_length_mm,
                                    float sensor_width_mm,
                                    float aspect /* width / height */,
                                    float near_clip);

/// Project a world point with a worldToNDC matrix to pixel coordinates of a width x height
/// display window (pixel centres at +0.5). Returns false behind the camera (w <= 0).
bool world_to_pixel(
    const glm::mat4 &world_to_ndc, const glm::vec3 &p, int width, int height, glm::vec2 &pixel);

}  // namespace posthaste
