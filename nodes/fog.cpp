// nodes/fog.cpp: fog and atmosphere over a frame, from depth and the camera matrices.
// Models: linear (start, end), exp and exp2 (density), exponential height fog with the exact
// line integral (src/shading/fog/height_fog.h), and a physically based atmosphere after Hillaire
// 2020 (src/shading/atmosphere/atmosphere.h: transmittance, multi-scattering and sky-view LUTs, an
// aerial perspective froxel volume), plus `atmosphere_raymarch`, the per-pixel reference it is
// judged by. Composite: RGB = RGB * T + inscatter; alpha untouched. Sky pixels (depth +inf) get the
// fog color (linear, exp, exp2, height with sky=fog) or the sky radiance (atmosphere). Departure:
// NaN depths are left untouched and negative depths count as 0.

#include <OpenImageIO/paramlist.h>

#include <array>
#include <cmath>
#include <limits>
#include <mutex>

#include "core/sanitize.h"
#include "graph/mask.h"
#include "nodes/node.h"
#include "nodes/sun_params.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/atmosphere/scene_sky.h"
#include "shading/camera_rays.h"
#include "shading/fog/filtered_edges.h"
#include "shading/fog/height_fog.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kModel =
    ParamSpec::choice("model", "linear|exp|exp2|height|atmosphere|atmosphere_raymarch", "height")
        .doc("Fog model; atmosphere_raymarch is the slow per-pixel reference of atmosphere.");
constexpr ParamSpec kColor = ParamSpec::vec3("color", 0.6, 0.7, 0.8)
                                 .at_least(0.0)
                                 .doc("Fog radiance, scene-linear (linear, exp, exp2, height).")
                                 .only_when("model", "linear|exp|exp2|height");
constexpr ParamSpec kStart =
    ParamSpec::real("start", 0.0)
        .at_least(0.0)
        .units("scene units")
        .doc("Linear: distance where fog begins; height: no fog closer than this.")
        .only_when("model", "linear|height");
constexpr ParamSpec kEnd = ParamSpec::real("end", 200.0)
                               .at_least(0.0)
                               .units("scene units")
                               .doc("Linear: distance of full fog.")
                               .only_when("model", "linear");
constexpr ParamSpec kDensity =
    ParamSpec::real("density", 0.01)
        .at_least(0.0)
        .units("1/unit")
        .doc("exp, exp2: density; height: extinction at base_height. 0 leaves the frame untouched.")
        .only_when("model", "exp|exp2|height");
constexpr ParamSpec kFalloff =
    ParamSpec::real("falloff", 0.1)
        .at_least(0.0)
        .units("1/unit")
        .doc("Height: density falls by exp(-falloff) per unit of height above base_height.")
        .only_when("model", "height");
constexpr ParamSpec kBaseHeight =
    ParamSpec::real("base_height", 0.0)
        .units("scene units")
        .doc("Height: the height along `up` where the density equals `density`.")
        .only_when("model", "height");
constexpr ParamSpec kSky =
    ParamSpec::choice("sky", "fog|ray", "fog")
        .doc("Height: sky pixels get the fog color (fog) or the fog of the infinite ray (ray).")
        .only_when("model", "height");
constexpr ParamSpec kSunDirection =
    ParamSpec::vec3("sun_direction", 0.4, 0.75, 0.3)
        .doc("World direction towards the sun.")
        .from_header("posthaste:sunDirection")
        .only_when("model", "height|atmosphere|atmosphere_raymarch");
constexpr ParamSpec kUp =
    ParamSpec::vec3("up", 0.0, 1.0, 0.0)
        .doc(
            "World direction of up, for heights and the sun's elevation: +Y (the rasterizer's, "
            "Maya's, Houdini's) or [0, 0, 1] for a Z-up world (Blender's, 3ds Max's, Unreal's).")
        .only_when("model", "height|atmosphere|atmosphere_raymarch");
constexpr ParamSpec kSunColor =
    ParamSpec::vec3("sun_color", 0.0, 0.0, 0.0)
        .at_least(0.0)
        .doc("Height: radiance scale of the sun in-scatter lobe (0: no lobe).")
        .only_when("model", "height");
constexpr ParamSpec kSunG = ParamSpec::real("sun_g", 0.7)
                                .range(-0.99, 0.99)
                                .doc("Height: Henyey-Greenstein asymmetry of the sun lobe.")
                                .only_when("model", "height");
constexpr ParamSpec kIlluminance = ParamSpec::vec3("sun_illuminance", 1.0, 1.0, 1.0)
                                       .range(0.0, 1e6)  // 1e38 made the sun's disc infinite
                                       .doc("Atmosphere: sun illuminance.")
                                       .from_header("posthaste:sunIlluminance")
                                       .only_when("model", "atmosphere|atmosphere_raymarch");
constexpr ParamSpec kMetresPerUnit = ParamSpec::real("metres_per_unit", 1.0)
                                         .range(1e-6, 1e6)
                                         .doc("Atmosphere: scene units to metres.")
                                         .only_when("model", "atmosphere|atmosphere_raymarch");
constexpr ParamSpec kGroundAltitude = ParamSpec::real("ground_altitude", 0.0)
                                          .range(0.0, 90000.0)
                                          .units("m")
                                          .doc("Atmosphere: altitude of world y = 0.")
                                          .only_when("model", "atmosphere|atmosphere_raymarch");
constexpr ParamSpec kFroxels =
    ParamSpec::integer("froxels", 32)
        .range(2, 256)
        .doc("Atmosphere: aerial-perspective volume resolution across the screen (per axis).")
        .only_when("model", "atmosphere");
constexpr ParamSpec kSlices = ParamSpec::integer("slices", 32)
                                  .range(2, 256)
                                  .doc("Atmosphere: aerial-perspective depth slices.")
                                  .only_when("model", "atmosphere");
constexpr ParamSpec kMaxDistance =
    ParamSpec::real("max_distance", 32000.0)
        .range(1.0, 1e9)
        .units("scene units")
        .doc("Atmosphere: depth range of the aerial-perspective volume.")
        .only_when("model", "atmosphere");
constexpr ParamSpec kSunDisc = ParamSpec::boolean("sun_disc", true)
                                   .doc("Atmosphere: draw the sun disc in the sky.")
                                   .only_when("model", "atmosphere|atmosphere_raymarch");
constexpr ParamSpec kSteps = ParamSpec::integer("steps", 64)
                                 .range(1, 4096)
                                 .doc("atmosphere_raymarch: integration steps per pixel.")
                                 .only_when("model", "atmosphere_raymarch");
constexpr ParamSpec kPixelFilter =
    ParamSpec::real("pixel_filter", 0.0)
        .range(0.0, 1.5)
        .units("px")
        .doc(
            "The renderer's pixel filter, as a Gaussian's sigma, where the colour is filtered at "
            "depth edges and the depth is not (a production render): each edge pixel is fogged "
            "as the mix of its neighbours' distances (Cycles' default Blackman-Harris 1.5 px "
            "measures best at 0.6). 0: passes of one sample a pixel (the rasterizer's).");
constexpr ParamSpec kParams[] = {
    kModel,       kColor,         kStart,          kEnd,      kDensity,     kFalloff,
    kBaseHeight,  kSky,           kSunDirection,   kUp,       kSunColor,    kSunG,
    kIlluminance, kMetresPerUnit, kGroundAltitude, kFroxels,  kSlices,      kMaxDistance,
    kSunDisc,     kSteps,         kPixelFilter,    kMaskPass, kMaskChannel, kMaskInvert};
constexpr PortSpec kInputs[] = {{"image", "color,depth", false, "Frame with color and depth."},
                                kMaskPort};

enum Model { Linear, Exp, Exp2, Height, Atmo, AtmoRayMarch };

/// The rotation taking the unit vector along `up` to +Y (the identity for +Y itself): about the
/// axis up x Y by the angle between them, or half a turn about X for -Y.
constexpr Binding<shading::HeightFog> kHeightFields[] = {
    bind<&shading::HeightFog::density>(kDensity),
    bind<&shading::HeightFog::falloff>(kFalloff),
    bind<&shading::HeightFog::base_height>(kBaseHeight),
    bind<&shading::HeightFog::start_distance>(kStart),
    bind<&shading::HeightFog::color>(kColor),
    bind<&shading::HeightFog::sun_color>(kSunColor),
    bind<&shading::HeightFog::sun_g>(kSunG),
    bind<&shading::HeightFog::opaque_sky>(kSky, "fog"),
};
constexpr Binding<shading::AtmosphereParams> kAtmosphereFields[] = {
    bind<&shading::AtmosphereParams::metres_per_unit>(kMetresPerUnit),
    bind<&shading::AtmosphereParams::ground_altitude_m>(kGroundAltitude),
};
constexpr Binding<shading::AerialPerspectiveSettings> kFroxelFields[] = {
    bind<&shading::AerialPerspectiveSettings::width>(kFroxels),
    bind<&shading::AerialPerspectiveSettings::slices>(kSlices),
    bind<&shading::AerialPerspectiveSettings::max_distance>(kMaxDistance),
};

glm::mat3 rotation_to_y_up(glm::vec3 up, const std::string &who)
{
    const float len = glm::length(up);
    if (!(len > 0.0f) || !std::isfinite(len)) {
        throw_runtime(who, ": up must be a non-zero finite vector");
    }
    up /= len;
    const glm::vec3 y(0.0f, 1.0f, 0.0f);
    if (up == y) {
        return glm::mat3(1.0f);
    }
    const float c = glm::dot(up, y);
    if (c < -0.999999f) {
        return glm::mat3(glm::vec3(1, 0, 0), glm::vec3(0, -1, 0), glm::vec3(0, 0, -1));
    }
    // Rodrigues: R = I + [k]x + [k]x^2 / (1 + c), k = up x y (|k| = sin).
    const glm::vec3 k = glm::cross(up, y);
    const glm::mat3 kx(glm::vec3(0.0f, k.z, -k.y),
                       glm::vec3(-k.z, 0.0f, k.x),
                       glm::vec3(k.y, -k.x, 0.0f));  // columns
    return glm::mat3(1.0f) + kx + kx * kx * (1.0f / (1.0f + c));
}

glm::vec3 vec3_of(const std::vector<double> &v)
{
    return glm::vec3(float(v[0]), float(v[1]), float(v[2]));
}

/// Atmospheres built so far, keyed by sun direction and illuminance (LUTs are computed once per
/// parameter set and reused across frames).
struct AtmosphereCache {
    std::unique_ptr<std::mutex> mutex = std::make_unique<std::mutex>();
    struct Built {
        std::array<float, 6> key;
        std::shared_ptr<const shading::Atmosphere> atmosphere;
        std::shared_ptr<const shading::SceneSky> sky;  // the lit ground below the horizon
    };
    mutable std::vector<Built> built;
};

AtmosphereCache::Built atmosphere_for(NodeContext &ctx,
                                      const glm::vec3 &sun_dir,
                                      const glm::vec3 &illuminance)
{
    const AtmosphereCache &cache =
        ctx.state().get_or_create<AtmosphereCache>([] { return AtmosphereCache{}; });
    const std::array<float, 6> key = {
        sun_dir.x, sun_dir.y, sun_dir.z, illuminance.x, illuminance.y, illuminance.z};
    std::lock_guard lock(*cache.mutex);
    for (const AtmosphereCache::Built &b : cache.built) {
        if (b.key == key) {
            return b;
        }
    }
    shading::AtmosphereParams p = fill(ctx.params(), kAtmosphereFields);
    p.sun_direction = sun_dir;
    p.sun_illuminance = illuminance;
    AtmosphereCache::Built b;
    b.key = key;
    b.atmosphere = std::make_shared<const shading::Atmosphere>(p);
    b.sky = std::make_shared<const shading::SceneSky>(*b.atmosphere);
    if (cache.built.size() >= 8) {
        cache.built.erase(cache.built.begin());
    }
    cache.built.push_back(b);
    return b;
}

/// linear / exp / exp2: transmittance from the distance along the ray.
void apply_classic(Model model,
                   const NodeContext &ctx,
                   const shading::CameraRays &rays,
                   const Image &depth,
                   Image &color)
{
    const glm::vec3 fog = vec3_of(ctx.get_vec(kColor));
    const float start = ctx.get_float(kStart), end = ctx.get_float(kEnd);
    const float density = ctx.get_float(kDensity);
    const int nch = color.channels();
    const float inv_w = 1.0f / float(color.width()), inv_h = 1.0f / float(color.height());
    parallel_for_tiles(color.bounds(), [&](const Rect &t) {
        for (int y = t.y0; y < t.y1; ++y) {
            for (int x = t.x0; x < t.x1; ++x) {
                const float z = depth.at(x, y, 0);
                if (std::isnan(z)) {
                    continue;
                }
                float transmittance = 0.0f;
                if (!std::isinf(z)) {
                    const glm::vec3 r = rays.depth_ray((x + 0.5f) * inv_w, (y + 0.5f) * inv_h);
                    const float d = std::max(z, 0.0f) * glm::length(r);
                    transmittance = model == Linear ? shading::linear_fog_factor(d, start, end)
                                    : model == Exp  ? shading::exp_fog_factor(d, density)
                                                    : shading::exp2_fog_factor(d, density);
                }
                float *p = color.pixel(x, y);
                for (int c = 0; c < std::min(nch, 3); ++c) {
                    p[c] = p[c] * transmittance + (1.0f - transmittance) * fog[c];
                }
            }
        }
    });
}

void execute(NodeContext &ctx)
{
    const Frame &in = ctx.input("image");
    const Pass &color_pass = in.pass(pass::kColor, ctx.where());
    // Non-finite input never reaches the output: NaN/Inf color reads as 0, NaN/-inf depth as 0
    // (no fog: the pixel is left as it is); no copy when everything is finite.
    Image color_storage, depth_storage;
    const Image &color_in = finite_view(*color_pass.image, 0.0f, color_storage);
    const Image &depth_in = finite_view(
        in.image(pass::kDepth, ctx.where()), 0.0f, depth_storage, /*allow_positive_inf=*/true);
    const Model model = Model(ctx.get_choice(kModel));
    const float density = ctx.get_float(kDensity);
    if ((model == Exp || model == Exp2 || model == Height) && density == 0.0f) {
        return;  // no fog: the output shares the input's color, bit for bit
    }
    if (model == Linear && ctx.get_float(kEnd) <= ctx.get_float(kStart) &&
        ctx.get_float(kStart) >= std::numeric_limits<float>::max()) {
        return;
    }
    if (color_pass.image->channels() < 3) {
        throw_runtime(ctx.where(),
                      ": color pass has ",
                      color_pass.image->channels(),
                      " channels; fog needs RGB");
    }
    const std::string who = ctx.where();
    const Camera camera = in.pixel_camera();  // NDC spans the data window
    // The models measure height along +Y: a world whose up is another axis is turned so that
    // its up is +Y, the camera and the sun with it (identity for the default).
    const glm::mat3 to_y_up = rotation_to_y_up(vec3_of(ctx.get_vec(kUp)), who);
    const glm::mat4 from_y_up = glm::mat4(glm::transpose(to_y_up));
    const glm::mat4 w2c = camera.require_world_to_camera(who) * from_y_up;
    const glm::mat4 w2ndc = camera.require_world_to_ndc(who) * from_y_up;
    const shading::CameraRays rays(w2c, w2ndc);

    // Negative depths count as 0 (a copy is made only when there are some). The height fog and
    // froxel kernels already treat depth <= 0 as "no fog", so they skip the scan.
    const Image *depth = &depth_in;
    Image sanitized;
    const bool scan = model != Height && model != Atmo;
    for (std::size_t i = 0; scan && i < depth_in.value_count(); ++i) {
        if (depth_in.data()[i] < 0.0f) {
            sanitized = depth_in;
            for (std::size_t j = 0; j < sanitized.value_count(); ++j) {
                sanitized.data()[j] = std::max(sanitized.data()[j], 0.0f);  // NaN stays NaN
            }
            depth = &sanitized;
            break;
        }
    }

    // The sun's direction: for the atmospheres, and for the height model's sun lobe where it
    // draws one (sun_color 0 draws none: the node notes no default for a direction it does not
    // use). One the graph gives is checked whatever the model does with it.
    const bool uses_sun =
        model == Atmo || model == AtmoRayMarch || ctx.params().given(kSunDirection) ||
        (model == Height && fill(ctx.params(), kHeightFields).sun_color != glm::vec3(0.0f));
    const glm::vec3 sun_dir = uses_sun
                                  ? to_y_up * glm::normalize(sun_direction(ctx, kSunDirection, in))
                                  : glm::vec3(0.0f, 1.0f, 0.0f);

    // The model over a colour image. The height fog and atmosphere kernels read the input and
    // write the output in one sweep; the other models work on a copy.
    auto fogged = [&](const Image &source) {
        Image out = model == Height || model == Atmo
                        ? Image::uninitialized(source.width(), source.height(), source.channels())
                        : source;
        switch (model) {
            case Linear:
            case Exp:
            case Exp2:
                apply_classic(model, ctx, rays, *depth, out);
                break;
            case Height: {
                // sky "fog": sky pixels get the fog's radiance (colour plus the sun lobe), folded
                // into the same sweep.
                shading::HeightFog fog = fill(ctx.params(), kHeightFields);
                fog.sun_direction = sun_dir;
                shading::apply_height_fog(fog, rays, *depth, source, out);
                break;
            }
            case Atmo:
            case AtmoRayMarch: {
                const glm::vec3 illuminance =
                    param_value<glm::vec3>(ctx, kIlluminance, HeaderSource::of(in));
                const AtmosphereCache::Built built = atmosphere_for(ctx, sun_dir, illuminance);
                const auto &atmosphere = built.atmosphere;
                const bool disc = ctx.get_bool(kSunDisc);
                if (model == Atmo) {
                    shading::AerialPerspectiveSettings s = fill(ctx.params(), kFroxelFields);
                    s.height = s.width;  // square froxels in NDC
                    // Froxels only as deep as this frame's geometry reaches.
                    const shading::AerialPerspective ap(*atmosphere, w2c, w2ndc, s, *depth);
                    shading::apply_atmosphere(
                        *atmosphere, atmosphere->cached_sky_view(), ap, *depth, source, out, disc);
                    // Sky pixels below the horizon see the lit ground (as the rasterizer draws it).
                    // Rows in bands; a pixel's ray points down when its depth-1 vector does, so the
                    // unit direction is only made for those.
                    const int nch = out.channels();
                    const float inv_w = 1.0f / float(out.width()),
                                inv_h = 1.0f / float(out.height());
                    parallel_for(0, out.height(), [&](int y) {
                        const float v = (y + 0.5f) * inv_h;
                        const glm::vec3 r0 = rays.depth_ray(0.0f, v);
                        const glm::vec3 dr = rays.depth_ray(1.0f, v) - r0;
                        const float *z = depth->pixel(0, y);
                        for (int x = 0; x < out.width(); ++x) {
                            const float u = (x + 0.5f) * inv_w;
                            if (!(z[x] == std::numeric_limits<float>::infinity()) ||
                                !(r0.y + u * dr.y < 0.0f)) {
                                continue;
                            }
                            const glm::vec3 dir = rays.direction(u, v);
                            if (dir.y >= 0.0f) {
                                continue;
                            }
                            const glm::vec3 g = built.sky->ground(dir, rays.position());
                            float *p = out.pixel(x, y);
                            for (int k = 0; k < std::min(nch, 3); ++k) {
                                p[k] += g[k];
                            }
                        }
                    });
                    break;
                }
                const int steps = ctx.get_int(kSteps);
                const int nch = out.channels();
                const float inv_w = 1.0f / float(out.width()), inv_h = 1.0f / float(out.height());
                parallel_for_tiles(out.bounds(), [&](const Rect &t) {
                    for (int y = t.y0; y < t.y1; ++y) {
                        for (int x = t.x0; x < t.x1; ++x) {
                            const float z = depth->at(x, y, 0);
                            if (std::isnan(z)) {
                                continue;
                            }
                            const float u = (x + 0.5f) * inv_w, v = (y + 0.5f) * inv_h;
                            const glm::vec3 dir = rays.direction(u, v);
                            float *p = out.pixel(x, y);
                            if (std::isinf(z)) {
                                const glm::vec3 sky =
                                    built.sky->radiance(dir, rays.position(), disc);
                                for (int k = 0; k < std::min(nch, 3); ++k) {
                                    p[k] = sky[k];
                                }
                                continue;
                            }
                            const float dist = z * glm::length(rays.depth_ray(u, v));
                            const shading::ScatteringResult r =
                                atmosphere->ray_march(rays.position(), dir, dist, steps);
                            for (int k = 0; k < std::min(nch, 3); ++k) {
                                p[k] = p[k] * r.transmittance[k] + r.inscatter[k];
                            }
                        }
                    }
                });
                break;
            }
        }
        return out;
    };
    Image out = fogged(color_in);
    if (const float sigma = ctx.get_float(kPixelFilter); sigma > 0.0f) {
        // Each pixel's transmittance and in-scattering: the model over colours 1 and 0.
        Image ones(color_in.width(), color_in.height(), color_in.channels());
        ones.fill(1.0f);
        const Image inscatter =
            fogged(Image(color_in.width(), color_in.height(), color_in.channels()));
        Image transmittance = fogged(ones);
        const std::size_t row = std::size_t(ones.width()) * std::size_t(ones.channels());
        parallel_for(0, ones.height(), [&](int y) {  // a full frame: rows on every thread
            float *t = transmittance.data() + std::size_t(y) * row;
            const float *i = inscatter.data() + std::size_t(y) * row;
            for (std::size_t k = 0; k < row; ++k) {
                t[k] -= i[k];
            }
        });
        shading::correct_filtered_edges(color_in, transmittance, inscatter, *depth, sigma, out);
    }
    ctx.output().set(pass::kColor,
                     std::make_shared<const Image>(std::move(out)),
                     color_pass.channels,
                     color_pass.storage);
}

void check(CheckContext &ctx)
{
    const Model model = Model(ctx.params.get_choice(kModel));
    if (model == Linear && ctx.params.get_real(kEnd) < ctx.params.get_real(kStart)) {
        throw_param_expected(ctx,
                             kEnd,
                             str_cat("at least start (", ctx.params.get_real(kStart), ")"),
                             ctx.params.get_real(kEnd));
    }
}

void plan(PlanContext &ctx)
{
    // The world-space models place each pixel through the camera.
    ctx.inputs[0].camera = true;
}

}  // namespace

extern const NodeType kFog{{"fog",
                            "Fog: linear, exp, exp2, exact height fog, or a physically "
                            "based atmosphere (Hillaire 2020).",
                            kInputs,
                            kParams,
                            "",
                            /*sink=*/false,
                            /*keeps_specular=*/false,
                            /*maskable=*/true},
                           &execute,
                           &plan,
                           &check,
                           nullptr,
                           [](std::vector<std::string> &problems) {
                               audit(kFog, kHeightFields, problems);
                               audit(kFog, kAtmosphereFields, problems);
                               audit(kFog, kFroxelFields, problems);
                           }};

}  // namespace posthaste::nodes
