#include "raster/render.h"

#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
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

// Where the specular share of a pixel moves (its specular_motion), as the point whose motion
// depth_motion then measures. The renderer's specular reflects only distant light (the sun and
// the sky), so on a ball of radius R its image is the convex mirror's virtual image of a source
// at infinity: the focal point R/2 behind the surface along the view ray (paraxial), carried by
// the ball's translation and not by its spin (a rolling ball's highlight moves with its centre;
// its silhouette does too, so the two blurs agree on its extent). On a flat face the image is a
// point at infinity, which moves with the camera's rotation alone, but the face's edges move with
// the face, and two independent blurs cannot keep the one inside the other: flat faces give the
// face's own motion (measured on thin_sky f4: 0.0077 RMSE this way, 0.0112 the other).
// specular_image is that point (the surface itself on flat faces); its depth is specular_depth,
// where a thin lens focuses the highlight.
glm::vec3 specular_image(const Hit &h, const glm::vec3 &d)
{
    if (!h.curved) {
        return h.p;
    }
    const float radius = glm::length(h.p - h.origin);
    return h.p + glm::normalize(d) * (0.5f * radius);
}

void specular_point(int i, const Hit &h, const glm::vec3 &d, DepthMotionRow &row)
{
    if (!h.curved) {
        row.surface(i, h.p, h.p_prev);
        return;
    }
    const glm::vec3 q = specular_image(h, d);
    row.surface(i, q, q - (h.origin - h.origin_prev));
}

void fill_header(const Scene &s, int frame, const RenderOptions &o, Frame &f)
{
    f.number = frame;
    f.set_size(o.width, o.height);
    const CameraState c = s.camera_at(frame), cp = s.camera_at(frame - 1);
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

Frame render_frame(const Scene &s, int frame, const RenderOptions &o, RenderStats *stats)
{
    validate(o);
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    if (stats) {
        *stats = RenderStats{};
    }
    Frame f;
    fill_header(s, frame, o, f);
    const double t = frame;
    const CameraState cam = s.camera_at(t);
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
    if (want_color) {
        color = fresh_image(o.width, o.height, 4);
        if (want_specular) {
            specular = fresh_image(o.width, o.height, 3);
        }
        if (o.supersample > 1) {
            // The beauty gets its own visibility at the supersampled size.
            const View vs = make_view(cam,
                                      o.width * o.supersample,
                                      o.height * o.supersample,
                                      s.near_clip,
                                      glm::vec2(0.0f));
            const Visibility vis_ss = visibility(g, vs, stats);
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
    if (o.passes.count(crypto_layer(kCryptoObject, 0)) ||
        o.passes.count(crypto_layer(kCryptoMaterial, 0))) {
        // Coverage from the beauty's own samples: a matte's edges are the beauty's.
        Visibility vis_ss;
        if (o.supersample > 1) {
            vis_ss = visibility(g,
                                make_view(cam,
                                          o.width * o.supersample,
                                          o.height * o.supersample,
                                          s.near_clip,
                                          glm::vec2(0.0f)),
                                stats);
        }
        add_cryptomattes(s, g, o.supersample > 1 ? vis_ss : vis, o, f);
    }
    t0 = Clock::now();
    std::optional<MaterialTable> own_materials;
    if (!ls) {
        own_materials.emplace(s);
    }
    const MaterialTable &mats = ls ? ls->materials : *own_materials;
    const glm::mat4 prev_ndc = *f.camera.prev_world_to_ndc;
    const glm::mat4 cur_ndc = *f.camera.world_to_ndc;

    auto make = [&](const char *name, int channels) {
        return has(name) ? fresh_image(o.width, o.height, channels) : Image();
    };
    Image depth = make(pass::kDepth, 1), normal = make(pass::kNormal, 3);
    Image position = make(pass::kPosition, 3), motion = make(pass::kMotion, 2);
    Image albedo = make(pass::kAlbedo, 3), material = make(pass::kMaterial, 3);
    Image tangent = make(pass::kTangent, 3), id = make(pass::kId, 1);
    Image spec_depth = make(pass::kSpecularDepth, 1), shadow = make(pass::kShadow, 1);
    Image spec_motion = make(pass::kSpecularMotion, 2),
          diffuse_motion = make(pass::kDiffuseMotion, 2);
    const glm::vec4 zrow(v.world_to_camera[0][2],
                         v.world_to_camera[1][2],
                         v.world_to_camera[2][2],
                         v.world_to_camera[3][2]);
    const DepthMotionParams dmp{zrow, cur_ndc, prev_ndc, o.width, o.height};

    parallel_for_tiles(Rect{0, 0, o.width, o.height}, [&](const Rect &tile) {
        SurfaceHitter hitter(g, v.origin);
        SkyCache sky(s);
        const int n = tile.x1 - tile.x0;
        std::optional<ColorRow> row;
        if (color_here) {
            row.emplace(ls->lighting, sky, n, want_specular);
        }
        Image no_color;  // supersampled colour was shaded already: leave it alone
        RowBuffer color_row(color_here ? color : no_color, n), depth_row(depth, n);
        RowBuffer specular_row(color_here ? specular : no_color, n);
        RowBuffer spec_motion_row(spec_motion, n);
        DepthMotionRow sm(spec_motion_row.active() ? n : 0);
        RowBuffer diffuse_motion_row(diffuse_motion, n), spec_depth_row(spec_depth, n);
        RowBuffer shadow_row(shadow, n);
        DepthMotionRow dfm(diffuse_motion_row.active() ? n : 0);
        RowBuffer normal_row(normal, n);
        RowBuffer position_row(position, n), motion_row(motion, n), albedo_row(albedo, n);
        RowBuffer material_row(material, n), tangent_row(tangent, n), id_row(id, n);
        const bool depth_motion_here = depth_row.active() || motion_row.active();
        DepthMotionRow dm(depth_motion_here ? n : 0);
        for (int y = tile.y0; y < tile.y1; ++y) {
            const std::uint32_t *ids = &vis.ids[std::size_t(y) * std::size_t(o.width)];
            for (int i = 0; i < n; ++i) {
                const int x = tile.x0 + i;
                const std::uint32_t tid = ids[x];
                const glm::vec3 d = v.ray_dir(float(x) + 0.5f, float(y) + 0.5f);
                auto put3 = [&](RowBuffer &b, const glm::vec3 &c) {
                    if (b.active()) {
                        float *p = b.at(i);
                        p[0] = c.x;
                        p[1] = c.y;
                        p[2] = c.z;
                    }
                };
                if (tid == kNoTriangle) {
                    if (color_here) {
                        row->add_sky(i, glm::normalize(d));
                    }
                    if (depth_motion_here) {
                        dm.background(i, d);
                    }
                    if (spec_motion_row.active()) {
                        sm.background(i, d);
                    }
                    if (diffuse_motion_row.active()) {
                        dfm.background(i, d);
                    }
                    if (spec_depth_row.active()) {
                        *spec_depth_row.at(i) = std::numeric_limits<float>::infinity();
                    }
                    put3(normal_row, glm::vec3(0.0f));
                    put3(position_row, glm::vec3(0.0f));
                    put3(albedo_row, glm::vec3(0.0f));
                    put3(material_row, glm::vec3(0.0f));
                    put3(tangent_row, glm::vec3(0.0f));
                    if (id_row.active()) {
                        *id_row.at(i) = 0.0f;
                    }
                    if (shadow_row.active()) {
                        *shadow_row.at(i) = 0.0f;
                    }
                    continue;
                }
                const Hit h = hitter.hit(tid, d);
                if (color_here) {
                    row->add_surface(i, h, glm::normalize(d));
                }
                if (depth_motion_here) {
                    dm.surface(i, h.p, h.p_prev);
                }
                if (spec_motion_row.active()) {
                    specular_point(i, h, d, sm);
                }
                if (spec_depth_row.active()) {
                    *spec_depth_row.at(i) = glm::dot(zrow, glm::vec4(specular_image(h, d), 1.0f));
                }
                if (diffuse_motion_row.active()) {
                    // Every object has one material: its shading moves with its shape, which a
                    // ball's spin (and rolling) does not change; other shapes do not turn.
                    dfm.surface(i, h.p, h.curved ? h.p - (h.origin - h.origin_prev) : h.p_prev);
                }
                const Material &m = mats.m[h.material];
                put3(normal_row, h.n);
                put3(position_row, h.p);
                put3(albedo_row, m.albedo);
                put3(material_row, glm::vec3(m.roughness, m.metallic, m.anisotropy));
                put3(tangent_row, h.t);
                if (id_row.active()) {
                    *id_row.at(i) = float(h.material);
                }
                if (shadow_row.active()) {
                    // The side the camera sees, as shade() lights it.
                    const glm::vec3 nv = glm::dot(h.n, d) > 0.0f ? -h.n : h.n;
                    *shadow_row.at(i) = sun_visibility(ls->lighting, h.p, nv);
                }
            }
            if (depth_motion_here) {
                depth_motion(dm,
                             n,
                             dmp,
                             depth_row.active() ? depth_row.at(0) : nullptr,
                             motion_row.active() ? motion_row.at(0) : nullptr);
            }
            if (spec_motion_row.active()) {
                depth_motion(sm, n, dmp, nullptr, spec_motion_row.at(0));
            }
            if (diffuse_motion_row.active()) {
                depth_motion(dfm, n, dmp, nullptr, diffuse_motion_row.at(0));
            }
            if (color_here) {
                const std::vector<glm::vec3> &c = row->finish();
                for (int i = 0; i < n; ++i) {
                    float *p = color_row.at(i);
                    p[0] = c[std::size_t(i)].x;
                    p[1] = c[std::size_t(i)].y;
                    p[2] = c[std::size_t(i)].z;
                    p[3] = 1.0f;
                }
                if (specular_row.active()) {
                    for (int i = 0; i < n; ++i) {
                        float *p = specular_row.at(i);
                        const glm::vec3 &sp = row->specular()[std::size_t(i)];
                        p[0] = sp.x;
                        p[1] = sp.y;
                        p[2] = sp.z;
                    }
                }
            }
            for (RowBuffer *b : {&color_row,
                                 &depth_row,
                                 &normal_row,
                                 &position_row,
                                 &motion_row,
                                 &albedo_row,
                                 &material_row,
                                 &tangent_row,
                                 &id_row,
                                 &specular_row,
                                 &spec_motion_row,
                                 &diffuse_motion_row,
                                 &spec_depth_row,
                                 &shadow_row}) {
                b->write(tile.x0, y);
            }
        }
        stream_fence();
    });
    if (stats) {
        stats->shade_ms += ms_since(t0);
    }
    store(pass::kColor, color);
    store(pass::kSpecular, specular);
    store(pass::kSpecularMotion, spec_motion);
    store(pass::kDiffuseMotion, diffuse_motion);
    store(pass::kSpecularDepth, spec_depth);
    store(pass::kShadow, shadow);
    store(pass::kDepth, depth);
    store(pass::kNormal, normal);
    store(pass::kPosition, position);
    store(pass::kMotion, motion);
    store(pass::kAlbedo, albedo);
    store(pass::kMaterial, material);
    store(pass::kTangent, tangent);
    store(pass::kId, id);
    return f;
}

Frame render_truth(const Scene &s, int frame, const RenderOptions &o, const TruthOptions &truth)
{
    validate(o);
    if (truth.samples < 1 || truth.samples > 1 << 20) {
        throw_usage("render truth: \"samples\": expected [1, 1048576], got ", truth.samples);
    }
    std::shared_ptr<SceneCache> local;
    SceneCache &cache = cache_of(s, local);
    Frame f;
    fill_header(s, frame, o, f);
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
    const CameraState centre = s.camera_at(frame);
    for (int i = 0; i < n; ++i) {
        double t = frame;
        if (truth.motion) {
            const float u =
                (float(truth.dof ? perm[std::size_t(i)] : i) + hash_unit(i, frame, 0, truth.seed)) /
                float(n);
            t = frame + (double(u) - 0.5) * double(centre.shutter);
        }
        const CameraState cam = s.camera_at(t);
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

}  // namespace posthaste::raster
