#pragma once
// The colour of a row of surfaces (internal to src/raster/render*.cpp): ColorRow collects a
// row's sky and surface hits and shades them, a vector of lanes at a time where the CPU has
// AVX2 (render_shade_kernels.cpp, render_shadow_kernels.cpp), one at a time through shade()
// otherwise.

#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {

// Surface pixels of one row in struct-of-arrays form for the vector beauty kernel. Everything per
// pixel that branches or looks up tables (hit, material, shadow map, memoised ambient) is done
// by the scalar prelude in ColorRow::add_surface; the kernel does the BRDF and sky light.
struct SurfaceLanes {
    std::vector<float> nx, ny, nz, vx, vy, vz, ar, ag, ab, rough, metal, vis, amb_r, amb_g, amb_b,
        env_r, env_g, env_b, px, py, pz;
    std::vector<float> out_r, out_g, out_b;
    std::vector<float> dif_r, dif_g, dif_b;  // the diffuse share of out (sun and sky)

    void resize(std::size_t n)
    {
        for (std::vector<float> *a :
             {&nx,    &ny,    &nz,    &vx,    &vy,    &vz,    &ar,    &ag,    &ab,
              &rough, &metal, &vis,   &amb_r, &amb_g, &amb_b, &env_r, &env_g, &env_b,
              &out_r, &out_g, &out_b, &px,    &py,    &pz,    &dif_r, &dif_g, &dif_b}) {
            a->assign(n, 0.0f);
        }
    }
};

// Lanes past a row's count that vector kernels may read: the widest vector (16 floats).
inline constexpr int kLanePadding = 16;

// Sun and sky constants of the kernel.
struct KernelLight {
    glm::vec3 l;        // toward the sun
    glm::vec3 sun_rgb;  // sun colour * illuminance
    float scale;        // scene sky_ambient
};
// shadow_lookup for the lanes [0, count) (arrays padded by kLanePadding): vis *= the 2x2 PCF of
// `sm` where vis > 0 (render_shadow_kernels.cpp, the CPU's best Highway target).
void shadow_lanes(const ShadowMap &sm, SurfaceLanes &s, int count);

// The sun's visibility at surface point p with normal n (facing the viewer): 0 where n faces away
// from the sun, else the shadow maps' filtered lookups multiplied (the shadow pass; shade()).
float sun_visibility(const Lighting &lt, const glm::vec3 &p, const glm::vec3 &n);

// The beauty of one surface sample; with `specular`, also its view-dependent share: the colour
// less the diffuse terms (albedo (1 - metallic) times the sun's n.l / pi, or its toon band, and
// the sky ambient), so that colour - specular moves with the surface.
glm::vec3 shade(const Lighting &lt,
                const Hit &h,
                const glm::vec3 &view_dir,
                SkyCache &sky,
                glm::vec3 *specular = nullptr);

// The expressions of shading::evaluate (isotropic, height-correlated Smith) and
// shading::add_sky_light for lanes [0, count) (arrays padded by kLanePadding), the diffuse share
// into dif_* (render_shade_kernels.cpp, the CPU's best Highway target).
void shade_lanes(SurfaceLanes &s, int count, const KernelLight &kl);

// The beauty of one row of visibility samples. The scalar path shades each pixel as it is added
// (shade() and the sky); the vector path (Highway; all but POSTHASTE_SIMD=scalar) defers surfaces
// to shadow_lanes and shade_lanes and the sky to the 4-wide SkyView::radiance_n. Toon and
// anisotropic materials always take shade().
class ColorRow {
   public:
    /// With `specular`, specular() holds each slot's view-dependent share (shade()).
    ColorRow(const Lighting &lt, SkyCache &sky, int capacity, bool specular = false)
        : lt_(lt),
          sky_(sky),
          vector_(simd::requested() != simd::Level::Scalar),
          out_(std::size_t(capacity)),
          spec_(specular ? std::size_t(capacity) : 0)
    {
        if (vector_) {
            const std::size_t padded = std::size_t(capacity + kLanePadding);
            lanes_.resize(padded);
            lane_slot_.resize(padded);
            for (std::vector<float> *a : {&sky_x_, &sky_y_, &sky_z_, &env_x_, &env_y_, &env_z_}) {
                a->resize(padded);
            }
            sky_slot_.resize(padded);
            env_lane_.resize(padded);
            sky_out_.resize(padded);
            kl_.l = lt.scene->sun.direction;
            kl_.sun_rgb = lt.scene->sun.color * lt.scene->sun.illuminance;
            kl_.scale = lt.scene->sky_ambient;
        }
    }

    void add_sky(int slot, const glm::vec3 &dn)
    {
        if (!spec_.empty()) {
            spec_[std::size_t(slot)] = glm::vec3(0.0f);
        }
        if (!vector_) {
            out_[std::size_t(slot)] = sky_.radiance(dn);
            return;
        }
        sky_x_[sky_n_] = dn.x;
        sky_y_[sky_n_] = dn.y;
        sky_z_[sky_n_] = dn.z;
        sky_slot_[sky_n_++] = slot;
    }

    void add_surface(int slot, const Hit &h, const glm::vec3 &dn)
    {
        const Material &mat = lt_.materials->m[h.material];
        if (!vector_ || mat.toon || mat.anisotropy != 0.0f) {
            out_[std::size_t(slot)] =
                shade(lt_, h, dn, sky_, spec_.empty() ? nullptr : &spec_[std::size_t(slot)]);
            return;
        }
        // The branchy part of shade(), in the same order.
        const glm::vec3 v = -dn;
        glm::vec3 n = h.n;
        if (glm::dot(n, v) < 0.0f) {
            n = -n;
        }
        const glm::vec3 &l = lt_.scene->sun.direction;
        const float vis = glm::dot(n, l) > 0.0f ? 1.0f : 0.0f;  // shadows: shadow_lanes
        const glm::vec3 &amb = sky_.ambient(n);
        const std::size_t k = lane_n_++;
        SurfaceLanes &s = lanes_;
        s.nx[k] = n.x, s.ny[k] = n.y, s.nz[k] = n.z;
        s.vx[k] = v.x, s.vy[k] = v.y, s.vz[k] = v.z;
        s.ar[k] = mat.albedo.x, s.ag[k] = mat.albedo.y, s.ab[k] = mat.albedo.z;
        s.rough[k] = mat.roughness, s.metal[k] = mat.metallic, s.vis[k] = vis;
        s.px[k] = h.p.x, s.py[k] = h.p.y, s.pz[k] = h.p.z;
        s.amb_r[k] = amb.x, s.amb_g[k] = amb.y, s.amb_b[k] = amb.z;
        lane_slot_[k] = slot;
        const float gloss = (1.0f - mat.roughness) * (1.0f - mat.roughness);
        if (gloss >= 0.05f) {
            const glm::vec3 r = glm::reflect(-v, n);
            env_x_[env_n_] = r.x;
            env_y_[env_n_] = r.y;
            env_z_[env_n_] = r.z;
            env_lane_[env_n_++] = k;
        }
    }

    /// Colours of the row's slots (valid for every slot added since the last finish()).
    const std::vector<glm::vec3> &finish()
    {
        if (vector_) {
            finish_vector();
        }
        return out_;
    }
    /// The view-dependent share of each slot's colour (constructed with `specular`).
    const std::vector<glm::vec3> &specular() const { return spec_; }

   private:
    void finish_vector()
    {
        const glm::vec3 cam(0.0f, shading::kSkyCameraY, 0.0f);
        const shading::SkyView &view = sky_.sky->atmosphere().cached_sky_view();
        if (sky_n_ > 0) {
            view.radiance_n(
                sky_x_.data(), sky_y_.data(), sky_z_.data(), int(sky_n_), sky_out_.data());
            for (std::size_t i = 0; i < sky_n_; ++i) {
                const glm::vec3 d(sky_x_[i], sky_y_[i], sky_z_[i]);
                out_[std::size_t(sky_slot_[i])] = sky_out_[i] + sky_.sky->ground(d, cam);
            }
        }
        if (env_n_ > 0) {
            view.radiance_n(
                env_x_.data(), env_y_.data(), env_z_.data(), int(env_n_), sky_out_.data());
            for (std::size_t i = 0; i < env_n_; ++i) {
                const glm::vec3 d(env_x_[i], env_y_[i], env_z_[i]);
                const glm::vec3 e = sky_out_[i] + sky_.sky->ground(d, cam);
                const std::size_t k = env_lane_[i];
                lanes_.env_r[k] = e.x, lanes_.env_g[k] = e.y, lanes_.env_b[k] = e.z;
            }
        }
        if (lane_n_ > 0) {
            if (lt_.static_map) {
                shadow_lanes(*lt_.static_map, lanes_, int(lane_n_));
            }
            if (lt_.dynamic_map) {
                shadow_lanes(*lt_.dynamic_map, lanes_, int(lane_n_));
            }
            shade_lanes(lanes_, int(lane_n_), kl_);
            for (std::size_t k = 0; k < lane_n_; ++k) {
                const glm::vec3 c(lanes_.out_r[k], lanes_.out_g[k], lanes_.out_b[k]);
                out_[std::size_t(lane_slot_[k])] = c;
                if (!spec_.empty()) {
                    spec_[std::size_t(lane_slot_[k])] =
                        c - glm::vec3(lanes_.dif_r[k], lanes_.dif_g[k], lanes_.dif_b[k]);
                }
            }
        }
        sky_n_ = env_n_ = lane_n_ = 0;
    }

    const Lighting &lt_;
    SkyCache &sky_;
    bool vector_;
    std::vector<glm::vec3> out_, spec_;
    SurfaceLanes lanes_;
    KernelLight kl_{};
    std::vector<int> lane_slot_, sky_slot_;
    std::vector<std::size_t> env_lane_;
    std::vector<float> sky_x_, sky_y_, sky_z_, env_x_, env_y_, env_z_;
    std::vector<glm::vec3> sky_out_;
    std::size_t sky_n_ = 0, env_n_ = 0, lane_n_ = 0;
};

}  // namespace posthaste::raster::render_detail
