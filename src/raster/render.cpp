#include "raster/render.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>
#include <limits>
#include <map>
#include <mutex>
#include <optional>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "core/error.h"
#include "core/hash.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "core/simd.h"
#include "core/timing.h"
#include "raster/color_row.h"
#include "raster/mesh.h"
#include "raster/raster.h"
#include "raster/render_detail.h"
#include "raster/scene_cache.h"
#include "shading/lighting/brdf.h"
#include "shading/lighting/lighting.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/atmosphere/sky.h"

namespace posthaste::raster {

using namespace render_detail;

namespace {

/// The camera at time t as a render of o's size sees it: the scene's, with the sensor widened
/// by `sensor_scale` (an overscan render: the same pixels, more of them).
CameraState camera_for(const Scene &s, double t, float sensor_scale)
{
    CameraState c = s.camera_at(t);
    c.sensor_width_mm *= sensor_scale;
    return c;
}

void fill_header(const Scene &s, int frame, const RenderOptions &o, Frame &f, float sensor_scale)
{
    f.number = frame;
    f.set_size(o.width, o.height);
    const CameraState c = camera_for(s, frame, sensor_scale),
                      cp = camera_for(s, frame - 1, sensor_scale);
    const float aspect = float(o.width) / float(o.height);
    const CameraMatrices m = make_camera_matrices(
        c.camera_to_world(), c.focal_length_mm, c.sensor_width_mm, aspect, s.near_clip);
    const CameraMatrices mp = make_camera_matrices(
        cp.camera_to_world(), cp.focal_length_mm, cp.sensor_width_mm, aspect, s.near_clip);
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    f.camera.prev_world_to_camera = mp.world_to_camera;
    f.camera.prev_world_to_ndc = mp.world_to_ndc;
    f.camera.fstop = c.fstop;
    f.camera.focus_distance = c.focus_distance;
    f.camera.focal_length_mm = c.focal_length_mm;
    f.camera.sensor_width_mm = c.sensor_width_mm;
    f.camera.sensor_height_mm = c.sensor_width_mm / aspect;
    f.camera.shutter = c.shutter;
    f.camera.near_clip = s.near_clip;
    f.camera.far_clip =
        std::sqrt(float(s.world.nx) * float(s.world.nx) + float(s.world.ny) * float(s.world.ny) +
                  float(s.world.nz) * float(s.world.nz)) +
        1000.0f;
    f.attributes["posthaste:scene"] = s.name;
    f.attributes["posthaste:fps"] = float(s.fps);
}

bool has_overscan(const RenderOptions &o)
{
    return o.overscan_x > 0 || o.overscan_y > 0;
}

/// The options of an overscan render's wide frame (the data window's size, no overscan left),
/// and the factor its sensor is widened by.
RenderOptions widened(const RenderOptions &o)
{
    RenderOptions w = o;
    w.width = o.width + 2 * o.overscan_x;
    w.height = o.height + 2 * o.overscan_y;
    w.overscan_x = w.overscan_y = 0;
    return w;
}

float sensor_scale(const RenderOptions &o)
{
    return float(o.width + 2 * o.overscan_x) / float(o.width);
}

/// The wide frame's header made the overscan frame's: the display window and camera of
/// width x height, the data window around it.
void set_overscan_header(const Scene &s, int frame, const RenderOptions &o, Frame &f)
{
    fill_header(s, frame, o, f, 1.0f);
    f.data_window = {-o.overscan_x, -o.overscan_y, o.width + o.overscan_x, o.height + o.overscan_y};
}

SceneCache &cache_of(const Scene &s, std::shared_ptr<SceneCache> &local)
{
    if (s.cache) {
        return *s.cache;
    }
    local = make_scene_cache();
    return *local;
}

// Concentric mapping of [0,1)^2 onto the unit disc (Shirley & Chiu 1997).
glm::vec2 concentric_disc(float u1, float u2)
{
    const float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) {
        return glm::vec2(0.0f);
    }
    const float pi4 = shading::kPi / 4.0f;
    if (std::abs(a) > std::abs(b)) {
        return a * glm::vec2(std::cos(pi4 * b / a), std::sin(pi4 * b / a));
    }
    return b * glm::vec2(std::cos(shading::kPi / 2 - pi4 * a / b),
                         std::sin(shading::kPi / 2 - pi4 * a / b));
}

}  // namespace

const std::set<std::string> &render_pass_names()
{
    static const std::set<std::string> names = {pass::kColor,
                                                pass::kDepth,
                                                pass::kNormal,
                                                pass::kPosition,
                                                pass::kMotion,
                                                pass::kAlbedo,
                                                pass::kMaterial,
                                                pass::kTangent,
                                                pass::kId,
                                                pass::kSpecular,
                                                pass::kSpecularMotion,
                                                pass::kDiffuseMotion,
                                                pass::kSpecularDepth,
                                                pass::kShadow};
    static const std::set<std::string> with_crypto = [] {
        std::set<std::string> all = names;
        for (int k = 0; k < 8; ++k) {
            all.insert(crypto_layer(kCryptoObject, k));
            all.insert(crypto_layer(kCryptoMaterial, k));
        }
        return all;
    }();
    return with_crypto;
}

std::string crypto_layer(const char *type, int k)
{
    return std::string(type) + char('0' + k / 10) + char('0' + k % 10);
}

void validate(const RenderOptions &o)
{
    if (o.width <= 0 || o.height <= 0 || o.width > kMaxImageSide / 4 ||
        o.height > kMaxImageSide / 4) {
        throw_usage("render: expected a size in [1, ",
                    kMaxImageSide / 4,
                    "], got ",
                    o.width,
                    "x",
                    o.height);
    }
    if (o.overscan_x < 0 || o.overscan_y < 0 ||
        o.width + 2 * std::int64_t(o.overscan_x) > kMaxImageSide / 4 ||
        o.height + 2 * std::int64_t(o.overscan_y) > kMaxImageSide / 4) {
        throw_usage("render: \"overscan\": ",
                    o.overscan_x,
                    "x",
                    o.overscan_y,
                    " pixels a side around ",
                    o.width,
                    "x",
                    o.height,
                    " makes a frame over ",
                    kMaxImageSide / 4,
                    " pixels a side (or is negative)");
    }
    if (o.cryptomatte_ranks < 1 || o.cryptomatte_ranks > 16) {
        throw_usage("render: \"cryptomatte_ranks\": expected 1..16, got ", o.cryptomatte_ranks);
    }
    if (o.supersample != 1 && o.supersample != 2 && o.supersample != 4) {
        throw_usage("render: \"supersample\": expected 1, 2 or 4, got ", o.supersample);
    }
    if (o.shadow_map_size < 16 || o.shadow_map_size > 16384) {
        throw_usage("render: \"shadow_map_size\": expected [16, 16384], got ", o.shadow_map_size);
    }
    for (const std::string &p : o.passes) {
        if (!render_pass_names().count(p)) {
            std::string known;
            for (const std::string &k : render_pass_names()) {
                known += (known.empty() ? "" : ", ") + k;
            }
            throw_usage("render: unknown pass ", posthaste::quoted(p), " (have: ", known, ")");
        }
    }
}

namespace {

/// render_frame of o's size with the sensor widened by `scale` (1: the scene's camera).
Frame render_frame_at(
    const Scene &s, int frame, const RenderOptions &o, float scale, RenderStats *stats)
{
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    if (stats) {
        *stats = RenderStats{};
    }
    Frame f;
    fill_header(s, frame, o, f, scale);
    const double t = frame;
    const CameraState cam = camera_for(s, t, scale);
    auto has = [&](const char *p) { return o.passes.count(p) != 0; };

    auto t0 = Clock::now();
    const auto meshes = scene_meshes(s, cache, o.greedy_meshing);
    const Geometry g = make_geometry(s, *meshes, t, t - 1.0);
    if (stats) {
        stats->mesh_ms += ms_since(t0);
    }
    // The specular share is shaded with the colour, at its sampling.
    const bool want_specular = has(pass::kSpecular);
    const bool want_color = has(pass::kColor) || want_specular;
    const bool data = std::any_of(o.passes.begin(), o.passes.end(), [](const std::string &p) {
        return p != pass::kColor && p != pass::kSpecular;
    });
    std::unique_ptr<LightingState> ls;
    Image color, specular;
    if (want_color || has(pass::kShadow)) {  // the shadow pass reads the shadow maps
        ls = std::make_unique<LightingState>(s, cache, g, o, stats);
    }
    const bool want_crypto = o.passes.count(crypto_layer(kCryptoObject, 0)) ||
                             o.passes.count(crypto_layer(kCryptoMaterial, 0));
    // The beauty's samples at the supersampled size, once: the beauty's colour and the
    // cryptomattes' coverage (a matte's edges are the beauty's) both read them.
    const View vs =
        make_view(cam, o.width * o.supersample, o.height * o.supersample, s.near_clip, glm::vec2(0.0f));
    Visibility vis_ss;
    if (o.supersample > 1 && (want_color || want_crypto)) {
        vis_ss = visibility(g, vs, stats);
    }
    if (want_color) {
        color = fresh_image(o.width, o.height, 4);
        if (want_specular) {
            specular = fresh_image(o.width, o.height, 3);
        }
        if (o.supersample > 1) {
            t0 = Clock::now();
            shade_color(g,
                        vs,
                        vis_ss,
                        ls->lighting,
                        o.supersample,
                        color,
                        want_specular ? &specular : nullptr);
            if (stats) {
                stats->shade_ms += ms_since(t0);
            }
        }
    }
    if (!want_crypto) {
        vis_ss = Visibility{};  // its 8 bytes a sample freed before the data passes
    }
    const bool color_here = want_color && o.supersample == 1;
    auto store = [&](const char *name, Image &img) {
        if (!img.empty() && has(name)) {
            f.set(name, std::move(img));
        }
    };
    if (!data && !color_here) {
        store(pass::kColor, color);
        store(pass::kSpecular, specular);
        return f;  // no pass asked for: the header and windows alone
    }
    const View v = make_view(cam, o.width, o.height, s.near_clip, glm::vec2(0.0f));
    const Visibility vis = visibility(g, v, stats);
    if (want_crypto) {
        add_cryptomattes(s, g, o.supersample > 1 ? vis_ss : vis, o, f);
    }
    shade_passes(s, g, v, vis, o, ls.get(), color_here, want_specular, color, specular, f, stats);
    return f;
}

Frame render_truth_at(const Scene &s,
                      int frame,
                      const RenderOptions &o,
                      const TruthOptions &truth,
                      float scale)
{
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    Frame f;
    fill_header(s, frame, o, f, scale);
    const int n = truth.samples;
    // Time strata are a hashed permutation of the sample index, so that the joint (time, lens)
    // pattern is stratified in each dimension without correlating them.
    std::vector<int> perm(static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
        perm[std::size_t(i)] = i;
    }
    for (int i = n - 1; i > 0; --i) {
        const int j = int(hash4(std::uint32_t(i), std::uint32_t(frame), 17u, truth.seed) %
                          std::uint32_t(i + 1));
        std::swap(perm[std::size_t(i)], perm[std::size_t(j)]);
    }
    const std::uint32_t scramble = hash4(std::uint32_t(frame), 3u, 5u, truth.seed);
    Image acc(o.width, o.height, 4);
    Image sample = Image::uninitialized(o.width, o.height, 4);
    const CameraState centre = camera_for(s, frame, scale);
    for (int i = 0; i < n; ++i) {
        double t = frame;
        if (truth.motion) {
            const float u =
                (float(truth.dof ? perm[std::size_t(i)] : i) + hash_unit(i, frame, 0, truth.seed)) /
                float(n);
            t = frame + (double(u) - 0.5) * double(centre.shutter);
        }
        const CameraState cam = camera_for(s, t, scale);
        glm::vec2 lens(0.0f);
        if (truth.dof) {
            const float u1 = (float(i) + hash_unit(i, frame, 1, truth.seed)) / float(n);
            const float u2 =
                float((std::uint32_t(posthaste::radical_inverse_base2(std::uint32_t(i)) *
                                     16777216.0f) ^
                       (scramble >> 8)) &
                      0xffffffu) /
                16777216.0f;
            const float radius = 0.5f * cam.focal_length_mm / cam.fstop * 1e-3f;  // metres
            lens = concentric_disc(u1, u2) * radius;
        }
        render_color(s, cache, t, lens, cam, o, sample, nullptr);
        parallel_for(0, o.height, [&](int y) {
            float *a = acc.pixel(0, y);
            const float *b = sample.pixel(0, y);
            for (int k = 0; k < o.width * 4; ++k) {
                a[k] += b[k];
            }
        });
    }
    const float inv = 1.0f / float(n);
    parallel_for(0, o.height, [&](int y) {
        float *a = acc.pixel(0, y);
        for (int k = 0; k < o.width * 4; ++k) {
            a[k] *= inv;
        }
    });
    f.set(pass::kColor, std::move(acc));
    return f;
}

}  // namespace

Frame render_frame(const Scene &s, int frame, const RenderOptions &o, RenderStats *stats)
{
    validate(o);
    if (!has_overscan(o)) {
        return render_frame_at(s, frame, o, 1.0f, stats);
    }
    Frame f = render_frame_at(s, frame, widened(o), sensor_scale(o), stats);
    set_overscan_header(s, frame, o, f);
    return f;
}

Frame render_truth(const Scene &s, int frame, const RenderOptions &o, const TruthOptions &truth)
{
    validate(o);
    if (truth.samples < 1 || truth.samples > 1 << 20) {
        throw_usage("render truth: \"samples\": expected [1, 1048576], got ", truth.samples);
    }
    if (!has_overscan(o)) {
        return render_truth_at(s, frame, o, truth, 1.0f);
    }
    Frame f = render_truth_at(s, frame, widened(o), truth, sensor_scale(o));
    set_overscan_header(s, frame, o, f);
    return f;
}

}  // namespace posthaste::raster
