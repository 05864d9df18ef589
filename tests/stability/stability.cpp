#include "stability/stability.h"

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <mutex>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/error.h"
#include "core/hash.h"
#include "core/passes.h"
#include "graph/graph.h"
#include "graph/param_json.h"
#include "io/cryptomatte.h"
#include "nodes/registry.h"

namespace posthaste::stability {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

/// Apply fn(pass name, channel, x, y, value&) to every value of every pass.
template <typename Fn>
Frame edited(const Frame &src, Fn &&fn)
{
    Frame out = src;
    for (const auto &[name, pass] : src.passes()) {
        Image img = *pass.image;
        for (int y = 0; y < img.height(); ++y) {
            for (int x = 0; x < img.width(); ++x) {
                for (int c = 0; c < img.channels(); ++c) {
                    fn(name, c, x, y, img.at(x, y, c));
                }
            }
        }
        out.set(name, std::make_shared<const Image>(std::move(img)), pass.channels, pass.storage);
    }
    return out;
}

// A value as `--set` reads it (graph_parse.cpp): text for strings and choices, else JSON, and
// converted by the graph's own conversion, so records and vectors are checked the same way.
ParamValue parse_value(const ParamSpec &spec, const std::string &text)
{
    nlohmann::json v;
    if (spec.type == ParamType::String || spec.type == ParamType::Choice) {
        v = text;
    } else {
        v = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
        if (v.is_discarded()) {
            v = text;
        }
    }
    return convert_param(spec, v, "stability", "param " + std::string(spec.name));
}

NodeParams make_params(const NodeType &type, const std::vector<std::string> &overrides)
{
    std::map<std::string, ParamValue> values;
    for (const ParamSpec &spec : type.spec.params) {
        values[std::string(spec.name)] = default_param(spec);
    }
    for (const std::string &o : overrides) {
        const std::size_t eq = o.find('=');
        const std::string name = o.substr(0, eq);
        const ParamSpec *spec = nullptr;
        for (const ParamSpec &s : type.spec.params) {
            spec = s.name == name ? &s : spec;
        }
        if (eq == std::string::npos || !spec) {
            throw std::invalid_argument("bad override for " + std::string(type.spec.type) + ": " +
                                        o);
        }
        values[name] = parse_value(*spec, o.substr(eq + 1));
    }
    return NodeParams(&type, std::move(values));
}

std::mutex g_mutex;
std::vector<StabilityResult> g_records;

struct WriteAtExit {
    ~WriteAtExit() { write_records(); }
} g_write_at_exit;

}  // namespace

Frame plain_frame(int w, int h, int number)
{
    Frame f;
    f.number = number;
    f.set_size(w, h);
    for (const pass::CanonicalPass &cp : pass::canonical_passes()) {
        const int channels = int(cp.channels.size());
        Image img(w, h, channels);
        const std::string name(cp.name);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                float *p = img.pixel(x, y);
                const float u = hash_unit(x, y, 0, 17), v = hash_unit(x, y, 1, 17);
                if (name == pass::kColor) {
                    const float a = 0.25f + 0.75f * u;
                    p[0] = a * v;
                    p[1] = a * 0.5f;
                    p[2] = a * (1.0f - v);
                    p[3] = a;
                } else if (name == pass::kDepth) {
                    p[0] = 1.0f + 49.0f * u;
                } else if (name == pass::kNormal || name == pass::kTangent) {
                    const float z = 2.0f * u - 1.0f, r = std::sqrt(1.0f - z * z);
                    p[0] = r * std::cos(6.2831853f * v);
                    p[1] = r * std::sin(6.2831853f * v);
                    p[2] = z;
                } else if (name == pass::kMotion || name == pass::kMotionNext) {
                    p[0] = 8.0f * (u - 0.5f);
                    p[1] = 8.0f * (v - 0.5f);
                } else if (name == pass::kId) {
                    p[0] = float(int(u * 8.0f));
                } else if (name == pass::kPosition) {
                    for (int c = 0; c < channels; ++c) {
                        p[c] = 20.0f * (hash_unit(x, y, c, 5) - 0.5f);
                    }
                } else {
                    for (int c = 0; c < channels; ++c) {
                        p[c] = hash_unit(x, y, c, 23);  // albedo, material: [0, 1]
                    }
                }
            }
        }
        f.set(name, std::move(img));
    }
    // A cryptomatte as a renderer declares it (two ranks: "rock" or "tree" first, the other
    // second, coverages from the hash), so the cryptomatte node keys every hostile frame.
    {
        const float rock = cryptomatte::id_of("rock"), tree = cryptomatte::id_of("tree");
        Image ranks(w, h, 4);
        for (int y = 0; y < h; ++y) {
            for (int x = 0; x < w; ++x) {
                const float u = hash_unit(x, y, 2, 29);
                float *p = ranks.pixel(x, y);
                p[0] = u < 0.5f ? rock : tree;
                p[1] = 0.5f + 0.5f * u;
                p[2] = u < 0.5f ? tree : rock;
                p[3] = 0.5f - 0.5f * u;
            }
        }
        f.set("CryptoObject00", std::move(ranks), {"R", "G", "B", "A"});
        const nlohmann::json manifest = {{"rock", cryptomatte::hex_of(rock)},
                                         {"tree", cryptomatte::hex_of(tree)}};
        for (const auto &[field, value] :
             std::vector<std::pair<std::string, std::string>>{{"name", "CryptoObject"},
                                                              {"hash", "MurmurHash3_32"},
                                                              {"conversion", "uint32_to_float32"},
                                                              {"manifest", manifest.dump()}}) {
            f.attributes.push_back(OIIO::ParamValue("cryptomatte/6f7a1c2/" + field, value));
        }
    }
    // A full camera header (this frame, the previous one moved 0.2 units and turned 2 degrees,
    // lens and shutter), so nodes that project or defocus run rather than refuse.
    const glm::mat4 now = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 2.0f, -10.0f));
    const glm::mat4 prev = glm::rotate(glm::translate(now, glm::vec3(-0.2f, 0.0f, 0.0f)),
                                       glm::radians(2.0f),
                                       glm::vec3(0.0f, 1.0f, 0.0f));
    const float aspect = float(w) / float(h);
    const CameraMatrices m = make_camera_matrices(now, 35.0f, 36.0f, aspect, 0.1f);
    const CameraMatrices pm = make_camera_matrices(prev, 35.0f, 36.0f, aspect, 0.1f);
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    f.camera.prev_world_to_camera = pm.world_to_camera;
    f.camera.prev_world_to_ndc = pm.world_to_ndc;
    f.camera.fstop = 2.8f;
    f.camera.focus_distance = 10.0f;
    f.camera.focal_length_mm = 35.0f;
    f.camera.sensor_width_mm = 36.0f;
    f.camera.sensor_height_mm = 36.0f / aspect;
    f.camera.shutter = 0.5f;
    f.camera.near_clip = 0.1f;
    f.camera.far_clip = 1000.0f;
    return f;
}

/// A window of a Cycles frame (samples/cycles/), read through the engine so that its camera is
/// solved from its passes as a graph's would be: a production renderer's filtered edges (depths
/// and positions mixed across silhouettes, normals not of unit length, motion mixed at edges),
/// Blender's sky (depth 1e10, read as +inf), a right-handed world, and a data window inside the
/// display window.
static Frame cycles_window(const std::string &shot, const Rect &window)
{
    const std::string graph = R"({"nodes": [
        {"id": "in", "type": "read", "params": {"path": ")" +
                              std::string(POSTHASTE_SOURCE_DIR) + "/samples/cycles/" + shot +
                              R"(.passes.exr"}},
        {"id": "out", "type": "write", "inputs": {"image": "in"}, "params": {"path": "unused.exr"}}]})";
    Graph g = Graph::parse(graph, "cycles_window", nodes::catalog());
    g.set_capture("in");
    const Frame full = g.evaluate(2);
    Frame f = full;
    f.data_window = window;
    f.clear_passes();
    for (const auto &[name, pass] : full.passes()) {
        const Image &img = *pass.image;
        Image cut(window.width(), window.height(), img.channels());
        for (int y = 0; y < window.height(); ++y) {
            std::copy_n(img.pixel(window.x0, window.y0 + y),
                        std::size_t(window.width()) * std::size_t(img.channels()),
                        cut.pixel(0, y));
        }
        f.set(name, std::move(cut), pass.channels);
    }
    return f;
}

std::vector<HostileFrame> hostile_frames()
{
    std::vector<HostileFrame> out;
    Frame base = plain_frame(16, 16);
    // Every port gets the frame, ssr's environment too: where it was taken, as a reflection
    // probe's header says, so that its depth pass reads as the probe's distances.
    const glm::vec3 probe(0.0f, 1.5f, -5.0f);
    base.attributes.push_back(
        OIIO::ParamValue("posthaste:probePosition", OIIO::TypeVector, 1, &probe));
    out.push_back({"plain", "ordinary finite values (the control)", base});
    out.push_back({"nan_everywhere",
                   "NaN in every pass, one channel at every 5th pixel",
                   edited(base, [](const std::string &, int c, int x, int y, float &v) {
                       v = (x + y) % 5 == 0 && c == x % 4 ? kNaN : v;
                   })});
    out.push_back({"inf_everywhere",
                   "+Inf and -Inf in every pass at every 7th pixel",
                   edited(base, [](const std::string &, int, int x, int y, float &v) {
                       v = (3 * x + y) % 7 == 0 ? ((x & 1) ? kInf : -kInf) : v;
                   })});
    out.push_back({"sky_depth_inf",
                   "top half is sky: depth +inf, zero normals and color",
                   edited(base, [](const std::string &name, int, int, int y, float &v) {
                       if (y < 8) {
                           v = name == pass::kDepth                            ? kInf
                               : name == pass::kPosition                       ? 0.0f
                               : name == pass::kNormal || name == pass::kColor ? 0.0f
                                                                               : v;
                       }
                   })});
    out.push_back({"one_by_one", "a 1x1 frame", plain_frame(1, 1)});
    out.push_back({"one_row", "a 37x1 frame", plain_frame(37, 1)});
    out.push_back({"huge_values",
                   "sun-like color 1e6, depth 1e9, motion 4096 px, position 1e7",
                   edited(base, [](const std::string &name, int c, int x, int y, float &v) {
                       if (name == pass::kColor && c < 3) {
                           v = (x + y) % 3 == 0 ? 1e6f : v;
                       } else if (name == pass::kDepth) {
                           v = 1e9f;
                       } else if (name == pass::kMotion || name == pass::kMotionNext) {
                           v = (c ? -4096.0f : 4096.0f);
                       } else if (name == pass::kPosition) {
                           v *= 1e6f;
                       }
                   })});
    out.push_back({"zero_alpha",
                   "color with alpha 0 and 1e-30 under nonzero RGB (bad premult)",
                   edited(base, [](const std::string &name, int c, int x, int, float &v) {
                       if (name == pass::kColor && c == 3) {
                           v = x % 2 ? 0.0f : 1e-30f;
                       }
                   })});
    out.push_back({"cycles_yard_edges",
                   "Cycles' filtered passes: thin poles against the sky, mixed depths at edges",
                   cycles_window("yard", {0, 0, 96, 64})});
    out.push_back({"cycles_closeup_edges",
                   "Cycles' filtered passes: a chrome ball's silhouette over a wall and the sky",
                   cycles_window("closeup", {40, 40, 136, 104})});
    out.push_back({"negative",
                   "negative color, depth and material values",
                   edited(base, [](const std::string &name, int, int, int, float &v) {
                       if (name == pass::kColor || name == pass::kDepth ||
                           name == pass::kMaterial || name == pass::kAlbedo) {
                           v = -v;
                       }
                   })});
    return out;
}

StabilityResult run_case(const NodeType &type,
                         const std::vector<std::string> &overrides,
                         const Frame &input,
                         double bound)
{
    StabilityResult r;
    r.node = std::string(type.spec.type);
    const NodeIdentity identity{"under_test", r.node, "stability"};
    const NodeParams params = make_params(type, overrides);
    auto in = std::make_shared<const Frame>(input);
    std::vector<std::shared_ptr<const Frame>> inputs;
    std::vector<std::string> ports;
    for (const PortSpec &p : type.spec.inputs) {
        inputs.push_back(in);
        ports.emplace_back(p.name);
    }
    PassSet requested;
    requested.all = true;
    NodeState state;
    NodeContext ctx(identity, params, inputs, ports, requested, input.number, state);

    // Where the input is non-finite: a pixel mask over the frame.
    std::vector<char> bad_in(std::size_t(input.width()) * std::size_t(input.height()), 0);
    for (const auto &[name, pass] : input.passes()) {
        const Image &img = *pass.image;
        for (int y = 0; y < img.height(); ++y) {
            for (int x = 0; x < img.width(); ++x) {
                for (int c = 0; c < img.channels(); ++c) {
                    if (!std::isfinite(img.at(x, y, c))) {
                        ++r.nonfinite_in;
                        bad_in[std::size_t(y) * std::size_t(input.width()) + std::size_t(x)] = 1;
                    }
                }
            }
        }
    }

    const auto t0 = std::chrono::steady_clock::now();
    try {
        type.execute(ctx);
    } catch (const Error &e) {
        r.status = "rejected";
        r.message = e.what();
        return r;
    } catch (const std::exception &e) {
        r.status = "crashed";
        r.message = e.what();
        return r;
    }
    r.ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();

    const Frame &out = ctx.output();
    // A cryptomatte's rank layers hold IDs, hash bits read as floats (any magnitude): the bound
    // does not apply to them (they must still be finite).
    const std::set<std::string> ids = cryptomatte::requested_ranks(
        {cryptomatte::request_for("")}, out.attributes, out.pass_names());
    for (const auto &[name, pass] : out.passes()) {
        const bool id_layer = ids.count(name) != 0;
        const Image &img = *pass.image;
        // Pixels are matched by file coordinates, so a node that cuts or moves the data window
        // without resampling (crop) is held to where its values came from.
        const Rect &in_w = input.data_window, &out_w = out.data_window;
        // +inf depth is the sky (no surface), a valid value: what a node that moves pixels
        // (lens) reads outside its input, as the reader pads a smaller part. specular_depth is
        // a depth too.
        const bool depth = pass::is_depth_pass(name.substr(0, name.find('@')));
        for (int y = 0; y < img.height(); ++y) {
            for (int x = 0; x < img.width(); ++x) {
                for (int c = 0; c < img.channels(); ++c) {
                    const float v = img.at(x, y, c);
                    if (depth && v == kInf) {
                        continue;
                    }
                    if (std::isfinite(v)) {
                        if (!id_layer) {
                            r.max_abs = std::max(r.max_abs, double(std::fabs(v)));
                        }
                        continue;
                    }
                    ++r.nonfinite_out;
                    const int ix = x + out_w.x0 - in_w.x0, iy = y + out_w.y0 - in_w.y0;
                    const bool inside =
                        ix >= 0 && iy >= 0 && ix < input.width() && iy < input.height();
                    if (!inside ||
                        !bad_in[std::size_t(iy) * std::size_t(input.width()) + std::size_t(ix)]) {
                        ++r.spread;
                    }
                }
            }
        }
    }
    if (r.spread > 0 || r.max_abs > bound) {
        r.status = "unstable";
        r.message = str_cat(r.spread,
                            " non-finite value(s) where the input was finite; max |v| ",
                            r.max_abs,
                            " (bound ",
                            bound,
                            ")");
    } else {
        r.status = "ok";
    }
    return r;
}

void record(const StabilityResult &result)
{
    std::lock_guard lock(g_mutex);
    g_records.push_back(result);
}

std::string write_records()
{
    std::lock_guard lock(g_mutex);
    if (g_records.empty()) {
        return {};
    }
    const char *env = std::getenv("POSTHASTE_STABILITY_JSON");
    const std::string path = env && *env ? env : "stability.json";
    nlohmann::json cases = nlohmann::json::array();
    for (const StabilityResult &r : g_records) {
        cases.push_back({{"node", r.node},
                         {"params", r.params},
                         {"frame", r.frame},
                         {"status", r.status},
                         {"message", r.message},
                         {"nonfinite_in", r.nonfinite_in},
                         {"nonfinite_out", r.nonfinite_out},
                         {"spread", r.spread},
                         {"max_abs", r.max_abs},
                         {"ms", r.ms}});
    }
    std::ofstream(path) << nlohmann::json{{"cases", cases}}.dump(2) << "\n";
    return path;
}

}  // namespace posthaste::stability
