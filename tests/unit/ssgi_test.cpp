// Screen-space GI: the node on an analytic floor-and-wall frame (a lit wall, a black floor)
// against the closed form of the light one bounce brings to the floor within the radius; what
// the probe adds for arcs the screen leaves open; overscan pixels used as input; the stability
// cases (NaN/Inf in every input, all sky, a bright emitter beside a dark wall, a one-pixel wall,
// the frame's edge, extreme parameters); same bits on any thread count; render's truth "gi".

#include "shading/gi/ssgi.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <limits>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/sanitize.h"
#include "raster/ray_cast.h"
#include "raster/render.h"
#include "raster/scene.h"
#include "shading/camera_rays.h"
#include "shading/lighting/lighting.h"
#include "test_util.h"

namespace posthaste {
namespace {

constexpr float kPi = 3.14159265358979f;
constexpr float kInf = std::numeric_limits<float>::infinity();
const glm::vec3 kWallLight(1.0f, 0.5f, 0.25f);

/// The floor y = 0 (black, albedo 1) and the wall x = 4 (radiance kWallLight) seen by a camera
/// at (0, 3, 0) looking along +x, 35 degrees down, as a frame ssgi reads: color, depth, world
/// normals, albedo and the camera. `margin` pixels of overscan on every side (the display
/// window stays w x h); with `thin`, the wall is only the strip 0.5 <= z <= 0.52.
Frame floor_wall_frame(int w, int h, int margin = 0, bool wall = true)
{
    glm::mat4 to_world(1.0f);
    const float pitch = glm::radians(35.0f);
    const glm::vec3 fwd(std::cos(pitch), -std::sin(pitch), 0.0f);
    const glm::vec3 right(0.0f, 0.0f, -1.0f);
    const glm::vec3 up = glm::cross(fwd, right);
    to_world[0] = glm::vec4(right, 0.0f);
    to_world[1] = glm::vec4(up, 0.0f);
    to_world[2] = glm::vec4(fwd, 0.0f);
    to_world[3] = glm::vec4(0.0f, 3.0f, 0.0f, 1.0f);
    const CameraMatrices m = make_camera_matrices(to_world, 24.0f, 36.0f, float(w) / h, 0.1f);
    Frame f;
    f.display_window = {0, 0, w, h};
    f.data_window = {-margin, -margin, w + margin, h + margin};
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    const int W = w + 2 * margin, H = h + 2 * margin;
    const Camera pc = f.pixel_camera();
    const shading::CameraRays rays(*pc.world_to_camera, *pc.world_to_ndc);
    const glm::vec3 cam = rays.position();
    Image color(W, H, 4), depth(W, H, 1), normal(W, H, 3), albedo(W, H, 3);
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            const glm::vec3 r = rays.depth_ray((x + 0.5f) / W, (y + 0.5f) / H);
            float best = kInf;
            glm::vec3 n(0.0f), l(0.0f);
            if (r.y < 0.0f) {
                best = -cam.y / r.y;
                n = glm::vec3(0, 1, 0);
            }
            if (wall && r.x > 0.0f) {
                const float t = (4.0f - cam.x) / r.x;
                if (t < best) {
                    best = t;
                    n = glm::vec3(-1, 0, 0);
                    l = kWallLight;
                }
            }
            depth.at(x, y, 0) = best;
            color.at(x, y, 3) = 1.0f;
            for (int c = 0; c < 3; ++c) {
                normal.at(x, y, c) = n[c];
                color.at(x, y, c) = l[c];
                albedo.at(x, y, c) = std::isfinite(best) ? 1.0f : 0.0f;
            }
        }
    }
    f.set("color", std::move(color));
    f.set("depth", std::move(depth));
    f.set("normal", std::move(normal));
    f.set("albedo", std::move(albedo));
    return f;
}

/// The largest absolute value of an image.
float peak(const Image &img)
{
    float m = 0.0f;
    for (std::size_t i = 0; i < img.value_count(); ++i) {
        m = std::max(m, std::abs(img.data()[i]));
    }
    return m;
}

/// The cosine-weighted fraction of a floor point's hemisphere that meets an infinite wall at
/// distance d within radius r (ao_test.cpp's corner form: one minus the visibility).
double wall_fraction(double d, double r)
{
    const double c = std::min(1.0, d / r);
    return (std::acos(c) - c * std::sqrt(1.0 - c * c)) / kPi;
}

/// Mean gi.R over floor pixels of the middle columns at distance [d0, d1) from the wall's
/// foot, against the closed form's mean.
void expect_floor_band(
    const Frame &in, const Frame &out, double r, double d0, double d1, double tolerance)
{
    const Image &gi = out.image("gi"), &depth = in.image("depth"), &normal = in.image("normal");
    const int w = gi.width(), h = gi.height();
    const Camera pc = in.pixel_camera();
    const shading::CameraRays rays(*pc.world_to_camera, *pc.world_to_ndc);
    double got = 0.0, want = 0.0;
    int count = 0;
    for (int y = 0; y < h; ++y) {
        for (int x = w / 4; x < 3 * w / 4; ++x) {
            if (normal.at(x, y, 1) != 1.0f) {
                continue;
            }
            const glm::vec3 pt = rays.position() +
                                 depth.at(x, y, 0) * rays.depth_ray((x + 0.5f) / w, (y + 0.5f) / h);
            const double d = 4.0 - pt.x;
            if (d >= d0 && d < d1) {
                got += gi.at(x, y, 0);
                want += wall_fraction(d, r) * kWallLight.x;
                ++count;
            }
        }
    }
    ASSERT_GT(count, 50) << d0;
    EXPECT_NEAR(got / count, want / count, tolerance) << "band from " << d0 << " m";
}

TEST(Ssgi, FloorBesideALitWallGetsTheClosedForm)
{
    // 640x480: at a quarter, the 5x5 denoise spans 20 pixels, a tenth of the floor's depth range.
    const Frame f = floor_wall_frame(640, 480);
    for (const char *res : {"full", "half", "quarter"}) {
        SCOPED_TRACE(res);
        const Frame out = test::run_node(
            "ssgi",
            f,
            std::string(R"({"radius": 1, "slices": 4, "steps": 16, "resolution": ")") + res +
                "\"}");
        // Bands from the wall's foot out to the radius (0.5 at the foot, 0 at 1 m).
        for (const double d0 : {0.0, 0.25, 0.5, 0.75}) {
            expect_floor_band(f, out, 1.0, d0, d0 + 0.25, 0.06);
        }
        // The wall's own pixels see the black floor: nothing added (but for samples on the wall
        // itself, facing it within rounding); colour is light + gi.
        const Image &gi = out.image("gi");
        EXPECT_LT(gi.at(320, 20, 0), 1e-3f);
        EXPECT_FLOAT_EQ(out.image("color").at(320, 400, 0),
                        f.image("color").at(320, 400, 0) + gi.at(320, 400, 0));
        EXPECT_EQ(out.image("color").at(320, 400, 3), 1.0f);
    }
}

TEST(Ssgi, NothingLitNothingAddedAndTheSkyStaysAsItIs)
{
    // A black wall: no light to bounce.
    Frame dark = floor_wall_frame(96, 64);
    Image black = dark.image("color");
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 96; ++x) {
            for (int c = 0; c < 3; ++c) {
                black.at(x, y, c) = 0.0f;
            }
        }
    }
    dark.set("color", std::move(black));
    Frame out = test::run_node("ssgi", dark, "{}");
    EXPECT_EQ(peak(out.image("gi")), 0.0f);
    // All sky: the colour passes through unchanged, gi is 0.
    Frame sky = floor_wall_frame(96, 64);
    Image inf_depth(96, 64, 1);
    inf_depth.fill(kInf);
    sky.set("depth", std::move(inf_depth));
    out = test::run_node("ssgi", sky, "{}");
    EXPECT_EQ(peak(out.image("gi")), 0.0f);
    EXPECT_TRUE(out.image("color").bit_equal(sky.image("color")));
    // Metal (metallic 1) and black albedo take no diffuse bounce.
    Frame metal = floor_wall_frame(96, 64);
    Image mat(96, 64, 3);
    for (int y = 0; y < 64; ++y) {
        for (int x = 0; x < 96; ++x) {
            mat.at(x, y, 1) = 1.0f;
        }
    }
    metal.set("material", std::move(mat));
    EXPECT_EQ(peak(test::run_node("ssgi", metal, "{}").image("gi")), 0.0f);
    // intensity 0: nothing added; apply none: the colour is the input's own image.
    out = test::run_node("ssgi", floor_wall_frame(96, 64), R"({"intensity": 0})");
    EXPECT_EQ(peak(out.image("gi")), 0.0f);
    const Frame lit = floor_wall_frame(96, 64);
    out = test::run_node("ssgi", lit, R"({"apply": "none"})");
    EXPECT_EQ(out.pass("color").image, lit.pass("color").image);
    EXPECT_GT(peak(out.image("gi")), 0.0f);
}

TEST(Ssgi, NonFiniteInputsGiveFiniteBoundedLight)
{
    Frame f = floor_wall_frame(128, 96);
    Image color = f.image("color"), depth = f.image("depth"), normal = f.image("normal"),
          albedo = f.image("albedo");
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int y = 0; y < 96; y += 3) {
        for (int x = (y * 7) % 5; x < 128; x += 5) {
            color.at(x, y, y % 3) = (x % 2) ? nan : kInf;
            depth.at((x + 1) % 128, y, 0) = (x % 3) ? nan : -kInf;
            normal.at((x + 2) % 128, y, x % 3) = (x % 2) ? kInf : nan;
            albedo.at((x + 3) % 128, y, 0) = nan;
        }
    }
    f.set("color", std::move(color));
    f.set("depth", std::move(depth));
    f.set("normal", std::move(normal));
    f.set("albedo", std::move(albedo));
    const Frame out = test::run_node("ssgi", f, "{}");
    const Image &gi = out.image("gi");
    for (std::size_t i = 0; i < gi.value_count(); ++i) {
        ASSERT_TRUE(std::isfinite(gi.data()[i])) << i;
        // The light a bounce adds is at most the brightest finite radiance times albedo 1.
        ASSERT_GE(gi.data()[i], 0.0f);
        ASSERT_LE(gi.data()[i], kWallLight.x + 1e-5f);
    }
}

TEST(Ssgi, ABrightEmitterBesideADarkWallStaysBounded)
{
    // One bright column of the wall (1e4), the rest dark: every pixel's light is a weighted
    // mean of radiances, so at most 1e4, and finite.
    Frame f = floor_wall_frame(160, 120);
    Image color = f.image("color");
    for (int y = 0; y < 120; ++y) {
        for (int x = 0; x < 160; ++x) {
            const bool wall = f.image("normal").at(x, y, 0) == -1.0f;
            for (int c = 0; c < 3; ++c) {
                color.at(x, y, c) = wall ? (x >= 78 && x < 82 ? 1e4f : 0.0f) : 0.0f;
            }
        }
    }
    f.set("color", std::move(color));
    for (const char *params : {"{}",
                               R"({"radius": 1e4, "max_radius_px": 8192, "steps": 64})",
                               R"({"radius": 1e-4})",
                               R"({"resolution": "full", "slices": 16})"}) {
        SCOPED_TRACE(params);
        const Frame out = test::run_node("ssgi", f, params);
        const Image &gi = out.image("gi");
        float peak = 0.0f;
        for (std::size_t i = 0; i < gi.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(gi.data()[i]));
            peak = std::max(peak, gi.data()[i]);
        }
        EXPECT_LE(peak, 1e4f);
    }
}

// Radiance at the top of float's range (3e38 on the wall) summed over a gather's taps and the
// denoise's 5x5 overflowed to infinity in a few pixels; a negative albedo (no physical surface
// has one) gave negative light. The light stays finite and non-negative, and added to a colour
// of 3e38 the sum stays finite too.
TEST(Ssgi, ExtremeRadianceAndNegativeAlbedoStayFiniteAndNonNegative)
{
    Frame f = floor_wall_frame(96, 72);
    Image color = f.image("color"), albedo = f.image("albedo");
    for (int y = 0; y < 72; ++y) {
        for (int x = 0; x < 96; ++x) {
            for (int c = 0; c < 3; ++c) {
                color.at(x, y, c) = 3e38f;
                albedo.at(x, y, c) = (x + y) % 2 ? -0.5f : 1.0f;
            }
        }
    }
    f.set("color", std::move(color));
    f.set("albedo", std::move(albedo));
    for (const char *params : {"{}", R"({"resolution": "full", "slices": 4, "intensity": 16})"}) {
        SCOPED_TRACE(params);
        const Frame out = test::run_node("ssgi", f, params);
        const Image &gi = out.image("gi"), &sum = out.image("color");
        for (std::size_t i = 0; i < gi.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(gi.data()[i])) << i;
            ASSERT_GE(gi.data()[i], 0.0f) << i;
        }
        for (std::size_t i = 0; i < sum.value_count(); ++i) {
            ASSERT_TRUE(std::isfinite(sum.data()[i])) << i;
        }
    }
}

TEST(Ssgi, OverscanPixelsLightTheFramesEdge)
{
    // The floor by the wall in the display window's leftmost columns: without overscan, half of
    // its slices run off the frame at once; with 32 px of margin they march on through wall
    // pixels beyond the edge, and the light comes closer to the closed form.
    const Frame plain = floor_wall_frame(320, 240, 0);
    const Frame wide = floor_wall_frame(320, 240, 32);
    const Frame fa = test::run_node("ssgi", plain, R"({"radius": 1, "resolution": "full"})");
    const Frame fb = test::run_node("ssgi", wide, R"({"radius": 1, "resolution": "full"})");
    const Image &a = fa.image("gi"), &b = fb.image("gi");
    ASSERT_EQ(b.width(), 384);
    const Camera pc = plain.pixel_camera();
    const shading::CameraRays rays(*pc.world_to_camera, *pc.world_to_ndc);
    const Image &depth = plain.image("depth"), &normal = plain.image("normal");
    double got_plain = 0.0, got_wide = 0.0, want = 0.0;
    int count = 0;
    for (int y = 0; y < 240; ++y) {
        for (int x = 0; x < 6; ++x) {
            if (normal.at(x, y, 1) != 1.0f) {
                continue;
            }
            const glm::vec3 pt =
                rays.position() +
                depth.at(x, y, 0) * rays.depth_ray((x + 0.5f) / 320, (y + 0.5f) / 240);
            const double d = 4.0 - pt.x;
            if (d < 0.5) {
                got_plain += a.at(x, y, 0);
                got_wide += b.at(x + 32, y + 32, 0);
                want += wall_fraction(d, 1.0) * kWallLight.x;
                ++count;
            }
        }
    }
    ASSERT_GT(count, 20);
    EXPECT_LT(std::abs(got_wide - want), std::abs(got_plain - want))
        << got_plain / count << " " << got_wide / count << " " << want / count;
    EXPECT_GT(got_wide, got_plain);
    // Away from the edges the margin changes little.
    double middle = 0.0;
    for (int y = 80; y < 160; ++y) {
        for (int x = 80; x < 240; ++x) {
            middle = std::max(middle, double(std::abs(a.at(x, y, 0) - b.at(x + 32, y + 32, 0))));
        }
    }
    EXPECT_LT(middle, 0.05);
}

TEST(Ssgi, TheProbeFillsWhatTheScreenLeavesOpen)
{
    // No wall on screen; a probe that sees a lit surface everywhere below the horizon and the
    // sky above: the floor gets the probe's light over the arcs the march leaves open.
    const Frame f = floor_wall_frame(128, 96, 0, false);
    Frame probe;
    probe.set_size(64, 32);
    Image pc(64, 32, 4), pd(64, 32, 1);
    for (int y = 0; y < 32; ++y) {
        for (int x = 0; x < 64; ++x) {
            const bool below = y >= 16;
            pd.at(x, y, 0) = below ? 5.0f : kInf;
            pc.at(x, y, 0) = pc.at(x, y, 1) = pc.at(x, y, 2) = 2.0f;  // the sky too: must not count
            pc.at(x, y, 3) = 1.0f;
        }
    }
    probe.set("color", std::move(pc));
    probe.set("depth", std::move(pd));
    const test::NodeRunner runner("ssgi", "{}");
    const Frame with = runner.run_ports({{"image", f}, {"environment", probe}}, 1);
    const Frame without = test::run_node("ssgi", f, "{}");
    // The floor's hemisphere is the sky's (up): its open arcs look up, where the probe sees sky.
    EXPECT_LT(peak(with.image("gi")), 0.05f);
    EXPECT_EQ(peak(without.image("gi")), 0.0f);
    // A probe that sees surfaces everywhere: open arcs are lit by them (the floor at most 2).
    Image all = probe.image("depth");
    all.fill(5.0f);
    probe.set("depth", std::move(all));
    const Frame lit_frame = runner.run_ports({{"image", f}, {"environment", probe}}, 1);
    const Image &lit = lit_frame.image("gi");
    EXPECT_GT(lit.at(64, 80, 0), 0.5f);
    EXPECT_LE(peak(lit), 2.0f + 1e-4f);
    // fallback none: as without the probe.
    const test::NodeRunner none("ssgi", R"({"fallback": "none"})");
    EXPECT_EQ(peak(none.run_ports({{"image", f}, {"environment", probe}}, 1).image("gi")), 0.0f);
}

/// The floor-and-wall frame with a material pass: every surface `roughness`, metallic 0.
Frame with_material(Frame f, float roughness)
{
    Image mat(f.width(), f.height(), 3);
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            mat.at(x, y, 0) = roughness;
        }
    }
    f.set("material", std::move(mat));
    return f;
}

TEST(Ssgi, ReshadingMovesOnlyViewDependentLight)
{
    // The sun below the floor and behind the wall (it lights neither face the frame shows) and
    // rough surfaces (no sky reflection): nothing of their light depends on the view, so
    // re-shading changes nothing but rounding.
    const std::string low_sun = R"(, "sun_irradiance": [3, 3, 3], "sun_direction": [1, -0.5, 0])";
    const Frame rough = with_material(floor_wall_frame(160, 120), 1.0f);
    const Frame a = test::run_node("ssgi", rough, R"({"resolution": "half"})");
    const Frame b = test::run_node(
        "ssgi", rough, std::string(R"({"resolution": "half", "reshade": "on")") + low_sun + "}");
    float diff = 0.0f;
    for (std::size_t i = 0; i < a.image("gi").value_count(); ++i) {
        diff = std::max(diff, std::abs(a.image("gi").data()[i] - b.image("gi").data()[i]));
    }
    EXPECT_LT(diff, 1e-5f);
    // A polished wall reflects the sky: toward the floor (grazing) more than toward the camera,
    // so the floor gets more light once the wall's samples are re-shaded for it.
    const std::string sun = R"(, "sun_irradiance": [3, 3, 3], "sun_direction": [1, 0.5, 0])";
    const Frame polished = with_material(floor_wall_frame(160, 120), 0.05f);
    const Frame c = test::run_node("ssgi", polished, R"({"resolution": "half"})");
    const Frame d = test::run_node(
        "ssgi", polished, std::string(R"({"resolution": "half", "reshade": "on")") + sun + "}");
    double before = 0.0, after = 0.0;
    for (std::size_t i = 0; i < c.image("gi").value_count(); ++i) {
        before += c.image("gi").data()[i];
        after += d.image("gi").data()[i];
        ASSERT_TRUE(std::isfinite(d.image("gi").data()[i]));
        ASSERT_GE(d.image("gi").data()[i], 0.0f);
    }
    EXPECT_GT(after, before * 1.05);
    // Without the sun's irradiance (no header, no parameter) re-shading is refused by name.
    try {
        test::run_node("ssgi", polished, R"({"reshade": "on"})");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("sun_irradiance"), std::string::npos) << e.what();
    }
}

/// The floor-and-wall frame with a mirror floor (metal, albedo 1, roughness 0.05) and a rough
/// wall (roughness 1, dielectric).
Frame with_mirror_floor(Frame f)
{
    Image mat(f.width(), f.height(), 3);
    const Image &normal = f.image("normal");
    for (int y = 0; y < f.height(); ++y) {
        for (int x = 0; x < f.width(); ++x) {
            const bool floor = normal.at(x, y, 1) == 1.0f;
            mat.at(x, y, 0) = floor ? 0.05f : 1.0f;
            mat.at(x, y, 1) = floor ? 1.0f : 0.0f;
        }
    }
    f.set("material", std::move(mat));
    return f;
}

/// The cosine-weighted mean radiance a wall point (4, y, 0) receives from the mirror floor
/// y = 0 lit by the sun `s` of irradiance 1, within radius 4 of the point: the floor's response
/// (the truth's lobe, roughness at least 0.3) integrated numerically over the directions about
/// the sun's mirror image, by the midpoint rule in (sqrt of the angle from it, turn): the lobe's
/// tail matters (a tenth of it lies beyond 30 degrees).
double wall_glint(double y, const glm::vec3 &s)
{
    shading::Surface floor;
    floor.albedo = glm::vec3(1.0f);
    floor.metallic = 1.0f;
    floor.roughness = shading::kReflectedSunMinRoughness;
    const glm::vec3 up(0, 1, 0), wall_n(-1, 0, 0);
    const glm::vec3 axis = glm::normalize(s - 2.0f * glm::dot(up, s) * up);
    const glm::vec3 t1 = glm::normalize(glm::cross(axis, up)), t2 = glm::cross(axis, t1);
    constexpr int kN = 400;
    const double cone = kPi / 2.0;
    double sum = 0.0;
    for (int i = 0; i < kN; ++i) {
        const double u = (i + 0.5) / kN, th = cone * u * u, dth = cone * 2.0 * u / kN;
        for (int j = 0; j < kN; ++j) {
            const double ph = (j + 0.5) * 2.0 * kPi / kN;
            const glm::vec3 w =
                float(std::cos(th)) * axis +
                float(std::sin(th)) * (float(std::cos(ph)) * t1 + float(std::sin(ph)) * t2);
            const double cos_r = glm::dot(w, wall_n), t = -y / w.y;
            if (!(w.y < 0.0f) || !(cos_r > 0.0) || t > 4.0) {
                continue;
            }
            const double l = shading::direct_response(floor, up, -w, s).x;
            sum += l * cos_r * std::sin(th) * dth * (2.0 * kPi / kN);
        }
    }
    return sum / kPi;
}

TEST(Ssgi, AMirrorFloorsReflectedSunReachesTheWallFacingIt)
{
    // The sun behind the camera, 45 degrees up: the floor mirrors it onto the wall, whose points
    // see the sun's image 45 degrees down, toward the camera. No sky light (sky_scale 0) and a
    // black metal floor: that light is all the wall gets.
    const glm::vec3 s = glm::normalize(glm::vec3(-1.0f, 1.0f, 0.0f));
    const Frame f = with_mirror_floor(floor_wall_frame(320, 240));
    const std::string sun =
        R"("reshade": "on", "sun_irradiance": [1, 1, 1], "sun_direction": [-1, 1, 0], "sky_scale": 0)";
    const Frame on = test::run_node("ssgi", f, "{" + sun + "}");
    const Frame off = test::run_node("ssgi", f, "{" + sun + R"(, "reflected_sun": false})");
    const Camera pc = f.pixel_camera();
    const shading::CameraRays rays(*pc.world_to_camera, *pc.world_to_ndc);
    const Image &depth = f.image("depth"), &normal = f.image("normal");
    int count = 0;
    double err_on = 0.0, err_off = 0.0;
    for (int y = 0; y < 240; y += 3) {
        double want = -1.0;  // the same height along a row of the wall
        for (int x = 120; x < 200; x += 7) {
            if (normal.at(x, y, 0) != -1.0f) {
                continue;
            }
            const glm::vec3 pt =
                rays.position() +
                depth.at(x, y, 0) * rays.depth_ray((x + 0.5f) / 320, (y + 0.5f) / 240);
            if (pt.y < 0.3f || pt.y > 2.0f) {
                continue;  // the floor the wall's points see lies on screen and within the radius
            }
            want = want < 0.0 ? wall_glint(pt.y, s) : want;
            ASSERT_GT(want, 0.05) << pt.y;
            // The node takes the lobe whole at its centre's direction: the part of its tail
            // beyond the wall's horizon or above the floor's (about a tenth here) counts too.
            EXPECT_NEAR(on.image("gi").at(x, y, 0), want, 0.15 * want) << x << "," << y;
            err_on += std::abs(on.image("gi").at(x, y, 0) - want);
            err_off += std::abs(off.image("gi").at(x, y, 0) - want);
            ++count;
        }
    }
    ASSERT_GT(count, 20);
    // Left to the slices (one a pixel, eight samples a side), the highlight is mostly missed.
    EXPECT_GT(err_off, 3.0 * err_on);
    // The floor itself faces away from the sun's image: nothing traced for it.
    EXPECT_LT(on.image("gi").at(160, 230, 0), 1e-3f);
    // NaN and Inf in the material, the normals and a shadow pass: finite, and at most the
    // sun's irradiance over pi from each of the two planes traced.
    Frame bad = f;
    Image mat = bad.image("material"), normal_bad = bad.image("normal"), shadow(320, 240, 1);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int y = 0; y < 240; ++y) {
        for (int x = 0; x < 320; ++x) {
            shadow.at(x, y, 0) = (x + y) % 7 == 0 ? nan : 1.0f;
            if ((x * 3 + y) % 11 == 0) {
                mat.at(x, y, x % 2) = x % 3 ? nan : kInf;
                normal_bad.at(x, y, y % 3) = nan;
            }
        }
    }
    bad.set("material", std::move(mat));
    bad.set("normal", std::move(normal_bad));
    bad.set("shadow", std::move(shadow));
    const Frame bad_out = test::run_node("ssgi", bad, "{" + sun + "}");
    const Image &gi = bad_out.image("gi");
    for (std::size_t i = 0; i < gi.value_count(); ++i) {
        ASSERT_TRUE(std::isfinite(gi.data()[i])) << i;
        ASSERT_GE(gi.data()[i], 0.0f);
        ASSERT_LE(gi.data()[i], 2.0f / kPi + kWallLight.x);
    }
}

/// A computed pixel's depth (its top-left full-resolution pixel's; NaN for no surface) and unit
/// normal (0 where unknown), as the resolve takes them.
float reduced_depth(const Image &depth, int st, int x, int y)
{
    const float z = depth.at(x * st, y * st, 0);
    return z > 0.0f && std::isfinite(z) ? z : std::numeric_limits<float>::quiet_NaN();
}
glm::vec3 reduced_normal(const Image &normal, int st, int x, int y)
{
    const glm::vec3 n(
        normal.at(x * st, y * st, 0), normal.at(x * st, y * st, 1), normal.at(x * st, y * st, 2));
    const float len2 = glm::dot(n, n);
    return len2 > 1e-12f && std::isfinite(len2) ? n / std::sqrt(len2) : glm::vec3(0.0f);
}

/// The upsample as a plain loop (the code the Highway rows replaced): bilinear weights times the
/// depth tent times max(0, n.m / |n|)^8 over the four reduced taps, the tap nearest in depth
/// where none weighs, 0 on the sky; no denoise, no albedo.
Image reference_upsample(const Image &light, const Image &depth, const Image &normal, int st)
{
    const int ow = light.width(), oh = light.height(), w = depth.width(), h = depth.height();
    const auto lz = [&](int x, int y) { return reduced_depth(depth, st, x, y); };
    const auto ln = [&](int x, int y) { return reduced_normal(normal, st, x, y); };
    Image out(w, h, 3);
    for (int y = 0; y < h; ++y) {
        const int j0 = std::min(y / st, oh - 1), j1 = std::min(j0 + 1, oh - 1);
        const float fy = float(y - j0 * st) / float(st);
        for (int x = 0; x < w; ++x) {
            const int i0 = std::min(x / st, ow - 1), i1 = std::min(i0 + 1, ow - 1);
            const float fx = float(x - i0 * st) / float(st);
            const float z = depth.at(x, y, 0);
            if (!(z > 0.0f) || !std::isfinite(z)) {
                continue;
            }
            const float inv = 1.0f / (0.1f * z);
            const glm::vec3 n(normal.at(x, y, 0), normal.at(x, y, 1), normal.at(x, y, 2));
            const float len2 = glm::dot(n, n);
            const bool known = len2 > 1e-12f && std::isfinite(len2);
            const float inv_len2 = known ? 1.0f / len2 : 0.0f;
            const int ti[4] = {i0, i1, i0, i1}, tj[4] = {j0, j0, j1, j1};
            const float bw[4] = {
                (1.0f - fx) * (1.0f - fy), fx * (1.0f - fy), (1.0f - fx) * fy, fx * fy};
            float sum[3] = {0.0f, 0.0f, 0.0f}, wsum = 0.0f, best = INFINITY;
            int nearest = -1;
            for (int k = 0; k < 4; ++k) {
                const float dz = std::abs(lz(ti[k], tj[k]) - z);
                const glm::vec3 tn = ln(ti[k], tj[k]);
                float nw = 1.0f;
                if (known && tn != glm::vec3(0.0f)) {
                    const float t = std::max(0.0f, glm::dot(n, tn));
                    const float t2 = t * t * inv_len2;
                    nw = t2 * t2;
                    nw *= nw;
                }
                const float tent = std::max(0.0f, 1.0f - dz * inv);
                const float wt = bw[k] * tent * nw;
                const float *v = light.pixel(ti[k], tj[k]);
                for (int c = 0; c < 3; ++c) {
                    sum[c] += wt * v[c];
                }
                wsum += wt;
                if (dz < best) {
                    best = dz;
                    nearest = k;
                }
            }
            float *o = out.pixel(x, y);
            for (int c = 0; c < 3; ++c) {
                o[c] = wsum > 1e-6f   ? sum[c] * (1.0f / wsum)
                       : nearest >= 0 ? light.pixel(ti[nearest], tj[nearest])[c]
                                      : 0.0f;
            }
        }
    }
    return out;
}

/// The denoise as a plain loop: a 5 x 5 window at the reduced resolution, weights the depth
/// tent times max(0, a.b)^8 of the unit normals (1 where either is unknown).
Image reference_denoise(const Image &light, const Image &depth, const Image &normal, int st)
{
    const int ow = light.width(), oh = light.height();
    const auto lz = [&](int x, int y) { return reduced_depth(depth, st, x, y); };
    const auto ln = [&](int x, int y) { return reduced_normal(normal, st, x, y); };
    Image low = light;
    for (int y = 0; y < oh; ++y) {
        for (int x = 0; x < ow; ++x) {
            const float z = lz(x, y);
            if (!(z > 0.0f)) {
                continue;
            }
            const float inv = 1.0f / (0.1f * z);
            const glm::vec3 n = ln(x, y);
            float sum[3] = {0.0f, 0.0f, 0.0f}, wsum = 0.0f;
            for (int j = std::max(0, y - 2); j <= std::min(oh - 1, y + 2); ++j) {
                for (int i = std::max(0, x - 2); i <= std::min(ow - 1, x + 2); ++i) {
                    const glm::vec3 m = ln(i, j);
                    float nw = 1.0f;
                    if (n != glm::vec3(0.0f) && m != glm::vec3(0.0f)) {
                        float t = std::max(0.0f, glm::dot(n, m));
                        t *= t;
                        t *= t;
                        nw = t * t;
                    }
                    const float wt = std::max(0.0f, 1.0f - std::abs(lz(i, j) - z) * inv) * nw;
                    for (int c = 0; c < 3; ++c) {
                        sum[c] += wt * light.at(i, j, c);
                    }
                    wsum += wt;
                }
            }
            for (int c = 0; c < 3; ++c) {
                low.at(x, y, c) = sum[c] / wsum;
            }
        }
    }
    return low;
}

TEST(Ssgi, TheResolveReadsNonFiniteValuesAsAScanWouldReplaceThem)
{
    // The node no longer scans depth, normals and albedo for NaN and infinities before the
    // resolve (58 MB at 1080p): the resolve reads a non-finite normal component or albedo as 0
    // and a non-finite depth as the sky, which is what finite_view gave it before, bit for bit.
    const int w = 203, h = 37, st = 4, ow = (w + st - 1) / st, oh = (h + st - 1) / st;
    const float nan = std::numeric_limits<float>::quiet_NaN(),
                inf = std::numeric_limits<float>::infinity();
    Image depth(w, h, 1), normal(w, h, 3), albedo(w, h, 3), material(w, h, 2), light(ow, oh, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::uint32_t k = std::uint32_t(x * 7919 + y * 104729);
            const float bad = k % 3 == 0 ? nan : k % 3 == 1 ? inf : -inf;
            depth.at(x, y, 0) = k % 37 == 0 ? bad : 2.0f + 0.05f * float(x % 13);
            const float a = 0.1f * float(k % 17);
            normal.at(x, y, 0) = k % 41 == 0 ? bad : std::sin(a);
            normal.at(x, y, 1) = k % 43 == 0 ? bad : std::cos(a);
            normal.at(x, y, 2) = 0.3f;
            for (int c = 0; c < 3; ++c) {
                albedo.at(x, y, c) = (k + std::uint32_t(c)) % 47 == 0 ? bad : 0.5f;
            }
            material.at(x, y, 1) = 0.2f;
        }
    }
    for (int y = 0; y < oh; ++y) {
        for (int x = 0; x < ow; ++x) {
            for (int c = 0; c < 3; ++c) {
                light.at(x, y, c) = 0.1f + 0.01f * float((x + 2 * y + c) % 11);
            }
        }
    }
    Image sd, sn, sa;
    const Image &depth_f = finite_view(depth, inf, sd, true);
    const Image &normal_f = finite_view(normal, 0.0f, sn);
    const Image &albedo_f = finite_view(albedo, 0.0f, sa);
    ASSERT_NE(&normal_f, &normal);
    ASSERT_NE(&albedo_f, &albedo);
    test::for_each_highway_target([&](const char *target) {
        for (const bool denoise : {false, true}) {
            const shading::SsgiApply raw{&albedo, &material, 1.0f},
                scanned{&albedo_f, &material, 1.0f};
            EXPECT_TRUE(shading::ssgi_resolve(light, depth, normal, st, denoise, &raw)
                            .bit_equal(shading::ssgi_resolve(
                                light, depth_f, normal_f, st, denoise, &scanned)))
                << target << (denoise ? ", denoised" : "");
        }
    });
}

TEST(Ssgi, TheResolveAddsItsLightToTheColourRowByRow)
{
    // apply: add makes colour + gi inside the resolve, each row while its light is in cache:
    // bit for bit the sum of the colour and the gi the resolve returns, other channels as they
    // are, for colour passes of 1, 3, 4 and 5 channels; a colour of another size is refused.
    const int w = 61, h = 23, st = 4, ow = (w + st - 1) / st, oh = (h + st - 1) / st;
    Image depth(w, h, 1), normal(w, h, 3), albedo(w, h, 3), light(ow, oh, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            depth.at(x, y, 0) = (x + y) % 11 == 0 ? std::numeric_limits<float>::infinity()
                                                  : 2.0f + 0.1f * float(x % 5);
            normal.at(x, y, 1) = 1.0f;
            for (int c = 0; c < 3; ++c) {
                albedo.at(x, y, c) = 0.2f + 0.1f * float(c);
            }
        }
    }
    for (int y = 0; y < oh; ++y) {
        for (int x = 0; x < ow; ++x) {
            for (int c = 0; c < 3; ++c) {
                light.at(x, y, c) = 0.3f + 0.01f * float((x * 7 + y * 3 + c) % 13);
            }
        }
    }
    for (const int nc : {1, 3, 4, 5}) {
        Image color(w, h, nc), sum(w, h, nc);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < nc; ++c) {
                    color.at(x, y, c) = 0.1f * float((x + 2 * y + 3 * c) % 17) + 1e-3f;
                }
            }
        }
        shading::SsgiApply apply{&albedo, nullptr, 0.8f};
        apply.color = &color;
        apply.sum = &sum;
        const Image gi = shading::ssgi_resolve(light, depth, normal, st, true, &apply);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < nc; ++c) {
                    const float want = color.at(x, y, c) + (c < 3 ? gi.at(x, y, c) : 0.0f);
                    ASSERT_EQ(sum.at(x, y, c), want) << nc << " channels, " << x << "," << y;
                }
            }
        }
    }
    Image small(w - 1, h, 4), sum(w - 1, h, 4);
    shading::SsgiApply apply{&albedo, nullptr, 1.0f};
    apply.color = &small;
    apply.sum = &sum;
    EXPECT_THROW(shading::ssgi_resolve(light, depth, normal, st, false, &apply), Error);
}

TEST(Ssgi, TheResolveGivesThePlainLoopsBitsOnEveryTarget)
{
    // A width that is no multiple of the lanes, depth edges, sky, NaN depth, zero and
    // unnormalised normals, a depth no tap's tent reaches: the Highway rows of the denoise and
    // the upsample give the plain loops' bits, on every target this CPU has, with the taps
    // permuted from the reduced rows (strides 2 and 4 inside a row) and gathered (stride 1, and
    // a row's last vectors).
    const int w = 203, h = 37;
    Image depth(w, h, 1), normal(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const std::uint32_t k = std::uint32_t(x * 7919 + y * 104729);
            float z = 2.0f + 0.05f * float(x % 13) + (x > 90 ? 6.0f : 0.0f);
            if (k % 23 == 0) {
                z = std::numeric_limits<float>::infinity();  // sky
            } else if (k % 29 == 0) {
                z = std::numeric_limits<float>::quiet_NaN();
            } else if (k % 31 == 0) {
                z = 100.0f;  // far from every tap
            }
            depth.at(x, y, 0) = z;
            const float a = 0.1f * float(k % 17);
            normal.at(x, y, 0) = k % 19 == 0 ? 0.0f : 2.0f * std::sin(a);
            normal.at(x, y, 1) = k % 19 == 0 ? 0.0f : 2.0f * std::cos(a);
            normal.at(x, y, 2) = k % 19 == 0 ? 0.0f : 0.3f;
        }
    }
    for (const int st : {1, 2, 4}) {
        const int ow = (w + st - 1) / st, oh = (h + st - 1) / st;
        Image light(ow, oh, 3);
        for (int y = 0; y < oh; ++y) {
            for (int x = 0; x < ow; ++x) {
                for (int c = 0; c < 3; ++c) {
                    light.at(x, y, c) = 0.01f * float((x * 31 + y * 17 + c * 5) % 97);
                }
            }
        }
        const Image ref = reference_upsample(light, depth, normal, st);
        // The albedo (three and four channels) and 1 - metallic (NaN, below 0, above 1), in a
        // material pass of 2 to 5 channels (loaded as interleaved vectors, or gathered).
        Image albedo3(w, h, 3), albedo4(w, h, 4);
        std::vector<Image> materials;
        for (int mc : {3, 2, 4, 5}) {
            materials.emplace_back(w, h, mc);
        }
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                for (int c = 0; c < 4; ++c) {
                    const float a = 0.1f + 0.2f * float((x + 3 * y + c) % 5);
                    if (c < 3) {
                        albedo3.at(x, y, c) = a;
                    }
                    albedo4.at(x, y, c) = a;
                }
                const int k = (x + y) % 7;
                for (Image &material : materials) {
                    material.at(x, y, 1) = k == 0   ? std::numeric_limits<float>::quiet_NaN()
                                           : k == 1 ? -0.5f
                                           : k == 2 ? 1.5f
                                                    : 0.1f * float(k);
                }
            }
        }
        const Image denoised =
            reference_upsample(reference_denoise(light, depth, normal, st), depth, normal, st);
        test::for_each_highway_target([&](const char *target) {
            const Image out = shading::ssgi_resolve(light, depth, normal, st, false, nullptr);
            EXPECT_TRUE(out.bit_equal(ref)) << "stride " << st << ", " << target;
            EXPECT_TRUE(
                shading::ssgi_resolve(light, depth, normal, st, true, nullptr).bit_equal(denoised))
                << "denoised, stride " << st << ", " << target;
            for (std::size_t i = 0; i < materials.size() + 1; ++i) {
                const Image *albedo = i == 0 ? &albedo4 : &albedo3;
                const Image &material = materials[i == 0 ? 0 : i - 1];
                const shading::SsgiApply apply{albedo, &material, 0.7f};
                const Image lit = shading::ssgi_resolve(light, depth, normal, st, false, &apply);
                Image want = ref;
                for (int y = 0; y < h; ++y) {
                    for (int x = 0; x < w; ++x) {
                        const float metal = material.at(x, y, 1);
                        float k = 0.7f;
                        k *= std::isfinite(metal) ? 1.0f - std::clamp(metal, 0.0f, 1.0f) : 1.0f;
                        for (int c = 0; c < 3; ++c) {
                            float &v = want.at(x, y, c);
                            v = k * albedo->at(x, y, c) * std::max(0.0f, v);
                        }
                    }
                }
                EXPECT_TRUE(lit.bit_equal(want))
                    << "stride " << st << ", albedo " << albedo->channels() << ", material "
                    << material.channels() << ", " << target;
            }
        });
    }
}

TEST(Ssgi, SameBitsOnAnyThreadCount)
{
    const Frame f = floor_wall_frame(200, 150);
    set_thread_count(1);
    const Frame one = test::run_node("ssgi", f, "{}");
    set_thread_count(2);
    const Frame two = test::run_node("ssgi", f, "{}");
    set_thread_count(0);
    EXPECT_TRUE(one.image("gi").bit_equal(two.image("gi")));
    EXPECT_TRUE(one.image("color").bit_equal(two.image("color")));
    // Re-shaded, with the mirror floor's reflected sun traced.
    const Frame m = with_mirror_floor(floor_wall_frame(200, 150));
    const std::string p =
        R"({"reshade": "on", "sun_irradiance": [1, 1, 1], "sun_direction": [-1, 1, 0]})";
    set_thread_count(1);
    const Frame m1 = test::run_node("ssgi", m, p);
    set_thread_count(2);
    const Frame m2 = test::run_node("ssgi", m, p);
    set_thread_count(0);
    EXPECT_TRUE(m1.image("gi").bit_equal(m2.image("gi")));
}

TEST(Ssgi, NodeNamesWhatIsMissing)
{
    Frame f = floor_wall_frame(32, 24);
    Frame no_albedo = f;
    no_albedo.erase("albedo");
    try {
        test::run_node("ssgi", no_albedo, "{}");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("albedo"), std::string::npos) << e.what();
    }
    Frame no_camera = f;
    no_camera.camera = Camera{};
    try {
        test::run_node("ssgi", no_camera, "{}");
        ADD_FAILURE() << "no error";
    } catch (const Error &e) {
        EXPECT_NE(std::string(e.what()).find("worldTo"), std::string::npos) << e.what();
    }
}

TEST(GiTruth, AddsLightOnlyToSurfacesAndIsRepeatable)
{
    const raster::Scene s = raster::load_scene(test::scene_path("minecrappy.json"));
    raster::RenderOptions o;
    o.width = 96;
    o.height = 54;
    const raster::GiTruth a = raster::render_gi_truth(s, 8, o, 16, 0);
    const raster::GiTruth b = raster::render_gi_truth(s, 8, o, 16, 0);
    EXPECT_TRUE(a.color.bit_equal(b.color));
    o.passes = {"color", "depth"};
    const Frame beauty = raster::render_frame(s, 8, o);
    const Image &c = beauty.image("color"), &z = beauty.image("depth");
    int lit = 0;
    for (int y = 0; y < 54; ++y) {
        for (int x = 0; x < 96; ++x) {
            for (int k = 0; k < 3; ++k) {
                const float add = a.indirect.at(x, y, k);
                ASSERT_TRUE(std::isfinite(add));
                ASSERT_GE(add, 0.0f);
                EXPECT_FLOAT_EQ(a.color.at(x, y, k), c.at(x, y, k) + add);
                if (!std::isfinite(z.at(x, y, 0))) {
                    EXPECT_EQ(add, 0.0f);  // the sky takes no bounce
                }
                lit += add > 0.0f;
            }
        }
    }
    EXPECT_GT(lit, 96 * 54);  // most surfaces get some light back
}

}  // namespace
}  // namespace posthaste
