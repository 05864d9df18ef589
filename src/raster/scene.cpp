#include "raster/scene.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "core/error.h"
#include "core/frame_limits.h"
#include "core/json_error.h"

namespace posthaste::raster {
namespace {

using Json = nlohmann::json;

// A JSON integer within [lo, hi]; an unsigned above 2^63 (which get<long long>() would read as
// a negative number) is out of range.
bool integer_in(const Json &v, long long lo, long long hi)
{
    if (!v.is_number_integer()) {
        return false;
    }
    if (v.is_number_unsigned()) {
        return hi >= 0 && v.get<std::uint64_t>() <= std::uint64_t(hi) &&
               (lo <= 0 || v.get<std::uint64_t>() >= std::uint64_t(lo));
    }
    return v.get<long long>() >= lo && v.get<long long>() <= hi;
}

// A JSON object being read: remembers its path for messages and which keys were used, so that
// unknown keys are reported (pbrt ReportUnused).
class Obj {
   public:
    Obj(const Json &j, std::string origin, std::string path)
        : j_(j), origin_(std::move(origin)), path_(std::move(path))
    {
        if (!j_.is_object()) {
            fail("", "expected an object, got " + std::string(j_.type_name()));
        }
    }

    [[noreturn]] void fail(const std::string &key, const std::string &what) const
    {
        throw_usage(origin_, ":", path_, key.empty() ? "" : "/" + key, ": ", what);
    }
    std::string where(const std::string &key) const { return path_ + "/" + key; }
    const std::string &origin() const { return origin_; }

    bool has(const std::string &key)
    {
        used_.insert(key);
        return j_.contains(key);
    }
    const Json &get(const std::string &key)
    {
        used_.insert(key);
        return j_.at(key);
    }

    double number(const std::string &key, double def, double lo = -1e30, double hi = 1e30)
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        if (!v.is_number()) {
            fail(key, "expected a number, got " + v.dump());
        }
        const double x = v.get<double>();
        if (!(x >= lo && x <= hi)) {
            std::ostringstream os;
            os << "expected a number in [" << lo << ", " << hi << "], got " << v.dump();
            fail(key, os.str());
        }
        return x;
    }
    int integer(const std::string &key, int def, int lo, int hi)
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        if (!integer_in(v, lo, hi)) {
            fail(key, str_cat("expected an integer in [", lo, ", ", hi, "], got ", v.dump()));
        }
        return v.get<int>();
    }
    bool boolean(const std::string &key, bool def)
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        if (!v.is_boolean()) {
            fail(key, "expected true or false, got " + v.dump());
        }
        return v.get<bool>();
    }
    std::string string(const std::string &key, const std::string &def)
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        if (!v.is_string()) {
            fail(key, "expected a string, got " + v.dump());
        }
        return v.get<std::string>();
    }
    /// Three numbers, each in [lo, hi] (by default float's finite range: 1e39 would read as
    /// infinity).
    glm::vec3 vec3(const std::string &key,
                   glm::vec3 def,
                   double lo = -std::numeric_limits<float>::max(),
                   double hi = std::numeric_limits<float>::max())
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        if (!v.is_array() || v.size() != 3 || !v[0].is_number() || !v[1].is_number() ||
            !v[2].is_number()) {
            fail(key, "expected an array of 3 numbers, got " + v.dump());
        }
        for (int i = 0; i < 3; ++i) {
            const double x = v[std::size_t(i)].get<double>();
            if (!(x >= lo && x <= hi)) {
                fail(key, str_cat("expected numbers in ", lo, "..", hi, ", got ", v.dump()));
            }
        }
        return {v[0].get<float>(), v[1].get<float>(), v[2].get<float>()};
    }
    glm::ivec3 ivec3(const std::string &key, glm::ivec3 def)
    {
        if (!has(key)) {
            return def;
        }
        const Json &v = get(key);
        // An int each: a larger integer would wrap in get<int>() and read as another value.
        constexpr int kMin = std::numeric_limits<int>::min(),
                      kMax = std::numeric_limits<int>::max();
        if (!v.is_array() || v.size() != 3 || !integer_in(v[0], kMin, kMax) ||
            !integer_in(v[1], kMin, kMax) || !integer_in(v[2], kMin, kMax)) {
            fail(key, "expected an array of 3 integers in int's range, got " + v.dump());
        }
        return {v[0].get<int>(), v[1].get<int>(), v[2].get<int>()};
    }
    // Each element of an array-valued key as an Obj.
    template <typename Fn>
    void each(const std::string &key, Fn &&fn)
    {
        if (!has(key)) {
            return;
        }
        const Json &v = get(key);
        if (!v.is_array()) {
            fail(key, "expected an array, got " + std::string(v.type_name()));
        }
        for (std::size_t i = 0; i < v.size(); ++i) {
            Obj o(v[i], origin_, str_cat(where(key), "/", i));
            fn(o, int(i));
            o.finish();
        }
    }
    template <typename Fn>
    void child(const std::string &key, Fn &&fn)
    {
        if (!has(key)) {
            return;
        }
        Obj o(get(key), origin_, where(key));
        fn(o);
        o.finish();
    }

    // Unknown keys are errors, with a hint when one is close to a known key.
    void finish() const
    {
        for (auto it = j_.begin(); it != j_.end(); ++it) {
            if (!used_.count(it.key())) {
                std::string known;
                for (const auto &k : used_) {
                    known += (known.empty() ? "" : ", ") + k;
                }
                fail(it.key(),
                     "unknown key " + posthaste::quoted(it.key()) + " (known here: " + known + ")");
            }
        }
    }

   private:
    const Json &j_;
    std::string origin_, path_;
    std::set<std::string> used_;
};

// The keys each object accepts are "used" by reading them; to list every known key in the
// unknown-key message, readers touch all keys even when absent (has() records them).
Motion read_motion(Obj &o)
{
    Motion m;
    m.velocity = o.vec3("velocity", m.velocity);
    m.amplitude = o.vec3("amplitude", m.amplitude);
    m.period = float(o.number("period", m.period, 1e-3, 1e9));
    m.phase = float(o.number("phase", m.phase));
    return m;
}

void read_camera_key(Obj &o, CameraKey &k)
{
    k.frame = o.number("frame", k.frame);
    k.position = o.vec3("position", k.position);
    k.yaw_deg = float(o.number("yaw_deg", k.yaw_deg));
    k.pitch_deg = float(o.number("pitch_deg", k.pitch_deg, -89.9, 89.9));
    k.roll_deg = float(o.number("roll_deg", k.roll_deg));
    k.focal_length_mm = float(o.number("focal_length_mm", k.focal_length_mm, 1.0, 2000.0));
    k.sensor_width_mm = float(o.number("sensor_width_mm", k.sensor_width_mm, 1.0, 200.0));
    k.fstop = float(o.number("fstop", k.fstop, 0.5, 1000.0));
    k.focus_distance = float(o.number("focus_distance", k.focus_distance, 0.01, 1e6));
    k.shutter = float(o.number("shutter", k.shutter, 0.0, 1.0));
}

// Hermite interpolation of scalar channels with Catmull-Rom tangents on non-uniform keys.
float hermite(double t, double t0, double t1, float p0, float p1, float m0, float m1)
{
    const double h = t1 - t0;
    const double s = (t - t0) / h;
    const double s2 = s * s, s3 = s2 * s;
    return float((2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * m0 + (-2 * s3 + 3 * s2) * p1 +
                 (s3 - s2) * h * m1);
}

}  // namespace

glm::vec3 Motion::offset(double t) const
{
    const double a = 2.0 * 3.14159265358979323846 * (t / double(period) + double(phase));
    return velocity * float(t) + amplitude * float(std::sin(a));
}

glm::mat4 Ball::transform(double t) const
{
    const glm::vec3 off = motion.offset(t);
    glm::mat4 m = glm::translate(glm::mat4(1.0f), center + off);
    glm::vec3 dir = motion.amplitude + motion.velocity;
    dir.y = 0.0f;
    const float len = glm::length(dir);
    if (len > 0.0f) {
        dir /= len;
        const glm::vec3 axis = glm::cross(glm::vec3(0, 1, 0), dir);
        // Rolling without slipping: angle = distance / radius. Rotating about up x dir by a
        // positive angle moves the bottom of the ball backwards, as rolling needs.
        const float angle = glm::dot(off, dir) / radius;
        m = glm::rotate(m, angle, axis);
    }
    if (spin_deg != 0.0f) {
        m = glm::rotate(m, float(glm::radians(double(spin_deg) * t)), spin_axis);
    }
    return m;
}

glm::mat4 Mover::transform(double t) const
{
    return glm::translate(glm::mat4(1.0f), motion.offset(t));
}

glm::mat4 CameraState::camera_to_world() const
{
    const float yaw = glm::radians(yaw_deg), pitch = glm::radians(pitch_deg);
    const float roll = glm::radians(roll_deg);
    const glm::vec3 fwd(
        std::sin(yaw) * std::cos(pitch), std::sin(pitch), std::cos(yaw) * std::cos(pitch));
    const glm::vec3 right0(std::cos(yaw), 0.0f, -std::sin(yaw));
    const glm::vec3 up0 = glm::cross(fwd, right0);
    // Positive roll tilts the camera's right axis up (anticlockwise seen from behind), so the
    // image content turns clockwise.
    const glm::vec3 right = std::cos(roll) * right0 + std::sin(roll) * up0;
    const glm::vec3 up = -std::sin(roll) * right0 + std::cos(roll) * up0;
    glm::mat4 m(1.0f);
    m[0] = glm::vec4(right, 0.0f);
    m[1] = glm::vec4(up, 0.0f);
    m[2] = glm::vec4(fwd, 0.0f);
    m[3] = glm::vec4(position, 1.0f);
    return m;
}

const Material *Scene::material(int id) const
{
    for (const Material &m : materials) {
        if (m.id == id) {
            return &m;
        }
    }
    return nullptr;
}

CameraState Scene::camera_at(double t) const
{
    const std::vector<CameraKey> &k = camera_keys;
    auto state = [](const CameraKey &c) {
        CameraState s;
        s.position = c.position;
        s.yaw_deg = c.yaw_deg;
        s.pitch_deg = c.pitch_deg;
        s.roll_deg = c.roll_deg;
        s.focal_length_mm = c.focal_length_mm;
        s.sensor_width_mm = c.sensor_width_mm;
        s.fstop = c.fstop;
        s.focus_distance = c.focus_distance;
        s.shutter = c.shutter;
        return s;
    };
    if (k.size() == 1 || t <= k.front().frame) {
        return state(k.front());
    }
    if (t >= k.back().frame) {
        return state(k.back());
    }
    std::size_t i = 0;
    while (i + 2 < k.size() && t >= k[i + 1].frame) {
        ++i;
    }
    const CameraKey &a = k[i], &b = k[i + 1];
    const CameraKey &pa = i > 0 ? k[i - 1] : a;
    const CameraKey &nb = i + 2 < k.size() ? k[i + 2] : b;
    auto lerp = [&](auto get) {
        // Catmull-Rom tangents from the neighbouring keys (one-sided at the ends).
        const float m0 = float((get(b) - get(pa)) / (b.frame - pa.frame));
        const float m1 = float((get(nb) - get(a)) / (nb.frame - a.frame));
        return hermite(t, a.frame, b.frame, get(a), get(b), m0, m1);
    };
    CameraState s;
    for (int c = 0; c < 3; ++c) {
        s.position[c] = lerp([c](const CameraKey &x) { return x.position[c]; });
    }
    s.yaw_deg = lerp([](const CameraKey &x) { return x.yaw_deg; });
    s.pitch_deg = lerp([](const CameraKey &x) { return x.pitch_deg; });
    s.roll_deg = lerp([](const CameraKey &x) { return x.roll_deg; });
    s.focal_length_mm = lerp([](const CameraKey &x) { return x.focal_length_mm; });
    s.sensor_width_mm = lerp([](const CameraKey &x) { return x.sensor_width_mm; });
    s.fstop = lerp([](const CameraKey &x) { return x.fstop; });
    s.focus_distance = lerp([](const CameraKey &x) { return x.focus_distance; });
    s.shutter = std::clamp(lerp([](const CameraKey &x) { return x.shutter; }), 0.0f, 1.0f);
    s.focus_distance = std::max(s.focus_distance, 0.01f);
    s.fstop = std::max(s.fstop, 0.5f);
    return s;
}

void Scene::invalidate_cache()
{
    cache = make_scene_cache();
}

Scene parse_scene(const std::string &text, const std::string &origin)
{
    const Json j = parse_json_document(text, origin);
    Scene s;
    s.path = origin;
    Obj root(j, origin, "");
    s.name = root.string("name", s.name);
    s.fps = root.number("fps", s.fps, 1e-3, 1e4);
    if (root.has("frame_range")) {
        const Json &r = root.get("frame_range");
        // The frame numbers --frames takes, at most as many (a range of 2e9 frames took
        // memory without bound; a number past int's range was cut).
        const auto within = [&](const Json &v) {
            return v.is_number_integer() && v.get<long long>() >= -kMaxFrameNumber &&
                   v.get<long long>() <= kMaxFrameNumber;
        };
        if (!r.is_array() || r.size() != 2 || !within(r[0]) || !within(r[1]) ||
            r[1].get<int>() < r[0].get<int>() ||
            r[1].get<long long>() - r[0].get<long long>() >= kMaxFrameCount) {
            root.fail("frame_range",
                      str_cat("expected [first, last] integers in ",
                              -kMaxFrameNumber,
                              "..",
                              kMaxFrameNumber,
                              " with first <= last, at most ",
                              kMaxFrameCount,
                              " frames, got ",
                              r.dump()));
        }
        s.frame_start = r[0].get<int>();
        s.frame_end = r[1].get<int>();
    }
    s.sky_ambient = float(root.number("sky_ambient", s.sky_ambient, 0.0, 1e6));
    s.near_clip = float(root.number("near_clip", s.near_clip, 1e-4, 100.0));
    root.each("materials", [&](Obj &o, int) {
        Material m;
        m.id = o.integer("id", m.id, 1, 255);
        m.name = o.string("name", "");
        m.albedo = o.vec3("albedo", m.albedo, 0.0, 1.0);  // a surface reflects at most all
        m.roughness = float(o.number("roughness", m.roughness, 0.0, 1.0));
        m.metallic = float(o.number("metallic", m.metallic, 0.0, 1.0));
        m.anisotropy = float(o.number("anisotropy", m.anisotropy, -1.0, 1.0));
        m.toon = o.boolean("toon", m.toon);
        if (s.material(m.id)) {
            o.fail("id", str_cat("duplicate material id ", m.id));
        }
        s.materials.push_back(m);
    });
    if (s.materials.empty()) {
        root.fail("materials", "expected at least one material");
    }
    auto check_material = [&](Obj &o, const char *key, int id) {
        if (!s.material(id)) {
            o.fail(key, str_cat("no material with id ", id));
        }
        return id;
    };
    root.child("world", [&](Obj &o) {
        WorldParams &p = s.world_params;
        p.seed = std::uint32_t(o.number("seed", p.seed, 0, 4294967295.0));
        const glm::ivec3 size = o.ivec3("size", {p.size_x, p.size_y, p.size_z});
        if (glm::any(glm::lessThan(size, glm::ivec3(1))) || size.x > 512 || size.y > 256 ||
            size.z > 512) {
            o.fail("size",
                   "expected [x, y, z] in [1, 512] x [1, 256] x [1, 512], got " +
                       o.get("size").dump());
        }
        p.size_x = size.x;
        p.size_y = size.y;
        p.size_z = size.z;
        p.terrain = o.string("terrain", p.terrain);
        if (p.terrain != "procedural" && p.terrain != "none") {
            o.fail("terrain",
                   "expected \"procedural\" or \"none\", got " + posthaste::quoted(p.terrain));
        }
        p.base_height = o.integer("base_height", p.base_height, 1, 255);
        p.height_amplitude = o.integer("height_amplitude", p.height_amplitude, 0, 255);
        p.trees = o.integer("trees", p.trees, 0, 100000);
        p.pillars = o.integer("pillars", p.pillars, 0, 100000);
    });
    root.each("boxes", [&](Obj &o, int) {
        Box b;
        b.min = o.ivec3("min", b.min);
        b.max = o.ivec3("max", b.max);
        // Material 0 carves air.
        b.material = o.integer("material", 1, 0, 255);
        if (b.material != 0) {
            check_material(o, "material", b.material);
        }
        s.boxes.push_back(b);
    });
    root.each("balls", [&](Obj &o, int) {
        Ball b;
        b.center = o.vec3("center", b.center);
        b.radius = float(o.number("radius", b.radius, 1e-3, 1e4));
        b.material = check_material(o, "material", o.integer("material", 1, 1, 255));
        b.segments = o.integer("segments", b.segments, 4, 180);
        b.spin_deg = float(o.number("spin_deg", b.spin_deg, -180.0, 180.0));
        const glm::vec3 axis = o.vec3("spin_axis", b.spin_axis);
        if (!(glm::length(axis) > 0.0f)) {
            o.fail("spin_axis", "expected a non-zero vector");
        }
        b.spin_axis = glm::normalize(axis);
        o.child("motion", [&](Obj &m) { b.motion = read_motion(m); });
        s.balls.push_back(b);
    });
    root.each("movers", [&](Obj &o, int) {
        Mover m;
        m.min = o.vec3("min", m.min);
        m.size = o.vec3("size", m.size, 0.0, 1e6);  // metres (a negative size was taken)
        m.material = check_material(o, "material", o.integer("material", 1, 1, 255));
        o.child("motion", [&](Obj &mo) { m.motion = read_motion(mo); });
        s.movers.push_back(m);
    });
    root.child("sun", [&](Obj &o) {
        const glm::vec3 d = o.vec3("direction", s.sun.direction);
        if (glm::length(d) <= 0.0f) {
            o.fail("direction", "expected a non-zero vector");
        }
        s.sun.direction = d;
        s.sun.color = o.vec3("color", s.sun.color, 0.0, 1e6);
        s.sun.illuminance = float(o.number("illuminance", s.sun.illuminance, 0.0, 1e9));
    });
    if (s.balls.size() + s.movers.size() > 10000) {
        root.fail("balls", "expected at most 10000 balls and movers together");
    }
    s.sun.direction = glm::normalize(s.sun.direction);
    CameraKey defaults;
    root.child("camera_defaults", [&](Obj &o) { read_camera_key(o, defaults); });
    root.each("camera", [&](Obj &o, int i) {
        CameraKey k = defaults;
        read_camera_key(o, k);
        if (!s.camera_keys.empty() && !(k.frame > s.camera_keys.back().frame)) {
            o.fail("frame", str_cat("keyframes must have increasing frames (key ", i, ")"));
        }
        s.camera_keys.push_back(k);
    });
    if (s.camera_keys.empty()) {
        root.fail("camera", "expected at least one camera keyframe");
    }
    root.finish();
    generate_world(s);
    return s;
}

Scene load_scene(const std::string &path)
{
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) {
        throw_usage(path, ": is a folder, not a scene file (samples/scenes/*.json)");
    }
    if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec)) {
        throw_usage(path, ": is not a regular file, not a scene file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw_usage(path, ": cannot open scene file");
    }
    std::stringstream ss;
    ss << in.rdbuf();
    return parse_scene(ss.str(), path);
}

}  // namespace posthaste::raster
