// nodes/read.cpp: read a frame sequence (multi-layer or multi-part EXR; PNG/TIFF/JPEG as color).
// Produces exactly the passes that nodes downstream read, mapped from other tools' channel names
// by the alias rules (io/aliases.h); camera and header attributes come along.

#include <cstdio>
#include <filesystem>
#include <map>

#include "io/image_file.h"
#include "io/sequence.h"
#include "nodes/node.h"

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
constexpr ParamSpec kParams[] = {
    kPath, kFrameOffset, kBadPixels, kLinearize, kAliases, kView, kDeep, kConvention};

ReadOptions read_options(const NodeParams &params, const NodeIdentity &node)
{
    ReadOptions o;
    o.aliases = parse_alias_rules(params.get_json(kAliases),
                                  node.json_path + "/params/aliases: " + node.describe());
    o.bad_pixels = BadPixels(params.get_choice(kBadPixels));
    o.linearize = params.get_bool(kLinearize);
    o.view = params.get_string(kView);
    o.deep = DeepMode(params.get_choice(kDeep));
    o.convention = params.get_string(kConvention);
    return o;
}

void execute(NodeContext &ctx)
{
    const ReadOptions &options = ctx.state().get_or_create<ReadOptions>(
        [&] { return read_options(ctx.params(), ctx.node()); });
    const std::string path =
        expand_frame_pattern(ctx.get_string(kPath), ctx.frame_number() + ctx.get_int(kFrameOffset));
    const PassSet &wanted = ctx.requested();
    try {
        std::map<std::string, std::size_t> non_finite;
        ctx.output() = read_frame(path,
                                  wanted.all ? nullptr : &wanted.names,
                                  ctx.frame_number(),
                                  options,
                                  &non_finite,
                                  &wanted.optional);
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
        throw Error(e.code(), ctx.where() + ": " + e.what());
    }
}

void check(CheckContext &ctx)
{
    const ReadOptions options = read_options(ctx.params, ctx.node);
    const std::string pattern = ctx.params.get_string(kPath);
    const int offset = ctx.params.get_int(kFrameOffset);
    // The first frame whose file exists must have every requested pass; frames that are missing
    // are reported by number when the run reaches them.
    std::string first_missing;
    for (int frame : ctx.frames) {
        const std::string path = expand_frame_pattern(pattern, frame + offset);
        std::error_code ec;
        if (!std::filesystem::exists(path, ec)) {
            if (first_missing.empty()) {
                first_missing = path;
            }
            continue;
        }
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
        return;
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
    &discover};

}  // namespace posthaste::nodes
