#include "shading/lighting/occluder_thickness.h"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <vector>

#include "core/parallel.h"

namespace posthaste::shading {
namespace {

/// The camera-space point at depth 1 seen through NDC (u, v): the two NDC equations of
/// cam_to_ndc solved for (X, Y) at z = 1 (relight.cpp's prepare_pixel at z = 1). False where the
/// matrix leaves them singular.
bool ray_at_unit_depth(const glm::mat4 &m, float u, float v, glm::vec3 &q)
{
    const float a00 = m[0][0] - u * m[0][3], a01 = m[1][0] - u * m[1][3];
    const float a10 = m[0][1] - v * m[0][3], a11 = m[1][1] - v * m[1][3];
    const float b0 = -((m[2][0] - u * m[2][3]) + m[3][0] - u * m[3][3]);
    const float b1 = -((m[2][1] - v * m[2][3]) + m[3][1] - v * m[3][3]);
    const float det = a00 * a11 - a01 * a10;
    if (!(det != 0.0f) || !std::isfinite(det)) {
        return false;
    }
    q = glm::vec3((b0 * a11 - a01 * b1) / det, (a00 * b1 - a10 * b0) / det, 1.0f);
    return std::isfinite(q.x) && std::isfinite(q.y);
}

}  // namespace

Image occluder_thickness(const Image &depth,
                         const Image &normal,
                         const glm::mat4 &world_to_camera,
                         const glm::mat4 &camera_to_ndc,
                         float max_thickness)
{
    const int w = depth.width(), h = depth.height();
    Image out(w, h, 1);  // 0: nothing there to occlude (sky, no depth)
    glm::vec3 q0, qx, qy;
    // Without a pixel footprint (a singular camera) every surface is as deep as the most.
    const bool known = ray_at_unit_depth(camera_to_ndc, 0.5f, 0.5f, q0) &&
                       ray_at_unit_depth(camera_to_ndc, 0.5f + 1.0f / float(w), 0.5f, qx) &&
                       ray_at_unit_depth(camera_to_ndc, 0.5f, 0.5f + 1.0f / float(h), qy);
    // A pixel's width at depth 1 (a pinhole's footprint grows with depth alone).
    const float footprint = known ? 0.5f * (glm::length(qx - q0) + glm::length(qy - q0)) : 0.0f;
    // Per pixel its depth (0 where none) and, once asked for, the tangent of the angle between
    // its normal and its view ray (-1 until then): how far depth steps from one pixel to the next
    // on a continuous surface. Only pixels beside a step in depth of more than 1 % ask.
    Image zt = Image::uninitialized(w, h, 2);
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = depth.at(x, y, 0);
            float *o = zt.pixel(x, y);
            o[0] = z > 0.0f && std::isfinite(z) ? z : 0.0f;
            o[1] = -1.0f;
        }
    });
    const glm::mat3 rot(world_to_camera);
    const auto tangent = [&](int x, int y) {
        float &t = zt.at(x, y, 1);
        if (t >= 0.0f) {
            return t;
        }
        t = 0.0f;  // no usable normal: the surface is taken as facing the camera
        glm::vec3 ray;
        const glm::vec3 n =
            rot * glm::vec3(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
        const float nn = glm::length(n);
        if (nn > 0.0f && std::isfinite(nn) &&
            ray_at_unit_depth(
                camera_to_ndc, (float(x) + 0.5f) / float(w), (float(y) + 0.5f) / float(h), ray)) {
            const float c = std::fabs(glm::dot(n, ray)) / (nn * glm::length(ray));
            const float s = std::sqrt(std::max(0.0f, 1.0f - c * c));
            t = std::min(s / std::max(c, 0.05f), 20.0f);
        }
        return t;
    };
    // Neighbours a and b lie on one surface when their depths differ by no more than twice what
    // the flatter one's slope gives over a pixel, plus 1 % of the depth (noise, curvature). (Each
    // pass below runs a line per thread and asks only for its line's pixels' tangents.)
    const auto joined = [&](int xa, int ya, int xb, int yb) {
        const float za = zt.at(xa, ya, 0), zb = zt.at(xb, yb, 0);
        if (za == 0.0f || zb == 0.0f) {
            return false;
        }
        const float z = std::min(za, zb), step = std::fabs(za - zb);
        if (step <= 0.01f * z) {
            return true;
        }
        return step <= z * (2.0f * footprint * std::min(tangent(xa, ya), tangent(xb, yb)) + 0.01f);
    };
    // The runs of joined pixels along each row, then each column; a run that reaches the
    // image's edge may go on beyond it: unbounded.
    constexpr float kUnbounded = 1e30f;
    Image run_x(w, h, 1), run_y(w, h, 1);
    const auto runs = [&](int count, int length, bool rows, Image &dst) {
        parallel_for(0, count, [&](int line) {
            const auto put = [&](int i, float v) {
                (rows ? dst.pixel(i, line) : dst.pixel(line, i))[0] = v;
            };
            int start = 0;
            for (int i = 1; i <= length; ++i) {
                if (i < length &&
                    (rows ? joined(i - 1, line, i, line) : joined(line, i - 1, line, i))) {
                    continue;
                }
                const bool open = start == 0 || i == length;
                const float v = open ? kUnbounded : float(i - start);
                for (int k = start; k < i; ++k) {
                    put(k, v);
                }
                start = i;
            }
        });
    };
    if (known) {
        runs(h, w, true, run_x);
        runs(w, h, false, run_y);
    }
    parallel_for(0, h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            const float z = zt.at(x, y, 0);
            const float extent = std::min(run_x.at(x, y, 0), run_y.at(x, y, 0));
            out.at(x, y, 0) = z == 0.0f ? 0.0f
                              : known   ? std::min(max_thickness, extent * footprint * z)
                                        : max_thickness;
        }
    });
    return out;
}

}  // namespace posthaste::shading
