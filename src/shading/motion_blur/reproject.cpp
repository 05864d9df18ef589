#include "shading/motion_blur/reproject.h"

#include <cmath>
#include <glm/glm.hpp>

#include "core/parallel.h"

namespace posthaste::shading {

Image camera_motion(const Image &depth, const Camera &camera, const std::string &who)
{
    const glm::mat4 &w2c = camera.require_world_to_camera(who);
    const glm::mat4 &w2n = camera.require_world_to_ndc(who);
    const glm::mat4 &prev_w2n = camera.require_prev_world_to_ndc(who);
    const glm::mat4 c2w = glm::inverse(w2c);
    const glm::mat4 c2n = w2n * c2w;  // camera space -> NDC (homogeneous)
    // Camera space -> previous pixel, in double: the two matrices are close and we want their
    // small difference, not float round-off.
    const glm::dmat4 c2prev = glm::dmat4(prev_w2n) * glm::dmat4(c2w);
    const int w = depth.width(), h = depth.height();
    Image out(w, h, 2);
    // Rows of c2n (GLM is column-major: row r is (m[0][r], m[1][r], m[2][r], m[3][r])).
    auto row = [&](int r) { return glm::vec4(c2n[0][r], c2n[1][r], c2n[2][r], c2n[3][r]); };
    const glm::vec4 r0 = row(0), r1 = row(1), r3 = row(3);
    parallel_for(0, h, [&](int y) {
        const float v = (float(y) + 0.5f) / float(h);
        for (int x = 0; x < w; ++x) {
            const float u = (float(x) + 0.5f) / float(w);
            const float z = depth.at(x, y, 0);
            const bool sky = std::isinf(z) && z > 0.0f;
            if (!sky && !(z > 0.0f && std::isfinite(z))) {
                continue;  // NaN, -inf or behind the camera: no motion
            }
            // Solve (r0 - u r3) . (X, Y, Z, 1) = 0 and (r1 - v r3) . (X, Y, Z, 1) = 0 for X, Y
            // with Z = z (for sky, Z = 1 and the point is a direction).
            const float zz = sky ? 1.0f : z;
            const glm::vec4 a = r0 - u * r3, b = r1 - v * r3;
            const float ca = a.z * zz + a.w, cb = b.z * zz + b.w;
            const float det = a.x * b.y - a.y * b.x;
            if (!(std::abs(det) > 0.0f)) {
                continue;
            }
            const float px = (-ca * b.y + cb * a.y) / det;
            const float py = (-a.x * cb + b.x * ca) / det;
            const glm::dvec4 hp = c2prev * glm::dvec4(px, py, zz, sky ? 0.0 : 1.0);
            if (!(hp.w > 0.0)) {
                continue;
            }
            const double prev_x = hp.x / hp.w * w, prev_y = hp.y / hp.w * h;
            const float mx = float((x + 0.5) - prev_x), my = float((y + 0.5) - prev_y);
            if (std::isfinite(mx) && std::isfinite(my)) {
                out.at(x, y, 0) = mx;
                out.at(x, y, 1) = my;
            }
        }
    });
    return out;
}

}  // namespace posthaste::shading
