// The renderer's Cryptomatte: CryptoObject (a block's material name for the voxel world,
// "ball_<i>" and "mover_<i>" for the moving objects) and CryptoMaterial (material names), ranked
// per pixel by the share of the pixel's samples that see each ID (render_detail.h).
#include <algorithm>
#include <nlohmann/json.hpp>

#include "core/cryptomatte_id.h"
#include "core/parallel.h"
#include "raster/render_detail.h"

namespace posthaste::raster::render_detail {

namespace {

std::string material_name(const Scene &s, int id)
{
    const Material *m = s.material(id);
    return m && !m->name.empty() ? m->name : "material_" + std::to_string(id);
}

/// One cryptomatte: the ID of every triangle id's instance and material, and the manifest.
struct IdTable {
    std::vector<float> by_material;  ///< Static world: by material id (0..255).
    std::vector<float> by_instance;  ///< Moving objects: by instance index (-dynamic_begin).
    nlohmann::json manifest = nlohmann::json::object();

    float add(const std::string &name)
    {
        const float id = cryptomatte::id_of(name);
        manifest[name] = cryptomatte::hex_of(id);
        return id;
    }
};

/// The IDs of CryptoObject (`objects`) or CryptoMaterial.
IdTable make_table(const Scene &s, const Geometry &g, bool objects)
{
    IdTable t;
    t.by_material.assign(256, 0.0f);
    for (const Material &m : s.materials) {
        if (m.id >= 0 && m.id < 256) {
            t.by_material[std::size_t(m.id)] = t.add(material_name(s, m.id));
        }
    }
    const std::size_t dynamic = g.instances.size() - g.dynamic_begin;
    t.by_instance.assign(dynamic, 0.0f);
    for (std::size_t i = 0; objects && i < dynamic; ++i) {
        t.by_instance[i] = t.add(i < s.balls.size() ? "ball_" + std::to_string(i)
                                                    : "mover_" + std::to_string(i - s.balls.size()));
    }
    return t;
}

/// The ID triangle `tid` shows in one cryptomatte (0: the sky).
float id_of_triangle(const Geometry &g, const IdTable &t, bool objects, std::uint32_t tid)
{
    if (tid == kNoTriangle) {
        return 0.0f;
    }
    const std::size_t instance = tid >> kInstanceShift;
    if (objects && instance >= g.dynamic_begin) {
        return t.by_instance[instance - g.dynamic_begin];
    }
    const Mesh &m = *g.instances[instance].mesh;
    return t.by_material[m.materials[tid & ((1u << kInstanceShift) - 1u)]];
}

}  // namespace

void add_cryptomattes(const Scene &s,
                      const Geometry &g,
                      const Visibility &vis,
                      const RenderOptions &o,
                      Frame &f)
{
    const int ss = o.supersample, w = o.width, h = o.height;
    const int ranks = o.cryptomatte_ranks, layers = (ranks + 1) / 2;
    const float share = 1.0f / float(ss * ss);  // exact: ss is 1, 2 or 4
    for (const char *type : {kCryptoObject, kCryptoMaterial}) {
        if (!o.passes.count(crypto_layer(type, 0))) {
            continue;
        }
        const bool objects = type == kCryptoObject;
        const IdTable table = make_table(s, g, objects);
        std::vector<Image> planes;
        for (int k = 0; k < layers; ++k) {
            planes.emplace_back(w, h, 4);  // zero: no ID, no coverage
        }
        parallel_for(0, h, [&](int y) {
            // (ID bits, samples) of one pixel; at most 16 samples.
            std::pair<std::uint32_t, int> seen[16];
            for (int x = 0; x < w; ++x) {
                int n = 0;
                for (int sy = 0; sy < ss; ++sy) {
                    const std::uint32_t *row =
                        &vis.ids[std::size_t(y * ss + sy) * std::size_t(w * ss) + std::size_t(x * ss)];
                    for (int sx = 0; sx < ss; ++sx) {
                        const float id = id_of_triangle(g, table, objects, row[sx]);
                        if (id == 0.0f) {
                            continue;  // the sky: no object
                        }
                        const std::uint32_t bits = cryptomatte::bits_of(id);
                        int k = 0;
                        while (k < n && seen[k].first != bits) {
                            ++k;
                        }
                        if (k == n) {
                            seen[n++] = {bits, 0};
                        }
                        ++seen[k].second;
                    }
                }
                // Most coverage first; ties by ID, so the ranks do not depend on sample order.
                std::sort(seen, seen + n, [](const auto &a, const auto &b) {
                    return a.second != b.second ? a.second > b.second : a.first < b.first;
                });
                for (int r = 0; r < std::min(n, ranks); ++r) {
                    float *p = planes[std::size_t(r / 2)].pixel(x, y) + 2 * (r % 2);
                    std::memcpy(&p[0], &seen[r].first, sizeof(float));
                    p[1] = float(seen[r].second) * share;
                }
            }
        });
        for (int k = 0; k < layers; ++k) {
            f.set(crypto_layer(type, k), std::move(planes[std::size_t(k)]), {"R", "G", "B", "A"});
        }
        const std::string key = "cryptomatte/" + cryptomatte::hex_of(cryptomatte::id_of(type)).substr(0, 7);
        f.attributes.push_back(OIIO::ParamValue(key + "/name", std::string(type)));
        f.attributes.push_back(OIIO::ParamValue(key + "/hash", std::string("MurmurHash3_32")));
        f.attributes.push_back(
            OIIO::ParamValue(key + "/conversion", std::string("uint32_to_float32")));
        f.attributes.push_back(OIIO::ParamValue(key + "/manifest", table.manifest.dump()));
    }
}

}  // namespace posthaste::raster::render_detail
