// Reading frames: OpenImageIO for flat files (every part, tiled or scanline, at native pixel
// types), OpenEXR's RGBA interface for luminance/chroma files, and deep files flattened front to
// back. Windows, views and the file's layout come along (io/source_file.h).

#include <OpenImageIO/deepdata.h>
#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "core/memory.h"
#include "core/passes.h"
#include "core/text.h"
#include "io/cryptomatte.h"
#include "io/image_file.h"
#include "io/io_detail.h"
#include "io/read_detail.h"
#include "io/source_file.h"

namespace posthaste {

using namespace io_detail;

namespace {

bool has_exr_magic(const std::string &path)
{
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec)) {
        return false;  // a FIFO would block the read
    }
    std::ifstream f(path, std::ios::binary);
    unsigned char m[4] = {};
    f.read(reinterpret_cast<char *>(m), 4);
    return f && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01;
}

struct Opened {
    std::unique_ptr<OIIO::ImageInput> in;  ///< Null for luminance/chroma files.
    FileInfo info;
    std::vector<OIIO::ImageSpec> specs;
    bool single_part_views = false;
    std::vector<ExrPartLayout> layouts;  ///< An EXR's parts as the header walk read them.
};

Opened open_file(const std::string &path, const ReadOptions &options)
{
    Opened o;
    // OpenImageIO refuses luminance/chroma files (subsampled channels); only then is the file
    // asked whether it is one (opening it through OpenEXR's RGBA interface costs a header read).
    try {
        o.in = open_input(path, &o.layouts);
    } catch (const Error &) {
        if (!has_exr_magic(path) || !is_luminance_chroma(path)) {
            throw;
        }
        o.info = luminance_chroma_info(path);
        std::vector<PartChannels> parts(1);
        for (const FileChannel &c : o.info.parts[0].channels) {
            parts[0].names.push_back(c.name);
        }
        o.info.passes = map_channels(parts, options.aliases, options.convention);
        return o;
    }
    FileInfo &info = o.info;
    info.path = path;
    info.format = o.in->format_name();
    for (int sub = 0; o.in->seek_subimage(sub, 0); ++sub) {
        const OIIO::ImageSpec &spec = o.in->spec();
        if (spec.nchannels <= 0) {
            throw_runtime(path, ": part ", sub, " has no channels");
        }
        FilePart part;
        part.name = spec.get_string_attribute("name");
        part.view = spec.get_string_attribute("view");
        part.deep = spec.deep;
        part.tiled = spec.tile_width > 0;
        part.tile_width = spec.tile_width;
        part.tile_height = spec.tile_height;
        part.compression = spec.get_string_attribute("compression");
        const std::string tex = spec.get_string_attribute("textureformat");
        part.envmap = tex == "CubeFace Environment"  ? "cube"
                      : tex == "LatLong Environment" ? "latlong"
                                                     : "";
        part.display_window = {spec.full_x,
                               spec.full_y,
                               spec.full_x + spec.full_width,
                               spec.full_y + spec.full_height};
        part.data_window = {spec.x, spec.y, spec.x + spec.width, spec.y + spec.height};
        check_window(path, sub, "data", part.data_window);
        check_window(path, sub, "display", part.display_window);
        for (int c = 0; c < spec.nchannels; ++c) {
            part.channels.push_back(
                {spec.channel_name(c), type_name(spec.channelformat(c)), "", 1, 1});
        }
        while (o.in->seek_subimage(sub, part.mip_levels)) {
            ++part.mip_levels;
        }
        part.level_mode = part.mip_levels > 1 ? "mipmap" : "";
        // OpenImageIO shows a ripmap as a chain of levels all of level 0's size.
        const int width0 = spec.width, height0 = spec.height;  // `spec` follows the seeks
        if (part.mip_levels > 1 && o.in->seek_subimage(sub, 1) && o.in->spec().width == width0 &&
            o.in->spec().height == height0) {
            part.level_mode = "ripmap";
            const bool up = o.in->spec().get_int_attribute("openexr:roundingmode", 0) == 1;
            auto levels = [up](int n) {
                int count = 1;
                for (; n > 1; ++count) {
                    n = up ? (n + 1) / 2 : n / 2;
                }
                return count;
            };
            part.rip_levels = {levels(width0), levels(height0)};
        }
        o.in->seek_subimage(sub, 0);
        if (sub == 0) {
            info.display_window = part.display_window;
        } else if (part.display_window != info.display_window) {
            throw_runtime(path,
                          ": part ",
                          sub,
                          " has display window (",
                          part.display_window.x0,
                          ", ",
                          part.display_window.y0,
                          ") ",
                          part.display_window.width(),
                          "x",
                          part.display_window.height(),
                          " but part 0 has (",
                          info.display_window.x0,
                          ", ",
                          info.display_window.y0,
                          ") ",
                          info.display_window.width(),
                          "x",
                          info.display_window.height());
        }
        o.in->seek_subimage(sub, 0);
        o.specs.push_back(o.in->spec());
        info.parts.push_back(std::move(part));
    }
    if (info.parts.empty()) {
        throw_runtime(path, ": no image in file");
    }
    const bool deep =
        std::any_of(info.parts.begin(), info.parts.end(), [](const FilePart &p) { return p.deep; });
    if (deep) {
        if (options.deep == DeepMode::Error) {
            throw_runtime(path, ": part 0 is deep and the read's deep mode is \"error\"");
        }
        info.conversion = "deep, flattened";
        for (std::size_t p = 0; p < info.parts.size(); ++p) {
            if (!info.parts[p].deep) {
                throw_runtime(path, ": part ", p, " is flat in a deep file (not supported)");
            }
        }
    }
    std::vector<MappedChannel> channels;
    assign_views(o.specs, info, channels, o.single_part_views);
    if (!options.view.empty()) {
        if (std::find(info.views.begin(), info.views.end(), options.view) == info.views.end()) {
            throw_runtime(
                path,
                ": no view \"",
                options.view,
                "\" (",
                info.views.empty() ? "the file has no views" : "have: " + join(info.views),
                ")");
        }
        info.view = options.view;
    } else if (!info.views.empty()) {
        const bool has_multi_view = o.specs[0].find_attribute("multiView") != nullptr;
        const bool viewless_part = std::any_of(
            info.parts.begin(), info.parts.end(), [](const FilePart &p) { return p.view.empty(); });
        info.view = has_multi_view || !viewless_part ? info.views[0] : "";
    }
    // The camera and attributes of the chosen view's first part.
    std::size_t camera_part = 0;
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        if (info.parts[p].view == info.view) {
            camera_part = p;
            break;
        }
    }
    read_camera(o.specs[camera_part], info.camera);
    for (const OIIO::ParamValue &p : o.specs[camera_part].extra_attribs) {
        const std::string n = p.name().string();
        // Exif metadata of a PNG, TIFF or JPEG describes that image; an EXR's is its header's.
        const bool foreign_exif = n.rfind("Exif:", 0) == 0 && info.format != "openexr";
        if (is_frame_attribute(n) && !foreign_exif) {
            info.attributes.push_back(p);
        }
    }
    std::vector<const OIIO::ParamValueList *> other_parts;
    for (const OIIO::ImageSpec &spec : o.specs) {
        other_parts.push_back(&spec.extra_attribs);
    }
    info.cryptomattes = cryptomatte::with_declarations_of(info.attributes, other_parts);
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        if (p != camera_part) {
            info.parts[p].own_attributes = own_attributes(o.specs[p], info.attributes);
        }
    }
    if (deep) {
        // Flattened deep channels: Z is the nearest sample's, ZBack is dropped.
        for (MappedChannel &m : channels) {
            if (m.name == "ZBack") {
                m.view = "\x01";  // in no view: not mapped
            }
        }
    }
    info.passes = map_views(info, channels, options.aliases, options.convention, &info.refused);
    info.data_window = {};
    for (const FilePart &p : info.parts) {
        info.data_window = info.data_window.unite(p.data_window);
    }
    return o;
}

}  // namespace

std::string verify_image_file(const std::string &path)
{
    try {
        Opened o = open_file(path, ReadOptions{});
        if (!o.in) {
            read_luminance_chroma(path, o.info.parts[0]);
            return "";
        }
        check_image_ends(path, o.info.format);
        for (std::size_t p = 0; p < o.info.parts.size(); ++p) {
            const FilePart &part = o.info.parts[p];
            if (part.deep) {
                OIIO::DeepData deep;
                if (!o.in->read_native_deep_image(int(p), 0, deep)) {
                    throw_runtime(path, ": deep part ", p, ": ", o.in->geterror());
                }
                continue;
            }
            const bool rip = part.level_mode == "ripmap";
            for (int level = 0; level < (rip ? 1 : part.mip_levels); ++level) {
                if (!o.in->seek_subimage(int(p), level)) {
                    throw_runtime(path, ": part ", p, " level ", level, ": cannot seek");
                }
                const OIIO::ImageSpec spec = o.in->spec();
                const auto buf = raw_bytes(
                    spec.image_bytes(/*native=*/true), spec.width, spec.height, spec.nchannels);
                if (!o.in->read_image(
                        int(p), level, 0, spec.nchannels, OIIO::TypeUnknown, buf.get())) {
                    std::string err = o.in->geterror();
                    std::replace(err.begin(), err.end(), '\n', ' ');
                    throw_runtime(path, ": part ", p, " level ", level, ": ", err);
                }
            }
            if (rip) {
                read_ripmap_levels(path, int(p), o.specs[p]);
            }
        }
        return "";
    } catch (const std::exception &e) {
        std::string m = e.what();
        std::replace(m.begin(), m.end(), '\n', ' ');
        return m;
    }
}

FileInfo read_file_info(const std::string &path, const ReadOptions &options)
{
    Opened o = open_file(path, options);
    if (options.count_deep_samples && o.in) {
        for (std::size_t p = 0; p < o.info.parts.size(); ++p) {
            FilePart &part = o.info.parts[p];
            if (!part.deep) {
                continue;
            }
            OIIO::DeepData deep;
            if (!o.in->read_native_deep_image(int(p), 0, deep)) {
                throw_runtime(path, ": cannot read deep part ", p, ": ", o.in->geterror());
            }
            part.deep_samples = 0;
            part.deep_max_samples = 0;
            for (std::int64_t i = 0; i < deep.pixels(); ++i) {
                const int n = int(deep.samples(i));
                part.deep_samples += n;
                part.deep_max_samples = std::max(part.deep_max_samples, n);
            }
        }
    }
    return std::move(o.info);
}

Frame read_frame(const std::string &path,
                 const std::set<std::string> *wanted,
                 int frame_number,
                 const ReadOptions &options,
                 std::map<std::string, std::size_t> *non_finite,
                 const std::set<std::string> *optional)
{
    Opened o = open_file(path, options);
    const FileInfo &info = o.info;
    std::vector<const PassSource *> selected;
    if (wanted) {
        for (const std::string &name : *wanted) {
            auto it = std::find_if(info.passes.begin(),
                                   info.passes.end(),
                                   [&](const PassSource &p) { return p.pass == name; });
            if (it == info.passes.end()) {
                std::string have;
                for (const PassSource &p : info.passes) {
                    have += (have.empty() ? "" : ", ") + p.pass;
                }
                throw_runtime(path,
                              ": no pass \"",
                              name,
                              "\" in file (have: ",
                              have,
                              ")",
                              info.refusal_hint(name));
            }
            selected.push_back(&*it);
        }
        // Optional passes the file has; "cryptomatte:<type>" asks for the rank layers of the
        // cryptomattes its header declares (every one for an empty type).
        std::set<std::string> also;
        if (optional) {
            std::vector<std::string> names;
            for (const PassSource &p : info.passes) {
                names.push_back(p.pass);
            }
            for (const std::string &request : *optional) {
                std::string type;
                if (!cryptomatte::parse_request(request, type)) {
                    also.insert(request);
                    continue;
                }
                for (const cryptomatte::Layer &l :
                     cryptomatte::find_layers(info.cryptomattes, path)) {
                    if (l.problem.empty() && (type.empty() || l.is(type))) {
                        for (const std::string &rank : cryptomatte::rank_passes(l, names, path)) {
                            also.insert(rank);
                        }
                    }
                }
            }
        }
        for (const PassSource &p : info.passes) {
            if (also.count(p.pass) != 0 && wanted->count(p.pass) == 0) {
                selected.push_back(&p);
            }
        }
    } else {
        for (const PassSource &p : info.passes) {
            selected.push_back(&p);
        }
    }

    // Which channels of which parts are needed, and the frame's data window: the union of the
    // windows of the parts read (part 0's when nothing is read).
    std::vector<std::set<int>> needed(info.parts.size());
    for (const PassSource *ps : selected) {
        for (const ChannelSource &cs : ps->sources) {
            if (cs.part >= 0) {
                needed[std::size_t(cs.part)].insert(cs.channel);
            }
        }
    }
    Rect window;
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        if (!needed[p].empty()) {
            window = window.unite(info.parts[p].data_window);
        }
    }
    if (window.empty()) {
        window = info.parts[0].data_window;
    }
    if (window.width() > kMaxImageSide || window.height() > kMaxImageSide ||
        std::int64_t(window.width()) * window.height() > kMaxFilePixels) {
        throw_runtime(path,
                      ": the parts' data windows together span ",
                      window.width(),
                      "x",
                      window.height(),
                      " (limit ",
                      kMaxImageSide,
                      " per side, ",
                      kMaxFilePixels,
                      " pixels)");
    }

    Frame frame;
    frame.number = frame_number;
    frame.display_window = info.display_window;
    frame.data_window = window;
    frame.camera = info.camera;
    for (const std::string &view : info.views) {
        for (std::size_t p = 0; p < info.parts.size() && view != info.view; ++p) {
            if (info.parts[p].view == view) {
                Camera c;
                read_camera(o.specs[p], c);
                if (!(c == Camera{})) {
                    frame.view_cameras[view] = c;
                }
                break;
            }
        }
    }
    frame.attributes = info.attributes;
    const bool keep_layout = o.in && info.format == "openexr" && info.conversion.empty();
    std::shared_ptr<SourceFile> source;
    if (keep_layout) {
        source = std::make_shared<SourceFile>();
        source->path = path;
        source->views = info.views;
        source->view = info.view;
        source->single_part_views = o.single_part_views;
        source->camera = info.camera;
    }

    // The parts' pixels: deep and luminance/chroma parts whole, as converted floats; flat parts
    // band by band below, at native types.
    std::vector<PartPixels> data(info.parts.size());
    std::vector<char> banded(info.parts.size(), 0);
    bool srgb_encoded = false;
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        const FilePart &part = info.parts[p];
        const bool whole = int(needed[p].size()) == int(part.channels.size());
        if (!o.in) {
            if (!needed[p].empty()) {
                data[p] = read_luminance_chroma(path, part);
            }
            continue;
        }
        const OIIO::ImageSpec &spec = o.specs[p];
        if (source) {
            SourcePart sp;
            sp.spec = spec;
            // The line order, which OpenImageIO does not report, from the header walk.
            const std::vector<ExrPartLayout> &layouts = o.layouts;
            if (p < layouts.size() && layouts[p].line_order == 1) {
                sp.spec.attribute("openexr:lineOrder", "decreasingY");
            } else if (p < layouts.size() && layouts[p].line_order == 2) {
                sp.spec.attribute("openexr:lineOrder", "randomY");
            }
            if (p < layouts.size()) {
                sp.attributes = layouts[p].attributes;
            }
            sp.name = part.name;
            sp.view = part.view;
            sp.mip_levels = part.mip_levels;
            sp.ripmap = part.level_mode == "ripmap";  // levels made again stay a ripmap
            for (const FileChannel &c : part.channels) {
                sp.channel_views.push_back(c.view);
            }
            source->parts.push_back(std::move(sp));
        }
        if (needed[p].empty()) {
            continue;
        }
        if (part.deep) {
            data[p] = flatten_deep(*o.in, int(p), path);
            continue;
        }
        PartPixels &pd = data[p];
        pd.chbegin = *needed[p].begin();
        pd.chend = *needed[p].rbegin() + 1;
        for (int c = pd.chbegin; c < pd.chend; ++c) {
            const OIIO::TypeDesc t = spec.channelformat(c);
            if (!supported_native(t)) {
                throw_runtime(path,
                              ": channel \"",
                              spec.channel_name(c),
                              "\" has pixel type ",
                              t.c_str(),
                              ", which is not supported");
            }
            pd.channels.push_back({pd.pixel_bytes, t});
            pd.pixel_bytes += t.size();
        }
        pd.bytes = std::size_t(spec.width) * std::size_t(spec.height) * pd.pixel_bytes;
        banded[p] = 1;
        // Lower mip levels of a part read whole travel as read, for an untouched write.
        if (source && whole && part.level_mode == "ripmap") {
            source->parts.back().levels = read_ripmap_levels(path, int(p), spec);
        } else if (source && whole && part.mip_levels > 1 && part.level_mode == "mipmap") {
            for (int level = 1; level < part.mip_levels; ++level) {
                if (!o.in->seek_subimage(int(p), level)) {
                    break;
                }
                SourceLevel sl;
                sl.spec = o.in->spec();
                auto buf = std::make_shared<std::vector<unsigned char>>(
                    std::size_t(sl.spec.width) * std::size_t(sl.spec.height) *
                    sl.spec.pixel_bytes(/*native=*/true));
                if (!o.in->read_image(
                        int(p), level, 0, sl.spec.nchannels, OIIO::TypeUnknown, buf->data())) {
                    throw_runtime(path, ": part ", p, " level ", level, ": ", o.in->geterror());
                }
                sl.pixels = std::move(buf);
                sl.lx = sl.ly = level;
                source->parts.back().levels.push_back(std::move(sl));
            }
        }
        if (p == 0 && is_integer_type(spec.format) && options.linearize) {
            const std::string cs = spec.get_string_attribute("oiio:ColorSpace", "sRGB");
            srgb_encoded = cs.empty() || OIIO::Strutil::iequals(cs, "sRGB");
        }
    }

    // The passes, and the file's bits of the channels a float cannot give back (one native
    // plane each, filled as the rows arrive).
    const int width = window.width(), height = window.height();
    const bool count_kept = non_finite && options.bad_pixels == BadPixels::Keep;
    FrameRows rows(path, info, window, options, count_kept);
    std::vector<FrameRows::Out> &outs = rows.outs;
    for (const PassSource *ps : selected) {
        // Depths (the surface's and the reflected one's): +inf is the sky, not a bad value.
        const std::string base = ps->pass.substr(0, ps->pass.find('@'));
        const bool is_depth = base == pass::kDepth || base == pass::kSpecularDepth;
        outs.push_back({ps,
                        Image::uninitialized(width, height, int(ps->sources.size())),
                        is_depth,
                        srgb_encoded && ps->pass == pass::kColor,
                        std::vector<std::pair<int, int>>(std::size_t(height), {-1, -1}),
                        std::vector<std::size_t>(std::size_t(height), 0)});
    }
    if (source) {
        for (const FrameRows::Out &out : outs) {
            for (const ChannelSource &cs : out.ps->sources) {
                if (cs.part < 0) {
                    continue;
                }
                const PartPixels &pd = data[std::size_t(cs.part)];
                const auto &nc = pd.channels[std::size_t(cs.channel - pd.chbegin)];
                const auto key = std::make_pair(cs.part, cs.channel);
                if (float_reproduces(nc.type, cs, *out.ps, out.linearize) ||
                    source->raw.count(key)) {
                    continue;
                }
                const std::size_t n = pd.bytes / pd.pixel_bytes, size = nc.type.size();
                auto plane = std::make_shared<std::vector<unsigned char>>(n * size);
                rows.raw_planes[std::size_t(cs.part)].push_back({nc.offset, size, plane->data()});
                source->raw[key] = std::move(plane);
            }
        }
    }
    rows.fill_uncovered();
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        if (!needed[p].empty()) {
            rows.read_part(
                banded[p] ? o.in.get() : nullptr, banded[p] ? &o.specs[p] : nullptr, p, data[p]);
        }
    }

    for (FrameRows::Out &out : outs) {
        const PassSource *ps = out.ps;
        for (int y = 0; y < height; ++y) {
            if (out.bad[std::size_t(y)].first >= 0) {
                const auto [x, k] = out.bad[std::size_t(y)];
                throw_runtime(path,
                              ": pass \"",
                              ps->pass,
                              "\" channel \"",
                              ps->sources[std::size_t(k)].name,
                              "\" has a NaN or infinite value at (",
                              x + window.x0,
                              ", ",
                              y + window.y0,
                              ")");
            }
        }
        if (count_kept) {
            std::size_t n = 0;
            for (std::size_t k : out.kept) {
                n += k;
            }
            if (n) {
                (*non_finite)[ps->pass] = n;
            }
        }
        Pass pass;
        pass.image = std::make_shared<const Image>(std::move(out.img));
        pass.channels = ps->channel_suffixes;
        if (source) {
            pass.as_read = pass.image;
            for (const ChannelSource &cs : ps->sources) {
                pass.origin.push_back({cs.part, cs.channel, cs.scale, cs.offset});
            }
        }
        frame.set_pass(ps->pass, std::move(pass));
    }
    frame.source = std::move(source);
    return frame;
}

}  // namespace posthaste
