#pragma once
// Shared helpers for tests: scratch directories, analytic sample frames, running the CLI.

#include <hwy/targets.h>
#include <sys/wait.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/glm.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <iterator>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>

#include "core/camera.h"
#include "core/frame.h"
#include "graph/graph.h"
#include "nodes/registry.h"
#include "raster/render.h"

namespace posthaste::test {

/// Calls fn(name) once on each Highway target this CPU has (the best it has, AVX-512, AVX2,
/// SSE4, the portable one-lane target), with Highway's dispatch held to that target
/// (hwy::SetSupportedTargetsForTest) and restored afterwards: for kernels whose targets must
/// agree.
template <class Fn>
void for_each_highway_target(const Fn &fn)
{
    struct Target {
        const char *name;
        std::int64_t bits;  // 0: the best this CPU has
    };
    static constexpr Target kTargets[] = {{"best", 0},
                                          {"AVX-512", HWY_AVX3},
                                          {"AVX2", HWY_AVX2},
                                          {"SSE4", HWY_SSE4},
                                          {"one lane", HWY_SCALAR | HWY_EMU128}};
    const std::int64_t cpu = hwy::SupportedTargets();
    for (const Target &t : kTargets) {
        if (t.bits != 0 && (cpu & t.bits) == 0) {
            continue;
        }
        hwy::SetSupportedTargetsForTest(t.bits);
        fn(t.name);
        hwy::SetSupportedTargetsForTest(0);
    }
}

/// A fresh, empty directory under the system temp dir, unique to the calling test.
inline std::string scratch_dir(const std::string &name)
{
    namespace fs = std::filesystem;
    const fs::path dir = fs::temp_directory_path() / ("posthaste_test_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir.string();
}

/// An analytic frame: a color gradient that changes with `frame`, a tilted depth plane, an
/// upward normal, constant motion (2, -1) px, world positions, albedo and material, plus a
/// camera. Every value is a closed-form function of (x, y, frame).
inline Frame make_sample_frame(int width, int height, int frame)
{
    Frame f;
    f.number = frame;
    Image color(width, height, 4), depth(width, height, 1), normal(width, height, 3);
    Image position(width, height, 3), motion(width, height, 2), albedo(width, height, 3);
    Image material(width, height, 3);
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            const float u = (x + 0.5f) / width, v = (y + 0.5f) / height;
            color.at(x, y, 0) = u * 2.0f;
            color.at(x, y, 1) = v;
            color.at(x, y, 2) = 0.25f + 0.01f * frame;
            color.at(x, y, 3) = 1.0f;
            depth.at(x, y, 0) =
                y < height / 8 ? std::numeric_limits<float>::infinity() : 2.0f + 10.0f * v;
            normal.at(x, y, 1) = 1.0f;
            position.at(x, y, 0) = u;
            position.at(x, y, 1) = 0.0f;
            position.at(x, y, 2) = 2.0f + 10.0f * v;
            motion.at(x, y, 0) = 2.0f;
            motion.at(x, y, 1) = -1.0f;
            albedo.at(x, y, 0) = 0.5f;
            albedo.at(x, y, 1) = 0.4f;
            albedo.at(x, y, 2) = 0.3f;
            material.at(x, y, 0) = 0.3f;
            material.at(x, y, 1) = u > 0.5f ? 1.0f : 0.0f;
            material.at(x, y, 2) = 0.0f;
        }
    }
    f.set("color", std::move(color));
    f.set("depth", std::move(depth));
    f.set("normal", std::move(normal));
    f.set("position", std::move(position));
    f.set("motion", std::move(motion));
    f.set("albedo", std::move(albedo));
    f.set("material", std::move(material));
    const glm::mat4 cam_to_world = glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 1.5f, -5.0f));
    const CameraMatrices m =
        make_camera_matrices(cam_to_world, 35.0f, 36.0f, float(width) / float(height), 0.1f);
    f.camera.world_to_camera = m.world_to_camera;
    f.camera.world_to_ndc = m.world_to_ndc;
    f.camera.fstop = 2.8f;
    f.camera.focus_distance = 5.0f;
    f.camera.focal_length_mm = 35.0f;
    f.camera.sensor_width_mm = 36.0f;
    f.camera.shutter = 0.5f;
    return f;
}

/// One node of type `type` with `params_json`, run on frames through its first input port as
/// the graph engine would. Its per-instance state (LUTs, caches, an exposure's adaptation)
/// lives as long as the runner, so successive runs see what a sequence would.
class NodeRunner {
   public:
    NodeRunner(const std::string &type, const std::string &params_json)
        : graph_(Graph::parse(R"({"nodes": [
        {"id": "src", "type": "read", "params": {"path": "unused.exr"}},
        {"id": "n", "type": ")" + type +
                                  R"(", "inputs": {")" + first_port(type) +
                                  R"(": "src"}, "params": )" + params_json + R"(},
        {"id": "out", "type": "write", "inputs": {"image": "n"}, "params": {"path": "x.exr"}}]})",
                              "NodeRunner(" + type + ")",
                              nodes::catalog())),
          port_(first_port(type))
    {
    }

    /// The node's output frame for input `in`, as frame `frame_number`.
    Frame run(std::shared_ptr<const Frame> in, int frame_number = 1) const
    {
        return graph_.run_node(graph_.find("n"), {std::move(in)}, {port_}, frame_number);
    }
    /// The node's output for frames on several of its ports (the first port's included), by
    /// port name.
    Frame run_ports(const std::vector<std::pair<std::string, Frame>> &inputs,
                    int frame_number = 1) const
    {
        std::vector<std::shared_ptr<const Frame>> frames;
        std::vector<std::string> ports;
        for (const auto &[port, frame] : inputs) {
            ports.push_back(port);
            frames.push_back(std::make_shared<const Frame>(frame));
        }
        return graph_.run_node(graph_.find("n"), std::move(frames), std::move(ports), frame_number);
    }
    Frame run(const Frame &in, int frame_number = 1) const
    {
        return run(std::make_shared<const Frame>(in), frame_number);
    }
    /// The node as the graph parsed it (identity, validated params, requested passes).
    const GraphNode &node() const { return graph_.nodes()[std::size_t(graph_.find("n"))]; }

   private:
    static std::string first_port(const std::string &type)
    {
        const NodeType *nt = find_node_type(type);
        if (!nt) {
            throw std::invalid_argument("NodeRunner: unknown node type " + type);
        }
        return std::string(nt->spec.inputs.empty() ? "" : nt->spec.inputs[0].name);
    }

    Graph graph_;
    std::string port_;
};

/// NodeRunner(type, params_json).run(in, frame_number): one run with fresh node state.
inline Frame run_node(const std::string &type,
                      const Frame &in,
                      const std::string &params_json,
                      int frame_number = 1)
{
    return NodeRunner(type, params_json).run(in, frame_number);
}

/// Node `node`'s output for `frame` in `graph` (a parsed graph file), its sinks writing nothing.
inline Frame graph_output(const Graph &graph, const std::string &node, int frame = 1)
{
    return *graph.evaluate_outputs(frame, {graph.find(node)})[0];
}

/// Whether every R, G and B value of `image` is finite.
inline bool all_finite_rgb(const Image &image)
{
    for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                if (!std::isfinite(image.at(x, y, c))) {
                    return false;
                }
            }
        }
    }
    return true;
}

/// Run a shell command, capturing stdout+stderr; returns the exit status.
/// A file's bytes ("" when it cannot be read).
inline std::string read_bytes(const std::string &path)
{
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline int run_command(const std::string &command, std::string *output = nullptr)
{
    FILE *pipe = ::popen((command + " 2>&1").c_str(), "r");
    if (!pipe) {
        return -1;
    }
    std::string out;
    char buf[4096];
    while (std::size_t n = std::fread(buf, 1, sizeof(buf), pipe)) {
        out.append(buf, n);
    }
    const int status = ::pclose(pipe);
    if (output) {
        *output = out;
    }
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

/// A scene of samples/scenes/.
inline std::string scene_path(const std::string &name)
{
    return std::string(POSTHASTE_SOURCE_DIR) + "/samples/scenes/" + name;
}

/// Render options of a w x h frame with these passes (the other options default).
inline raster::RenderOptions render_options(int w, int h, std::set<std::string> passes)
{
    raster::RenderOptions o;
    o.width = w;
    o.height = h;
    o.passes = std::move(passes);
    return o;
}

/// RMS over RGB of a - b (images of one size, at least 3 channels).
inline double rms_rgb(const Image &a, const Image &b)
{
    double sum = 0.0;
    for (int y = 0; y < a.height(); ++y) {
        for (int x = 0; x < a.width(); ++x) {
            for (int c = 0; c < 3; ++c) {
                const double d = double(a.at(x, y, c)) - double(b.at(x, y, c));
                sum += d * d;
            }
        }
    }
    return std::sqrt(sum / (3.0 * double(a.pixel_count())));
}

}  // namespace posthaste::test
