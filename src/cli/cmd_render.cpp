// posthaste render SCENE -o PATTERN: render a Minecrappy scene's frames (every pass by default),
// or their ground truth, to EXR. Built as a two-node graph (render -> write) so it shares run's
// validation, parallel frames, progress and summary.

#include <map>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cli/commands.h"
#include "core/error.h"
#include "core/text.h"
#include "graph/graph.h"
#include "nodes/registry.h"

namespace posthaste::cli {
namespace {

struct RenderCommand : RunSettings {
    std::string scene;
    std::string output;
    std::string passes = "all";
    std::string size = "1920x1080";
    int supersample = 1;
    bool no_shadows = false;
    bool probe = false;
    std::string truth;
    int samples = 64;
    int seed = 0;
    double ao_radius = 1.0;
    double overscan = 0.0;
    std::string compression = "piz";
    std::vector<std::string> given;  ///< Truth options on the command line (--samples, ...).
};

/// An error of the command's two-node graph in the command's own terms: the location in a JSON
/// the user never wrote ("posthaste render s.json:/nodes/1/params/path: node \"write\"
/// (write): param \"path\": ") becomes the option the value came from ("render -o: ").
std::string command_message(const std::string &what, const std::string &origin)
{
    const std::string at = origin + ":/nodes/";
    const std::size_t colon = what.find(": ", at.size());
    if (what.rfind(at, 0) != 0 || colon == std::string::npos) {
        return what;  // a frame's error names its node and frame already
    }
    const std::string pointer = what.substr(at.size(), colon - at.size());  // "1/params/path"
    const std::size_t slash = pointer.find("/params/");
    const std::string param = slash == std::string::npos ? "" : pointer.substr(slash + 8);
    std::string rest = what.substr(colon + 2);
    for (const std::string &prefix : {std::string("node \"render\" (render): "),
                                      std::string("node \"write\" (write): "),
                                      "param \"" + param + "\": "}) {
        if (rest.rfind(prefix, 0) == 0) {
            rest.erase(0, prefix.size());
        }
    }
    static const std::map<std::string, std::string> kOptions = {{"0/width", "--size"},
                                                                {"0/height", "--size"},
                                                                {"0/supersample", "--supersample"},
                                                                {"0/truth", "--truth"},
                                                                {"0/samples", "--samples"},
                                                                {"0/seed", "--seed"},
                                                                {"0/ao_radius", "--ao-radius"},
                                                                {"0/overscan", "--overscan"},
                                                                {"0/projection", "--probe"},
                                                                {"1/path", "-o"},
                                                                {"1/passes", "--passes"},
                                                                {"1/compression", "--compression"}};
    std::string option;
    if (const auto it = kOptions.find(pointer.substr(0, 1) + "/" + param); it != kOptions.end()) {
        option = " " + it->second;
    }
    const std::string downstream = "; a node downstream reads it";  // the graph's wording
    if (rest.size() > downstream.size() &&
        rest.compare(rest.size() - downstream.size(), downstream.size(), downstream) == 0) {
        rest.erase(rest.size() - downstream.size());
        option = " --passes";
    }
    return "render" + option + ": " + rest;
}

int render(const RenderCommand &o)
{
    // Whole numbers in int's range (sscanf's %d wrapped 4294967360x36 to a 64x36 frame).
    const std::size_t x = o.size.find('x');
    const std::optional<int> w = parse_int(o.size.substr(0, x));
    const std::optional<int> h =
        x == std::string::npos ? std::nullopt : parse_int(o.size.substr(x + 1));
    if (!w || !h || *w <= 0 || *h <= 0) {
        throw_usage("--size: expected WIDTHxHEIGHT, got \"", o.size, "\"");
    }
    const int width = *w, height = *h;
    // A truth option without the truth it sets was ignored without a word.
    for (const std::string &opt : o.given) {
        const bool applies = opt == "--ao-radius" ? o.truth == "ao" : !o.truth.empty() || o.probe;
        if (!applies) {
            throw_usage(opt,
                        opt == "--ao-radius" ? " applies only to --truth ao"
                                             : " applies only to --truth or --probe");
        }
    }
    std::string truth = "none";
    if (o.truth == "ao" || o.truth == "reflections" || o.truth == "gi") {
        truth = o.truth;
    } else if (!o.truth.empty()) {
        const bool motion = o.truth.find("motion") != std::string::npos;
        const bool dof = o.truth.find("dof") != std::string::npos;
        for (const std::string &w : split_list(o.truth)) {
            if (w != "motion" && w != "dof") {
                throw_usage(
                    "--truth: expected motion, dof, motion,dof, ao, reflections or gi, got \"",
                    o.truth,
                    "\"");
            }
        }
        truth = motion && dof ? "motion_dof" : motion ? "motion" : "dof";
    }
    std::string passes = o.passes;
    if (passes == "all") {
        passes = o.probe ? "color,depth" : o.truth.empty() ? "*" : o.truth == "ao" ? "ao" : "color";
    }
    nlohmann::json g;
    g["nodes"] = nlohmann::json::array();
    g["nodes"].push_back({{"id", "render"},
                          {"type", "render"},
                          {"params",
                           {{"scene", o.scene},
                            {"width", width},
                            {"height", height},
                            {"supersample", o.supersample},
                            {"shadows", !o.no_shadows},
                            {"truth", truth},
                            {"samples", o.samples},
                            {"seed", o.seed},
                            {"overscan", o.overscan},
                            {"projection", o.probe ? "latlong" : "perspective"}}}});
    if (truth == "ao") {
        g["nodes"][0]["params"]["ao_radius"] = o.ao_radius;
    }
    g["nodes"].push_back(
        {{"id", "write"},
         {"type", "write"},
         {"inputs", {{"image", "render"}}},
         {"params", {{"path", o.output}, {"passes", passes}, {"compression", o.compression}}}});
    if (passes == "*") {
        // "every pass the renderer makes": ask for them by name so the planner requests them.
        g["nodes"][1]["params"]["passes"] =
            "color,depth,normal,position,motion,albedo,material,tangent,id,specular,specular_"
            "motion,"
            "diffuse_motion,specular_depth";
    }
    const std::string origin = "posthaste render " + o.scene;
    try {
        Graph graph = Graph::parse(g.dump(), origin, nodes::catalog());
        return run_graph(graph, o);
    } catch (const Error &e) {
        throw Error(e.code(), command_message(e.what(), origin));
    }
}

}  // namespace

void add_render_command(CLI::App &app, int &exit_code)
{
    auto o = std::make_shared<RenderCommand>();
    CLI::App *cmd = app.add_subcommand(
        "render", "Render a Minecrappy scene's frames with every pass, or their ground truth");
    cmd->add_option("scene", o->scene, "Scene file (samples/scenes/*.json)")->required();
    cmd->add_option("-o,--output", o->output, "Output EXR pattern, e.g. out/shot.####.exr")
        ->required()
        ->check(not_empty());  // "" reached the write node as a preview without a format
    cmd->add_option("--frames,-f", o->frames, "Frames (default: the scene's range)");
    cmd->add_option("--passes",
                    o->passes,
                    "Comma-separated passes, or all (default: all; color only with --truth)");
    cmd->add_option("--size", o->size, "WIDTHxHEIGHT (default 1920x1080)");
    cmd->add_option("--supersample", o->supersample, "Beauty supersampling per axis: 1, 2 or 4")
        ->check(CLI::IsMember({1, 2, 4}));
    cmd->add_flag("--no-shadows", o->no_shadows, "Turn the sun's shadow map off");
    cmd->add_flag("--probe",
                  o->probe,
                  "A reflection probe instead: the latitude-longitude map seen from the camera's "
                  "position, exactly traced (color, and depth as distance; --samples rays a "
                  "texel); for ssr's environment input");
    cmd->add_option(
        "--truth",
        o->truth,
        "Ground truth: motion, dof, motion,dof, ao, reflections or gi (one diffuse bounce)");
    cmd->add_option("--overscan",
                    o->overscan,
                    "Render beyond the frame: below 1 a fraction each dimension grows by, from 1 "
                    "whole pixels a side (the data window grows, the display window stays)")
        ->check(in_range(0.0, 4096.0));
    const std::vector<CLI::Option *> truth_options = {
        cmd->add_option("--ao-radius", o->ao_radius, "Ambient occlusion truth: radius in metres")
            ->check(in_range(1e-3, 100.0)),
        cmd->add_option("--samples", o->samples, "Renders accumulated for the ground truth")
            ->check(in_range(1, 65536)),
        cmd->add_option("--seed", o->seed, "Ground-truth jitter seed")
            ->check(in_range(0, 1 << 30))};
    cmd->add_option("--compression", o->compression, "EXR compression (default piz)");
    cmd->add_option("--jobs,-j", o->jobs, "Frames rendered at once")->check(in_range(0, 256));
    cmd->add_option("--max-memory",
                    o->max_memory,
                    "Budget for pass images (8G, 512M; 0: none; default 80 % of available)");
    cmd->add_option("--threads,-t", o->threads, "Worker threads (default: all cores)")
        ->check(in_range(0, 1024));
    cmd->add_flag("--quiet,-q", o->quiet, "No progress and no summary");
    cmd->callback([o, truth_options, &exit_code] {
        for (const CLI::Option *opt : truth_options) {
            if (opt->count() > 0) {
                o->given.push_back(opt->get_name());
            }
        }
        exit_code = render(*o);
    });
}

}  // namespace posthaste::cli
