// nodes/write.cpp: write each frame to EXR (passes, per-pass pixel type, compression, single- or
// multi-part), or to a display-referred preview (PNG, JPEG, TIFF...) through an OpenColorIO
// display transform when the path does not end in .exr. Writes are atomic.

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <set>
#include <span>

#include "filter/frame_ops.h"
#include "io/color.h"
#include "io/cryptomatte.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "nodes/node.h"

namespace posthaste::nodes {
namespace {

constexpr ParamSpec kPath =
    ParamSpec::string("path", "")
        .file_path()
        .mandatory()
        .doc("Output file or frame pattern; .exr writes passes, other extensions write a preview.");
constexpr ParamSpec kPasses =
    ParamSpec::string("passes", "*")
        .doc("EXR: comma-separated passes to write, or * for every pass the frame has.");
constexpr ParamSpec kCompression =
    ParamSpec::string("compression", "auto")
        .doc(
            "EXR compression: auto (the source part's if lossless, else zip; piz for frames not "
            "read from an EXR), none, rle, zips, zip, piz, pxr24, b44, b44a, dwaa, dwab (dwaa:45 "
            "sets a level).");
constexpr ParamSpec kLayout =
    ParamSpec::choice("layout", "auto|single|multipart", "auto")
        .doc(
            "EXR: auto keeps the source file's parts, views, channel names, pixel types and "
            "windows (single for frames not read from an EXR); single or multipart rebuild the "
            "file with canonical channel names, in one part or one part per pass.");
constexpr ParamSpec kStorage =
    ParamSpec::choice("storage", "auto|half|float", "auto")
        .doc(
            "EXR pixel type: auto keeps each source channel's type, and is half for color and "
            "albedo, float for other passes no file gave.");
constexpr ParamSpec kAllowLossyData =
    ParamSpec::boolean("allow_lossy_data", false)
        .doc(
            "Permit lossy compression (dwaa, dwab, pxr24, b44, b44a) on "
            "data passes (depth, motion, normals...).");
constexpr ParamSpec kColorSpace = ParamSpec::string("input_colorspace", "lin_rec709")
                                      .doc("Preview: color space of the color pass.");
constexpr ParamSpec kDisplay = ParamSpec::string("display", "sRGB").doc("Preview: OCIO display.");
constexpr ParamSpec kView = ParamSpec::string("view", "Standard").doc("Preview: OCIO view.");
constexpr ParamSpec kAlpha =
    ParamSpec::boolean("alpha", false)
        .doc("Preview: write alpha (unpremultiplied) as a fourth channel.");
constexpr ParamSpec kPngLevel =
    ParamSpec::integer("png_compression", 1)
        .range(0, 9)
        .doc("Preview: zlib level of a PNG (1: fast, 6: zlib's default, about 10 % smaller).");
constexpr ParamSpec kPngFilter =
    ParamSpec::choice("png_filter", "none|sub|up|average|paeth|adaptive", "none")
        .doc(
            "Preview: the PNG row filter (adaptive tries all five per row, as libpng's default; "
            "none was both faster and smaller on rendered frames, docs/PERFORMANCE.md).");
constexpr ParamSpec kDither =
    ParamSpec::boolean("dither", true)
        .doc("Preview: 8x8 ordered dither before 8-bit quantisation (no bands in gradients).");
constexpr ParamSpec kCrop =
    ParamSpec::choice("crop", "none|display", "none")
        .doc(
            "EXR: none writes the data window as it is (an overscan kept); display cuts it to the "
            "display window (the delivered format). A preview always shows the display window.");
constexpr ParamSpec kParams[] = {kPath,
                                 kCrop,
                                 kPngLevel,
                                 kPngFilter,
                                 kDither,
                                 kPasses,
                                 kCompression,
                                 kLayout,
                                 kStorage,
                                 kAllowLossyData,
                                 kColorSpace,
                                 kDisplay,
                                 kView,
                                 kAlpha};
// Every parameter but the path is of one kind of output; one of the other kind is refused.
constexpr const ParamSpec *kExrOnly[] = {
    &kPasses, &kCompression, &kLayout, &kStorage, &kAllowLossyData, &kCrop};
constexpr const ParamSpec *kPreviewOnly[] = {
    &kColorSpace, &kDisplay, &kView, &kAlpha, &kPngLevel, &kPngFilter, &kDither};
constexpr PortSpec kInputs[] = {{"image", "", false, "The frame to write."}};

bool is_preview(const NodeParams &params)
{
    return !is_exr_path(params.get_string(kPath));
}

std::vector<std::string> listed_passes(const NodeParams &params)
{
    const std::string &p = params.get_string(kPasses);
    return p == "*" ? std::vector<std::string>{} : split_list(p);
}

ColorProcessor make_display(const NodeParams &params, const NodeIdentity &node)
{
    return ColorProcessor::display_view(params.get_string(kColorSpace),
                                        params.get_string(kDisplay),
                                        params.get_string(kView),
                                        node.json_path + "/params: " + node.describe(),
                                        /*for_8bit=*/true,
                                        std::string(kColorSpace.name));
}

constexpr Binding<PreviewOptions> kPreviewFields[] = {
    bind<&PreviewOptions::alpha>(kAlpha),
    bind<&PreviewOptions::png_level>(kPngLevel),
    bind<&PreviewOptions::png_filter>(kPngFilter),
    bind<&PreviewOptions::dither>(kDither),
};
constexpr Binding<WriteOptions> kExrFields[] = {
    bind<&WriteOptions::compression>(kCompression),
    bind<&WriteOptions::layout>(kLayout),
    bind<&WriteOptions::allow_lossy_data>(kAllowLossyData),
};

/// A cryptomatte's rank layers hold 32-bit hashes: they are written as float whatever storage
/// the graph asks for the other passes (said once), and a lossy codec is refused for them.
void keep_cryptomattes_exact(NodeContext &ctx, const Frame &frame, WriteOptions &options)
{
    const std::set<std::string> ranks = cryptomatte::requested_ranks(
        {cryptomatte::request_for("")}, cryptomatte::declarations(frame), frame.pass_names());
    bool forced = false;
    for (const std::string &name : ranks) {
        auto it = options.storage.find(name);
        forced = forced || (it != options.storage.end() && it->second == PixelStorage::Half);
        options.storage[name] = PixelStorage::Float;
    }
    if (forced) {
        ctx.state().note_once(ctx.node().describe() +
                              ": cryptomatte rank layers are written as float (their IDs are "
                              "32-bit hashes), the other passes as asked");
    }
    const std::string &c = options.compression;
    if (!ranks.empty() && is_lossy_compression(c)) {
        throw_runtime(ctx.where(),
                      ": compression \"",
                      c,
                      "\" would change the IDs of cryptomatte rank layer \"",
                      *ranks.begin(),
                      "\"; choose a lossless compression (zip, piz, ...) or leave the layers out");
    }
}

void execute(NodeContext &ctx)
{
    const NodeParams &params = ctx.params();
    const Frame &frame = ctx.input("image");
    const std::string path = expand_frame_pattern(params.get_string(kPath), ctx.frame_number());
    try {
        if (is_preview(params)) {
            const ColorProcessor &display = ctx.state().get_or_create<ColorProcessor>(
                [&] { return make_display(params, ctx.node()); });
            // A preview shows the display window (the delivered format); outside the data
            // window it is transparent black.
            const PreviewOptions po = fill(params, kPreviewFields);
            write_display_preview(frame.image(pass::kColor, path),
                                  frame.data_window,
                                  frame.display_window,
                                  display,
                                  path,
                                  po);
            return;
        }
        WriteOptions options = fill(params, kExrFields);
        options.passes = listed_passes(params);
        const int storage = params.get_choice(kStorage);
        if (storage != 0) {
            for (const std::string &name : frame.pass_names()) {
                options.storage[name] = storage == 1 ? PixelStorage::Half : PixelStorage::Float;
            }
        }
        keep_cryptomattes_exact(ctx, frame, options);
        // Once a run, not once a frame (the line names neither the file nor the count).
        options.warn = [&](const std::string &line) {
            ctx.state().note_once(str_cat(ctx.node().describe(), ": ", line));
        };
        const Rect display = frame.data_window.intersect(frame.display_window);
        if (params.get_choice(kCrop) == 1 && display.empty()) {
            // (It was written uncut.) An EXR holds at least one pixel.
            const auto text = [](const Rect &r) {
                return str_cat("(", r.x0, ",", r.y0, ")-(", r.x1 - 1, ",", r.y1 - 1, ")");
            };
            throw_runtime(path,
                          ": crop display: the data window ",
                          text(frame.data_window),
                          " lies outside the display window ",
                          text(frame.display_window),
                          ", so no pixel is left to write");
        }
        if (params.get_choice(kCrop) == 1 && display != frame.data_window) {
            Frame cut = frame;
            filter::cut_data_window(frame, display, cut);
            write_exr(cut, path, options);
            return;
        }
        write_exr(frame, path, options);
    } catch (const Error &e) {
        rethrow_with_prefix(e, ctx.where() + ": ");
    }
}

void plan(PlanContext &ctx)
{
    PassSet &in = ctx.inputs[0];
    // A node reading the write's frame downstream (a write passes its input on) may read the
    // camera; the write itself only writes what the frame has.
    const bool camera = ctx.downstream.camera;
    in = PassSet{};
    in.camera = camera;
    if (is_preview(ctx.params)) {
        in.add(pass::kColor);
        return;
    }
    const std::vector<std::string> passes = listed_passes(ctx.params);
    if (passes.empty()) {
        in.all = true;
    }
    for (const std::string &p : passes) {
        in.add(p);
    }
}

void check(CheckContext &ctx)
{
    const std::string where = ctx.node.json_path + "/params: " + ctx.node.describe();
    const std::string path = ctx.params.get_string(kPath);
    // A parameter of the other kind of output is refused where given: it was ignored, also
    // when invalid (a preview asked for passes: albedo showed colour).
    const bool preview = is_preview(ctx.params);
    using Kind = std::span<const ParamSpec *const>;
    for (const ParamSpec *p : preview ? Kind(kExrOnly) : Kind(kPreviewOnly)) {
        if (ctx.params.given(*p)) {
            throw_param(ctx,
                        *p,
                        preview ? "applies only to EXR outputs, not to a preview (" + path + ")"
                                : "applies only to previews, not to an EXR (" + path + ")");
        }
    }
    if (preview) {
        make_display(ctx.params, ctx.node);
        auto out = OIIO::ImageOutput::create(path);
        if (!out) {
            throw_param_expected(ctx, kPath, "a .exr, .png, .jpg or .tif file", quoted(path));
        }
        // Before any frame: a JPEG dropped the alpha without a word, a PPM failed at frame 1.
        if (ctx.params.get_bool(kAlpha) && !out->supports("alpha")) {
            throw_param(ctx,
                        kAlpha,
                        str_cat("a ",
                                out->format_name(),
                                " preview has no alpha channel (",
                                path,
                                "; a .png or .tif has)"));
        }
    }
    if (ctx.frames.size() > 1 && !has_frame_placeholder(path)) {
        throw_param(ctx,
                    kPath,
                    str_cat(quoted(path),
                            " has no frame placeholder (####) but ",
                            ctx.frames.size(),
                            " frames would be written to it"));
    }
    if (preview) {
        return;
    }
    check_compression(ctx.params.get_string(kCompression), where + ": param \"compression\"");
    if (listed_passes(ctx.params).empty() && ctx.params.get_string(kPasses) != "*") {
        throw_param(ctx, kPasses, "lists no pass (* writes every pass the frame has)");
    }
    std::vector<std::string> listed = listed_passes(ctx.params);
    std::sort(listed.begin(), listed.end());
    if (const auto twice = std::adjacent_find(listed.begin(), listed.end());
        twice != listed.end()) {
        throw_param(ctx, kPasses, str_cat("lists \"", *twice, "\" twice"));
    }
}

}  // namespace

extern const NodeType kWrite{
    {"write",
     "Write frames to EXR, or previews through an OCIO display.",
     kInputs,
     kParams,
     "",
     /*sink=*/true,
     /*keeps_specular=*/true},
    &execute,
    &plan,
    &check,
    nullptr,
    [](std::vector<std::string> &problems) {
        audit(kWrite, kPreviewFields, problems);
        audit(kWrite, kExrFields, problems);
        for (const ParamSpec &p : kParams) {
            const auto of = [&](std::span<const ParamSpec *const> kind) {
                return std::count_if(kind.begin(), kind.end(), [&](const ParamSpec *k) {
                    return k->name == p.name;
                });
            };
            if (p.name != kPath.name && of(kExrOnly) + of(kPreviewOnly) != 1) {
                problems.push_back(
                    str_cat("write: param \"", p.name, "\" is not of exactly one kind of output"));
            }
        }
    }};

}  // namespace posthaste::nodes
