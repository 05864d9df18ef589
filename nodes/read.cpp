// nodes/read.cpp: read a frame sequence (multi-layer or multi-part EXR; PNG/TIFF/JPEG as color).
// Produces exactly the passes that nodes downstream read, mapped from other tools' channel names
// by the alias rules (io/aliases.h); camera and header attributes come along.

#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>

#include "core/camera_solve.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "nodes/node.h"
#include "nodes/read_camera.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kPath =
    ParamSpec::string("path", "")
        .file_path()
        .mandatory()
        .doc("File or frame pattern: '#' or '@' is one digit (shot.####.exr), or %04d.");
constexpr ParamSpec kFrameOffset =
    ParamSpec::integer("frame_offset", 0)
        .doc("Added to the frame number before the pattern is expanded.");
constexpr ParamSpec kBadPixels =
    ParamSpec::choice("bad_pixels", "keep|zero|error", "keep")
        .doc("NaN or infinite values (other than +inf depth): keep them, replace with 0, or fail.");
constexpr ParamSpec kLinearize =
    ParamSpec::boolean("linearize", true)
        .doc("Decode sRGB-encoded 8/16-bit files (PNG, JPEG, TIFF) to scene-linear.");
constexpr ParamSpec kAliases = ParamSpec::json("aliases", "[]")
                                   .doc(
                                       "Extra channel alias rules [{pass, channels, scale, offset, "
                                       "infinite_above}], tried first.");
constexpr ParamSpec kView =
    ParamSpec::string("view", "")
        .doc(
            "Stereo/multi-view files: the view the canonical passes come from (\"\": the file's "
            "default, the first of its multiView list). Other views' passes travel as "
            "pass@view and are written back as views.");
constexpr ParamSpec kConvention =
    ParamSpec::choice("convention",
                      "auto|canonical|blender|nuke|arnold|vray|redshift|unreal|karma|renderman",
                      "auto")
        .doc(
            "Whose pass names to recognise: auto (every renderer's, docs/CONVENTIONS.md), or one "
            "renderer's (with posthaste's canonical names), when names of two renderers clash.");
constexpr ParamSpec kDeep =
    ParamSpec::choice("deep", "flatten|error", "flatten")
        .doc(
            "Deep files: composite each pixel's samples front to back (depth = the nearest "
            "sample), or refuse them.");
constexpr ParamSpec kCamera =
    ParamSpec::json("camera", "null")
        .doc(
            "The camera, replacing the header's: {\"world_to_camera\": [16], \"world_to_ndc\": "
            "[16]} (OpenEXR's order), or {\"camera_to_world\": [16], \"focal_length\": mm, "
            "\"sensor_width\": mm} (camera space +X right, +Y up, +Z forward); \"near_clip\" "
            "optional.");
constexpr ParamSpec kSolveCamera =
    ParamSpec::choice("solve_camera", "auto|never", "auto")
        .doc(
            "auto: a file without worldToCamera/worldToNDC that has position and depth passes "
            "gets its pinhole camera solved from them where a node downstream reads the camera "
            "(posthaste info shows the residual); never: leave such a frame without a camera.");
constexpr ParamSpec kCameraResidual =
    ParamSpec::real("camera_residual", kDefaultMaxResidualPx)
        .range(1e-6, 10.0)
        .units("px")
        .doc("Largest RMS reprojection error a solved camera may have before the read refuses.")
        .only_when("solve_camera", "auto");
constexpr ParamSpec kParams[] = {kPath,
                                 kFrameOffset,
                                 kBadPixels,
                                 kLinearize,
                                 kAliases,
                                 kView,
                                 kDeep,
                                 kConvention,
                                 kCamera,
                                 kSolveCamera,
                                 kCameraResidual};

constexpr Binding<ReadOptions> kOptionFields[] = {
    bind<&ReadOptions::bad_pixels>(kBadPixels),
    bind<&ReadOptions::linearize>(kLinearize),
    bind<&ReadOptions::view>(kView),
    bind<&ReadOptions::deep>(kDeep),
    bind<&ReadOptions::convention>(kConvention),
};
constexpr Binding<CameraSolveOptions> kSolveFields[] = {
    bind<&CameraSolveOptions::max_residual_px>(kCameraResidual),
};

ReadOptions read_options(const NodeParams &params, const NodeIdentity &node)
{
    ReadOptions o = fill(params, kOptionFields);
    o.aliases = parse_alias_rules(params.get_json(kAliases),
                                  node.json_path + "/params/aliases: " + node.describe());
    return o;
}

/// What a read node decides once for its sequence, from its parameters and the first frame's
/// header it opens.
struct ReadState {
    ReadOptions options;
    GraphCamera graph_camera;
    /// The sequence's headers carry no camera matrices but the files have position and depth:
    /// read those two passes too and solve the camera.
    bool solve = false;
    std::string no_solve_why;  ///< Why not, for the message of a node that needs the camera.
    CameraSolveOptions solve_options;
    /// The solve is reported once on stderr.
    std::shared_ptr<std::once_flag> said = std::make_shared<std::once_flag>();
};

ParamWhere camera_where(const NodeIdentity &node)
{
    return {node.json_path + "/params/camera", node.describe()};
}

/// Give the frame the graph's camera, or the one solved from its passes (where something
/// downstream reads the camera, `required`, or takes every pass, `wanted`: a write of the whole
/// file, which keeps it where the solve succeeds and goes on without one where it fails), or
/// mark the header's.
void resolve_camera(const ReadState &state,
                    const NodeContext &ctx,
                    const std::string &path,
                    bool wanted,
                    bool required,
                    Frame &frame)
{
    Camera &cam = frame.camera;
    if (state.graph_camera.given()) {
        apply_graph_camera(state.graph_camera, frame);
        return;
    }
    if (cam.world_to_camera && cam.world_to_ndc) {
        cam.origin = "the header of " + path;
        return;
    }
    if (state.solve && !wanted) {
        // Nothing downstream reads the camera (PassSet::camera): its passes were not read.
        cam.origin = "none: " + path +
                     " has no camera matrices (not solved: no node of the graph reads the camera)";
        return;
    }
    if (!state.solve || !frame.has("position") || !frame.has("depth")) {
        // Said where a node asks for the matrices: which file lacked them.
        cam.origin = "none: " + path + " has no camera matrices" +
                     (state.solve ? " and no position and depth passes" : state.no_solve_why);
        return;
    }
    CameraSolve solve;
    try {
        solve = solve_frame_camera(frame, state.solve_options, path);
    } catch (const Error &e) {
        if (required) {
            throw;
        }
        // No node reads the camera (an all-sky frame of a sequence has no surface to solve
        // from): said where a node asks for the matrices.
        cam.origin = "none: " + path + " has no camera matrices (not solved: " + e.what() + ")";
        return;
    }
    std::call_once(*state.said, [&] {
        std::fprintf(stderr,
                     "note: %s: %s: camera %s (later frames are solved likewise)\n",
                     ctx.node().describe().c_str(),
                     path.c_str(),
                     solve.describe().c_str());
    });
}

ReadState make_state(const NodeParams &params, const NodeIdentity &node, const std::string &path)
{
    ReadState s;
    s.options = read_options(params, node);
    s.graph_camera = parse_graph_camera(params.get_json(kCamera), camera_where(node));
    s.solve_options = fill(params, kSolveFields);
    if (params.get_choice(kSolveCamera) != 0) {
        s.no_solve_why = " (read's solve_camera is never)";
    } else if (!s.graph_camera.given()) {
        const FileInfo info = read_file_info(path, s.options);
        bool position = false, depth = false;
        for (const PassSource &ps : info.passes) {
            position = position || ps.pass == "position";
            depth = depth || ps.pass == "depth";
        }
        s.solve = !(info.camera.world_to_camera && info.camera.world_to_ndc) && position && depth;
        if (!(position && depth)) {
            s.no_solve_why = " and no position and depth passes";
        }
    }
    return s;
}

void execute(NodeContext &ctx)
{
    const std::string path =
        expand_frame_pattern(ctx.get_string(kPath), ctx.frame_number() + ctx.get_int(kFrameOffset));
    const PassSet &wanted = ctx.requested();
    try {
        const ReadState &state = ctx.state().get_or_create<ReadState>(
            [&] { return make_state(ctx.params(), ctx.node(), path); });
        const ReadOptions &options = state.options;
        // The solve's two passes, read for it alone where nothing downstream asked for them;
        // the solve only where something downstream reads the camera.
        const bool solve = state.solve && (wanted.all || wanted.camera);
        std::set<std::string> optional = wanted.optional;
        std::vector<std::string> only_for_solve;
        if (solve && !wanted.all) {
            for (const char *name : {"position", "depth"}) {
                if (!wanted.wants(name)) {
                    optional.insert(name);
                    only_for_solve.push_back(name);
                }
            }
        }
        std::map<std::string, std::size_t> non_finite;
        ctx.output() = read_frame(path,
                                  wanted.all ? nullptr : &wanted.names,
                                  ctx.frame_number(),
                                  options,
                                  &non_finite,
                                  &optional);
        resolve_camera(state, ctx, path, solve, solve && wanted.camera, ctx.output());
        for (const std::string &name : only_for_solve) {
            ctx.output().erase(name);
            non_finite.erase(name);
        }
        if (!non_finite.empty()) {
            // One line per frame, not one per pixel (the spatial nodes never spread them).
            std::string counts;
            for (const auto &[pass, n] : non_finite) {
                counts += (counts.empty() ? "" : ", ") + pass + " " + std::to_string(n);
            }
            std::fprintf(stderr,
                         "warning: %s: %s: NaN or infinite values kept: %s (bad_pixels: zero "
                         "replaces them, error refuses them)\n",
                         ctx.where().c_str(),
                         path.c_str(),
                         counts.c_str());
        }
    } catch (const Error &e) {
        rethrow_with_prefix(e, ctx.where() + ": ");
    }
}

void check(CheckContext &ctx)
{
    const ReadOptions options = read_options(ctx.params, ctx.node);
    parse_graph_camera(ctx.params.get_json(kCamera), camera_where(ctx.node));
    const std::string pattern = ctx.params.get_string(kPath);
    const int offset = ctx.params.get_int(kFrameOffset);
    // The first frame whose file exists must have every requested pass; frames that are missing
    // are reported by number when the run reaches them, or all at once for a dry run.
    std::string first_missing;
    std::vector<int> missing;
    bool checked = false;
    for (int frame : ctx.frames) {
        if (checked && !ctx.every_frame) {
            break;
        }
        const std::string path = expand_frame_pattern(pattern, frame + offset);
        std::error_code ec;
        if (!std::filesystem::exists(path, ec)) {
            if (first_missing.empty()) {
                first_missing = path;
            }
            missing.push_back(frame);
            continue;
        }
        if (checked) {
            continue;
        }
        checked = true;
        try {
            const FileInfo info = read_file_info(path, options);
            if (!ctx.downstream.all) {
                for (const std::string &name : ctx.downstream.names) {
                    bool found = false;
                    for (const PassSource &ps : info.passes) {
                        found = found || ps.pass == name;
                    }
                    if (!found) {
                        std::string have;
                        for (const PassSource &ps : info.passes) {
                            have += (have.empty() ? "" : ", ") + ps.pass;
                        }
                        throw_usage(ctx.node.json_path,
                                    ": ",
                                    ctx.node.describe(),
                                    ": ",
                                    path,
                                    ": no pass \"",
                                    name,
                                    "\" (have: ",
                                    have,
                                    "); a node downstream reads it",
                                    info.refusal_hint(name));
                    }
                }
            }
        } catch (const Error &e) {
            if (e.code() == ExitCode::Usage) {
                throw;
            }
            throw Error(e.code(), ctx.node.describe() + ": " + e.what());
        }
    }
    if (checked && (missing.empty() || !ctx.every_frame)) {
        return;
    }
    if (checked) {
        throw_runtime(ctx.node.describe(),
                      ": no input file for ",
                      missing.size(),
                      missing.size() == 1 ? " requested frame: " : " requested frames (first: ",
                      first_missing,
                      missing.size() == 1 ? "" : ")");
    }
    throw_runtime(ctx.node.describe(),
                  ": no input file for any requested frame (first: ",
                  first_missing,
                  ")");
}

std::vector<int> discover(const NodeParams &params)
{
    std::vector<int> frames = find_frames_on_disk(params.get_string(kPath));
    for (int &f : frames) {
        f -= params.get_int(kFrameOffset);
    }
    return frames;
}

}  // namespace

extern const NodeType kRead{
    {"read", "Read a frame sequence of EXR (or PNG/TIFF/JPEG) files.", {}, kParams, "*"},
    &execute,
    nullptr,
    &check,
    &discover,
    [](std::vector<std::string> &problems) {
        audit(kRead, kOptionFields, problems);
        audit(kRead, kSolveFields, problems);
    }};

}  // namespace posthaste::nodes
