// The atmosphere's three tables through the disk cache (core/disk_cache.h): a process that
// builds an atmosphere of parameters a former process of this binary built reads them instead
// of integrating them again (about 100 ms at two threads).

#include <cstdint>
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

void Atmosphere::build_tables()
{
    struct Tables {
        Lut2D transmittance, multi_scattering, sky;
    };
    const AtmosphereParams &p = params_;
    const glm::vec3 sky_camera(0.0f, p.sky_view_y, 0.0f);
    Tables tables = disk_cache::cached<Tables>(
        tables_key(p),
        [&] {
            build_transmittance();
            build_multi_scattering();
            // The sky view reads the other two, so it is made before they move.
            Lut2D sky = make_sky_view(sky_camera).lut_;
            return Tables{std::move(transmittance_), std::move(multi_scattering_), std::move(sky)};
        },
        [](const Tables &t, disk_cache::Writer &w) {
            put_lut(w, t.transmittance);
            put_lut(w, t.multi_scattering);
            put_lut(w, t.sky);
        },
        [&](disk_cache::Reader &r) {
            Tables t;
            if (!get_lut(r, t.transmittance, p.transmittance_width, p.transmittance_height) ||
                !get_lut(r, t.multi_scattering, p.multi_scattering_size, p.multi_scattering_size) ||
                !get_lut(r, t.sky, p.sky_view_width, p.sky_view_height)) {
                throw std::out_of_range("atmosphere: tables of another size");
            }
            return t;
        });
    transmittance_ = std::move(tables.transmittance);
    multi_scattering_ = std::move(tables.multi_scattering);
    sky_view_ = make_sky_view(sky_camera, &tables.sky);  // the view's frame; the LUT as it is
}

}  // namespace posthaste::shading
