// The atmosphere's three tables through the disk cache (core/disk_cache.h): a process that
// builds an atmosphere of parameters a former process of this binary built reads them instead
// of integrating them again (about 100 ms at two threads).

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <utility>
#include <vector>

#include "core/disk_cache.h"
#include "shading/atmosphere/atmosphere.h"

namespace posthaste::shading {

namespace {

// Every field of AtmosphereParams is 4 bytes (floats, vec3s of floats, ints), so its bytes have
// no padding and are the disk cache's key as they are. A new field of another size must keep
// that true (or the key be built field by field).
static_assert(sizeof(AtmosphereParams) == 42 * 4 && alignof(AtmosphereParams) == 4);

disk_cache::Key tables_key(const AtmosphereParams &p)
{
    disk_cache::Key key("atmosphere");
    key.add(p);
    return key;
}

void put_lut(disk_cache::Writer &w, const Lut2D &lut)
{
    w.put(std::int32_t(lut.width()));
    w.put(std::int32_t(lut.height()));
    w.put_vector(lut.texel_vector());
}

bool get_lut(disk_cache::Reader &r, Lut2D &lut, int width, int height)
{
    const auto w = r.get<std::int32_t>(), h = r.get<std::int32_t>();
    return w == width && h == height &&
           lut.assign(w, h, r.get_vector<glm::vec3>(std::size_t(width) * std::size_t(height) + 1));
}

}  // namespace

bool Atmosphere::load_tables()
{
    const std::optional<std::vector<unsigned char>> bytes = disk_cache::load(tables_key(params_));
    if (!bytes) {
        return false;
    }
    const AtmosphereParams &p = params_;
    try {
        disk_cache::Reader r(*bytes);
        Lut2D t, ms, sky;
        if (get_lut(r, t, p.transmittance_width, p.transmittance_height) &&
            get_lut(r, ms, p.multi_scattering_size, p.multi_scattering_size) &&
            get_lut(r, sky, p.sky_view_width, p.sky_view_height) && r.at_end()) {
            transmittance_ = std::move(t);
            multi_scattering_ = std::move(ms);
            sky_view_ = make_sky_view(glm::vec3(0.0f, p.sky_view_y, 0.0f), &sky);
            return true;
        }
    } catch (const std::out_of_range &) {
    }
    return false;
}

void Atmosphere::store_tables() const
{
    if (!disk_cache::enabled()) {
        return;
    }
    disk_cache::Writer w;
    put_lut(w, transmittance_);
    put_lut(w, multi_scattering_);
    put_lut(w, sky_view_.lut_);
    disk_cache::store(tables_key(params_), w.bytes());
}

}  // namespace posthaste::shading
