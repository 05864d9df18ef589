#include "shading/atmosphere/sky.h"

#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "shading/atmosphere/atmosphere.h"
#include "shading/atmosphere/scene_sky.h"

namespace posthaste::shading {
namespace {

struct Entry {
    glm::vec3 sun;
    std::unique_ptr<Atmosphere> atmosphere;
    std::unique_ptr<SceneSky> sky;
};

std::mutex g_mutex;
std::vector<std::unique_ptr<Entry>> g_entries;  // never erased: references stay valid

}  // namespace

const SceneSky &scene_sky(const glm::vec3 &sun_dir_in)
{
    // Per-pixel callers hit the same sun again and again: a per-thread memo avoids the lock.
    thread_local glm::vec3 last_sun(std::numeric_limits<float>::quiet_NaN());
    thread_local const SceneSky *last_sky = nullptr;
    if (last_sky && sun_dir_in == last_sun) {
        return *last_sky;
    }
    glm::vec3 sun = sun_dir_in;
    if (!(glm::length(sun) > 0.0f) || !std::isfinite(glm::length(sun))) {
        sun = glm::vec3(0.4f, 0.75f, 0.3f);
    }
    sun = glm::normalize(sun);
    std::lock_guard lock(g_mutex);
    for (const auto &e : g_entries) {
        if (e->sun == sun) {
            last_sun = sun_dir_in;
            last_sky = e->sky.get();
            return *last_sky;
        }
    }
    auto e = std::make_unique<Entry>();
    e->sun = sun;
    AtmosphereParams p;
    p.sun_direction = sun;
    p.sun_illuminance = glm::vec3(kSkyIlluminance);
    p.sky_view_y = kSkyCameraY;
    e->atmosphere = std::make_unique<Atmosphere>(p);
    e->sky = std::make_unique<SceneSky>(*e->atmosphere);
    g_entries.push_back(std::move(e));
    last_sun = sun_dir_in;
    last_sky = g_entries.back()->sky.get();
    return *last_sky;
}

glm::vec3 sky_radiance(const glm::vec3 &dir, const glm::vec3 &sun_dir)
{
    return scene_sky(sun_dir).radiance(dir, glm::vec3(0.0f, kSkyCameraY, 0.0f), false);
}

glm::vec3 sky_ambient_radiance(const glm::vec3 &n, const glm::vec3 &sun_dir)
{
    return scene_sky(sun_dir).ambient(n);
}

}  // namespace posthaste::shading
