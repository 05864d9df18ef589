// The disk cache of start-up tables (core/disk_cache.h): what it stores comes back bit for bit,
// what is damaged or foreign is a miss and is rebuilt, and a cache that cannot be written never
// fails a build. Then the three users: the atmosphere's LUTs, the tonal art maps and the voxel
// meshes give the same bits from the cache as built.

#include "core/disk_cache.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "raster/mesh.h"
#include "raster/scene.h"
#include "raster/scene_cache.h"
#include "shading/atmosphere/atmosphere.h"
#include "shading/hatching/tam.h"
#include "tests/test_util.h"

namespace posthaste {
namespace {

namespace fs = std::filesystem;
using test::run_command;
using test::scene_path;
using test::scratch_dir;

/// Points the cache at a fresh folder of the test's own, on, and back to the environment's after.
class CacheDir {
   public:
    explicit CacheDir(const std::string &name) : dir_(scratch_dir("cache_" + name))
    {
        disk_cache::set_directory(dir_);
        disk_cache::set_enabled(true);
    }
    ~CacheDir()
    {
        disk_cache::set_directory("");
        disk_cache::set_enabled(true);
    }
    const std::string &path() const { return dir_; }
    std::vector<fs::path> entries() const
    {
        std::vector<fs::path> out;
        for (const auto &e : fs::directory_iterator(dir_)) {
            out.push_back(e.path());
        }
        return out;
    }

   private:
    std::string dir_;
};

std::vector<unsigned char> bytes_of(const std::string &s)
{
    return {s.begin(), s.end()};
}

std::vector<unsigned char> read_file(const fs::path &p)
{
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_file(const fs::path &p, const std::vector<unsigned char> &bytes)
{
    std::ofstream out(p, std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char *>(bytes.data()), std::streamsize(bytes.size()));
}

TEST(DiskCache, TheBinaryHasABuildId)
{
    // Without one the cache is off; the project's builds always have one (GNU ld's default).
    EXPECT_EQ(disk_cache::build_id().size(), 40u) << disk_cache::build_id();
}

TEST(DiskCache, WhatIsStoredComesBackAndOtherKeysMiss)
{
    CacheDir dir("roundtrip");
    ASSERT_TRUE(disk_cache::enabled());
    disk_cache::Key key("unit");
    key.add(42).add(1.5f);
    const std::vector<unsigned char> payload = bytes_of("the payload");
    EXPECT_FALSE(disk_cache::load(key).has_value());
    disk_cache::store(key, payload);
    ASSERT_EQ(dir.entries().size(), 1u);
    EXPECT_EQ(dir.entries()[0].filename().string().rfind("unit-", 0), 0u);
    const auto back = disk_cache::load(key);
    ASSERT_TRUE(back.has_value());
    EXPECT_EQ(*back, payload);

    disk_cache::Key other("unit");
    other.add(42).add(1.25f);  // one parameter differs: another entry, not this one
    EXPECT_FALSE(disk_cache::load(other).has_value());
    disk_cache::Key other_kind("unit2");
    other_kind.add(42).add(1.5f);
    EXPECT_FALSE(disk_cache::load(other_kind).has_value());
}

TEST(DiskCache, DamagedEntriesAreMissesAndAreRebuilt)
{
    CacheDir dir("damaged");
    disk_cache::Key key("unit");
    key.add(7);
    disk_cache::store(key, bytes_of("0123456789abcdef"));
    ASSERT_EQ(dir.entries().size(), 1u);
    const fs::path entry = dir.entries()[0];
    const std::vector<unsigned char> good = read_file(entry);

    const auto rejected = [] { return disk_cache::stats().rejected; };
    // A flipped payload byte (the checksum), a flipped key byte, a truncated file, an empty file,
    // a file of another format, one byte too many.
    std::vector<std::vector<unsigned char>> damaged;
    damaged.push_back(good);
    damaged.back()[good.size() - 12] ^= 1;
    damaged.push_back(good);
    damaged.back()[20] ^= 0x80;
    damaged.push_back(std::vector<unsigned char>(good.begin(), good.end() - 3));
    damaged.push_back({});
    damaged.push_back(bytes_of("not a cache entry at all, but long enough to read a header"));
    damaged.push_back(good);
    damaged.back().push_back(0);
    for (std::size_t i = 0; i < damaged.size(); ++i) {
        write_file(entry, damaged[i]);
        const int before = rejected();
        EXPECT_FALSE(disk_cache::load(key).has_value()) << "damage " << i;
        EXPECT_EQ(rejected(), before + 1) << "damage " << i;
    }

    // cached() builds on the miss and stores the entry again: the next load hits.
    int builds = 0;
    const auto build = [&] {
        ++builds;
        return std::string("0123456789abcdef");
    };
    const auto encode = [](const std::string &s, disk_cache::Writer &w) {
        w.put_vector(std::vector<char>(s.begin(), s.end()));
    };
    const auto decode = [](disk_cache::Reader &r) {
        const std::vector<char> v = r.get_vector<char>(1024);
        return std::string(v.begin(), v.end());
    };
    EXPECT_EQ(disk_cache::cached<std::string>(key, build, encode, decode), "0123456789abcdef");
    EXPECT_EQ(builds, 1);  // the raw bytes stored above are not an encoded string: a miss
    EXPECT_EQ(disk_cache::cached<std::string>(key, build, encode, decode), "0123456789abcdef");
    EXPECT_EQ(builds, 1);  // now a hit
    EXPECT_EQ(dir.entries().size(), 1u);
}

TEST(DiskCache, OffOrUnwritableNeverFailsAndWritesNothing)
{
    CacheDir dir("off");
    disk_cache::Key key("unit");
    key.add(1);
    disk_cache::set_enabled(false);
    EXPECT_FALSE(disk_cache::enabled());
    disk_cache::store(key, bytes_of("x"));
    EXPECT_FALSE(disk_cache::load(key).has_value());
    EXPECT_TRUE(dir.entries().empty());
    disk_cache::set_enabled(true);

    ::setenv("POSTHASTE_CACHE", "off", 1);
    EXPECT_FALSE(disk_cache::enabled());
    ::unsetenv("POSTHASTE_CACHE");
    EXPECT_TRUE(disk_cache::enabled());

    // A folder that cannot be made (under a regular file): stores are dropped, builds still run.
    const std::string file = dir.path() + "/a_file";
    write_file(file, bytes_of("x"));
    disk_cache::set_directory(file + "/cache");
    int builds = 0;
    const int v = disk_cache::cached<int>(
        key,
        [&] { return ++builds, 5; },
        [](int x, disk_cache::Writer &w) { w.put(x); },
        [](disk_cache::Reader &r) { return r.get<int>(); });
    EXPECT_EQ(v, 5);
    EXPECT_EQ(builds, 1);
    EXPECT_FALSE(fs::exists(file + "/cache"));
}

template <typename T>
bool same_bits(const std::vector<T> &a, const std::vector<T> &b)
{
    return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0;
}

TEST(DiskCache, TheAtmosphereFromTheCacheHasTheBuiltBits)
{
    CacheDir dir("atmosphere");
    shading::AtmosphereParams p;
    p.sun_direction = glm::vec3(0.3f, 0.4f, -0.2f);
    p.sun_illuminance = glm::vec3(2.0f);
    disk_cache::set_enabled(false);
    const shading::Atmosphere built(p);
    disk_cache::set_enabled(true);
    const int hits = disk_cache::stats().hits;
    const shading::Atmosphere first(p);  // a miss: built and stored
    EXPECT_EQ(disk_cache::stats().hits, hits);
    ASSERT_EQ(dir.entries().size(), 1u);
    const shading::Atmosphere loaded(p);  // a hit
    EXPECT_EQ(disk_cache::stats().hits, hits + 1);
    for (const shading::Atmosphere *a : {&first, &loaded}) {
        EXPECT_TRUE(same_bits(a->transmittance_table().texel_vector(),
                              built.transmittance_table().texel_vector()));
        EXPECT_TRUE(same_bits(a->multi_scattering_table().texel_vector(),
                              built.multi_scattering_table().texel_vector()));
        EXPECT_TRUE(same_bits(a->cached_sky_view().lut().texel_vector(),
                              built.cached_sky_view().lut().texel_vector()));
        // The view's frame (not in the entry) is rebuilt: radiances agree bit for bit.
        for (const glm::vec3 d :
             {glm::vec3(0, 1, 0), glm::vec3(0.6f, 0.1f, -0.79f), glm::vec3(-0.3f, -0.5f, 0.81f)}) {
            const glm::vec3 dir_n = glm::normalize(d);
            const glm::vec3 x = a->sky_radiance(dir_n, glm::vec3(0, 1.7f, 0));
            const glm::vec3 y = built.sky_radiance(dir_n, glm::vec3(0, 1.7f, 0));
            EXPECT_EQ(std::memcmp(&x, &y, sizeof x), 0);
        }
    }
    // Another sun is another entry; the first stays.
    p.sun_direction = glm::vec3(0.3f, 0.5f, -0.2f);
    const shading::Atmosphere another(p);
    EXPECT_EQ(dir.entries().size(), 2u);
    EXPECT_FALSE(same_bits(another.cached_sky_view().lut().texel_vector(),
                           built.cached_sky_view().lut().texel_vector()));
}

TEST(DiskCache, TheTonalArtMapFromTheCacheHasTheBuiltBits)
{
    CacheDir dir("tam");
    shading::TamParams p;
    p.size = 64;
    p.stroke_levels = 2;
    disk_cache::set_enabled(false);
    const shading::Tam built = shading::build_tam(p);
    disk_cache::set_enabled(true);
    const shading::Tam first = shading::build_tam(p);
    const int hits = disk_cache::stats().hits;
    const shading::Tam loaded = shading::build_tam(p);
    EXPECT_EQ(disk_cache::stats().hits, hits + 1);
    ASSERT_EQ(dir.entries().size(), 1u);
    for (const shading::Tam *t : {&first, &loaded}) {
        ASSERT_EQ(t->levels(), built.levels());
        ASSERT_EQ(t->strokes().size(), built.strokes().size());
        EXPECT_EQ(std::memcmp(t->strokes().data(),
                              built.strokes().data(),
                              built.strokes().size() * sizeof(shading::TamStroke)),
                  0);
        for (int tone = 0; tone < shading::kTamTones; ++tone) {
            for (int l = 0; l < built.levels(); ++l) {
                const std::size_t n = std::size_t(built.level_size(l) * built.level_size(l));
                EXPECT_EQ(std::memcmp(t->texels(tone, l), built.texels(tone, l), n * 4), 0);
            }
        }
        const std::size_t packed =
            std::size_t(built.level_offset(built.levels() - 1) + 1) * shading::Tam::kPacked;
        EXPECT_EQ(std::memcmp(t->packed(), built.packed(), packed * 4), 0);
        EXPECT_FLOAT_EQ(t->ramp(0.7f, 0.3f, 0.6f, 0.5f), built.ramp(0.7f, 0.3f, 0.6f, 0.5f));
    }
}

TEST(DiskCache, TheVoxelMeshesFromTheCacheHaveTheBuiltBits)
{
    CacheDir dir("meshes");
    const raster::Scene scene = raster::load_scene(scene_path("minecrappy.json"));
    const std::vector<raster::Mesh> built = raster::mesh_chunks(scene.world, false);
    for (int round = 0; round < 2; ++round) {  // a miss that stores, then a hit
        const int hits = disk_cache::stats().hits;
        auto cache = raster::make_scene_cache();
        const auto meshes = raster::scene_meshes(scene, *cache, false);
        EXPECT_EQ(disk_cache::stats().hits, hits + round);
        ASSERT_EQ(meshes->chunks.size(), built.size());
        for (std::size_t i = 0; i < built.size(); ++i) {
            const raster::Mesh &a = meshes->chunks[i], &b = built[i];
            EXPECT_TRUE(same_bits(a.positions, b.positions));
            EXPECT_TRUE(same_bits(a.normals, b.normals));
            EXPECT_TRUE(same_bits(a.tangents, b.tangents));
            EXPECT_TRUE(same_bits(a.triangles, b.triangles));
            EXPECT_TRUE(same_bits(a.materials, b.materials));
            EXPECT_EQ(a.bounds_min, b.bounds_min);
            EXPECT_EQ(a.bounds_max, b.bounds_max);
        }
    }
    EXPECT_EQ(dir.entries().size(), 1u);
}

TEST(DiskCache, TheCommandLineWritesNoEntryWithNoCache)
{
    const std::string dir = scratch_dir("cache_cli");
    const std::string graph = std::string(POSTHASTE_SOURCE_DIR) + "/graphs/minecrappy.json";
    const std::string run = "POSTHASTE_CACHE_DIR=" + dir + " " + std::string(POSTHASTE_BINARY) +
                            " run " + graph +
                            " --frames 1 -q -j 1 --set scene.width=16 --set scene.height=16"
                            " --set exr.path=" +
                            dir + "/out/a.####.exr --set preview.path=" + dir +
                            "/out/a.####.png --set hatched_preview.path=" + dir + "/out/h.####.png";
    std::string out;
    ASSERT_EQ(run_command(run + " --no-cache", &out), 0) << out;
    int entries = 0;
    for (const auto &e : fs::directory_iterator(dir)) {
        entries += e.path().extension() == ".bin";
    }
    EXPECT_EQ(entries, 0);
    ASSERT_EQ(run_command(run, &out), 0) << out;
    for (const auto &e : fs::directory_iterator(dir)) {
        entries += e.path().extension() == ".bin";
    }
    EXPECT_EQ(entries, 3);  // the atmosphere, the hatching's maps, the voxel meshes
}

}  // namespace
}  // namespace posthaste
