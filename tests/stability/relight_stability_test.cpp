// Stability of the relight node (nodes/relight.cpp) on degenerate G-buffers: n.v and n.l near
// 0, roughness 0, degenerate tangents (zero, NaN, parallel to n), background (Z = +inf, N = 0),
// NaN normals, positions and materials. Output must be finite everywhere, background and
// unusable pixels keep their input, and the added radiance stays under the stated bound:
// per unit irradiance, direct_response <= 1/pi + 1 / (4 pi alpha_min^3) (GGX peak D = 1 / (pi
// alpha^2) times V n.l <= 1 / (4 alpha)), about 9.6e6 at alpha_min = 0.045^2.
#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <string>

#include "core/camera.h"
#include "core/error.h"
#include "core/hash.h"
#include "core/parallel.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "shading/lighting/brdf.h"
#include "test_util.h"

namespace posthaste {
namespace {

// Run the relight node with `params` (JSON object text) on `in`, outside a graph's evaluation.
Frame run_relight(const Frame &in, const std::string &params)
{
    return test::run_node("relight", in, params, in.number);
}

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

// A camera at the origin looking along +z; the surface point of pixel (x, y) lies at depth 4 and
// every pixel gets its own normal, light-facing configuration, material and tangent from a sweep
// over the degenerate cases (column = case, row = parameter).
Frame degenerate_frame(int w, int h)
{
    Frame f;
    f.number = 1;
    f.set_size(w, h);
    const CameraMatrices cm =
        make_camera_matrices(glm::mat4(1.0f), 35.0f, 36.0f, float(w) / float(h), 0.05f);
    f.camera.world_to_camera = cm.world_to_camera;
    f.camera.world_to_ndc = cm.world_to_ndc;
    Image color(w, h, 4), normal(w, h, 3), position(w, h, 3), albedo(w, h, 3), material(w, h, 3);
    Image tangent(w, h, 3), depth(w, h, 1), id(w, h, 1);
    const glm::mat4 c2w = glm::inverse(cm.world_to_camera);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float u = (float(x) + 0.5f) / float(w), v = (float(y) + 0.5f) / float(h);
            // Camera-space point at z = 4 through the pixel centre (sx = 35 / 36).
            const float sx = 35.0f / 36.0f, sy = sx * float(w) / float(h);
            const glm::vec3 pc((u - 0.5f) / sx * 4.0f, (0.5f - v) / sy * 4.0f, 4.0f);
            const glm::vec3 p(c2w * glm::vec4(pc, 1.0f));
            const glm::vec3 view = glm::normalize(-p);  // toward the camera at the origin
            // Normals: from facing the camera to exactly perpendicular to it (n.v = 0), and
            // random directions including back-facing ones.
            const float r1 = hash_unit(x, y, 0, 1), r2 = hash_unit(x, y, 1, 1);
            const glm::vec3 side = glm::normalize(glm::cross(view, glm::vec3(0, 1, 0)));
            glm::vec3 n;
            switch (x % 4) {
                case 0: {  // grazing view: n.v in [0, 1e-3]
                    const float nv = r1 * 1e-3f;
                    n = glm::normalize(view * nv + side * std::sqrt(1 - nv * nv));
                    break;
                }
                case 1:  // random sphere direction
                    n = glm::vec3(
                        std::sqrt(1 - (2 * r1 - 1) * (2 * r1 - 1)) * std::cos(6.2831853f * r2),
                        2 * r1 - 1,
                        std::sqrt(1 - (2 * r1 - 1) * (2 * r1 - 1)) * std::sin(6.2831853f * r2));
                    break;
                case 2:  // mirror configuration for the sun: h = n
                    n = glm::normalize(view + glm::normalize(glm::vec3(0.3f, 0.8f, -0.5f)));
                    break;
                default:
                    n = view;
                    break;
            }
            float rough = (y % 5) * 0.25f;  // 0, 0.25 .. 1
            float aniso = (y % 3) - 1.0f;   // -1, 0, 1
            glm::vec3 t = glm::normalize(glm::cross(n, glm::vec3(0.3f, 0.4f, 0.5f)));
            bool nan_position = false;
            switch ((x / 4) % 7) {
                case 0:
                    t = glm::vec3(0.0f);
                    break;  // degenerate tangents
                case 1:
                    t = glm::vec3(kNaN);
                    break;
                case 2:
                    t = n;
                    break;
                case 3:
                    n = glm::vec3(kNaN, 0, 0);
                    break;  // NaN normal
                case 4:
                    rough = kNaN;
                    aniso = kNaN;
                    break;  // NaN material
                case 5:
                    nan_position = true;
                    break;
                default:
                    break;
            }
            float z = pc.z;
            if ((x + 3 * y) % 11 == 0) {  // background: as the rasterizer writes its sky
                z = kInf;
                n = glm::vec3(0.0f);
            }
            auto put = [&](Image &img, const glm::vec3 &c) {
                img.at(x, y, 0) = c.x;
                img.at(x, y, 1) = c.y;
                img.at(x, y, 2) = c.z;
            };
            put(color, glm::vec3(0.2f, 0.3f, 0.4f));
            color.at(x, y, 3) = 1.0f;
            put(normal, n);
            put(position, z == kInf ? glm::vec3(0.0f) : nan_position ? glm::vec3(kNaN) : p);
            put(albedo, glm::vec3(0.9f, 0.5f, 0.2f));
            put(material, glm::vec3(rough, (x / 24) % 2 ? 1.0f : 0.0f, aniso));
            put(tangent, t);
            depth.at(x, y, 0) = z;
            id.at(x, y, 0) = float(1 + y % 2);
        }
    }
    f.set("color", std::move(color));
    f.set("normal", std::move(normal));
    f.set("position", std::move(position));
    f.set("albedo", std::move(albedo));
    f.set("material", std::move(material));
    f.set("tangent", std::move(tangent));
    f.set("depth", std::move(depth));
    f.set("id", std::move(id));
    return f;
}

// One unit-irradiance sun (the mirror direction of column case 2) plus lights at n.l ~ 0.
const std::string kLights = R"("lights": [
    {"type": "directional", "direction": [0.3, 0.8, -0.5]},
    {"type": "directional", "direction": [1, 0, 0]},
    {"type": "point", "position": [0, 0, 4], "radius": 0.05},
    {"type": "spot", "position": [0, 0, 3.999], "direction": [0, 0, 1]}])";

TEST(RelightStability, DegenerateInputsStayFiniteAndBounded)
{
    const int w = 96, h = 30;
    const Frame in = degenerate_frame(w, h);
    const float alpha_min = shading::kMinRoughness * shading::kMinRoughness;
    // Four lights; the point light is at most 1 / radius^2 = 400 times unit irradiance.
    const double bound = (3.0 + 400.0) * (1.0 / M_PI + 1.0 / (4.0 * M_PI * std::pow(alpha_min, 3)));
    for (const std::string &options :
         {std::string(R"("geometry": "smith_correlated")"),
          std::string(R"("geometry": "smith_separable", "diffuse": "burley")"),
          std::string(R"("geometry": "cook_torrance", "energy_compensation": true)"),
          std::string(R"("energy_compensation": true, "toon_ids": "2", "toon_specular_steps": 4)"),
          std::string(R"("position_from": "depth", "shadows": true, "ambient": 1)")}) {
        for (const char *mode : {"add", "replace"}) {
            const Frame out = run_relight(
                in, "{\"mode\": \"" + std::string(mode) + "\", " + kLights + ", " + options + "}");
            const Image &c = out.image("color");
            double peak = 0.0;
            int kept = 0;
            for (int y = 0; y < h; ++y) {
                for (int x = 0; x < w; ++x) {
                    const Image &n = in.image("normal");
                    const bool usable =
                        std::isfinite(n.at(x, y, 0)) && n.at(x, y, 0) * n.at(x, y, 0) +
                                                                n.at(x, y, 1) * n.at(x, y, 1) +
                                                                n.at(x, y, 2) * n.at(x, y, 2) >
                                                            0.25f;
                    for (int ch = 0; ch < 4; ++ch) {
                        ASSERT_TRUE(std::isfinite(c.at(x, y, ch)))
                            << options << " " << mode << " at " << x << "," << y;
                    }
                    if (!usable) {
                        for (int ch = 0; ch < 4; ++ch) {
                            EXPECT_EQ(c.at(x, y, ch), in.image("color").at(x, y, ch));
                        }
                        ++kept;
                    }
                    for (int ch = 0; ch < 3; ++ch) {
                        peak = std::max(peak, double(c.at(x, y, ch)));
                    }
                }
            }
            std::printf("%-70s %-7s peak %.4g (bound %.3g), %d pixels kept\n",
                        options.c_str(),
                        mode,
                        peak,
                        bound,
                        kept);
            EXPECT_LE(peak, bound);
            EXPECT_GT(kept, w * h / 12);
        }
    }
}

TEST(RelightStability, ClampBoundsEveryLight)
{
    const int w = 96, h = 30;
    const Frame in = degenerate_frame(w, h);
    const Frame out = run_relight(in, "{\"mode\": \"add\", \"clamp\": 2, " + kLights + "}");
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int ch = 0; ch < 3; ++ch) {
                const float added =
                    out.image("color").at(x, y, ch) - in.image("color").at(x, y, ch);
                EXPECT_LE(added, 4 * 2.0f + 1e-5f);
                EXPECT_GE(added, 0.0f);
            }
        }
    }
}

// A light's colour times its intensity beyond a float's range is refused naming the light (both
// within their own ranges, 1e27 x 1e12 once lit thousands of pixels to inf), and a direction
// whose float length underflows is the direction it names, not [0, 0, 0].
TEST(RelightStability, ALightBeyondAFloatIsNamedAndATinyDirectionIsADirection)
{
    const Frame in = degenerate_frame(48, 16);
    try {
        run_relight(in, R"({"lights": [{"type": "point", "position": [0, 2, 0],
            "color": [1e27, 1, 1], "intensity": 1e12}]})");
        ADD_FAILURE() << "an overflowing light ran";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("/lights/0: node \"n\" (relight): color times "
                                             "intensity is beyond a float's range"),
                  std::string::npos)
            << e.what();
    }
    const auto directional = [&](const char *d) {
        return run_relight(
                   in,
                   std::string(R"({"lights": [{"type": "directional", "direction": )") + d + "}]}")
            .image("color");
    };
    EXPECT_TRUE(directional("[1e-30, 1e-30, 0]").bit_equal(directional("[1, 1, 0]")));
    EXPECT_THROW(directional("[0, 0, 0]"), Error);
}

TEST(RelightStability, SameBitsForAnyThreadCount)
{
    const int w = 200, h = 90;
    const Frame in = degenerate_frame(w, h);
    const std::string p =
        "{\"mode\": \"add\", \"shadows\": true, \"energy_compensation\": true, " + kLights + "}";
    set_thread_count(1);
    const Frame one = run_relight(in, p);
    set_thread_count(0);
    const Frame many = run_relight(in, p);
    const Image &a = one.image("color"), &b = many.image("color");
    for (std::size_t i = 0; i < a.pixel_count() * 4; ++i) {
        ASSERT_EQ(a.data()[i], b.data()[i]) << i;
    }
}

}  // namespace
}  // namespace posthaste
