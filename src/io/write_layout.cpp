// The EXR writer's output layout (io/write_layout.h): which parts and channels a frame is written
// as, their pixel types, windows and header attributes.

#include "io/write_layout.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <set>

#include "core/error.h"
#include "core/passes.h"
#include "io/io_detail.h"

namespace posthaste::io_detail {

namespace {

OIIO::TypeDesc storage_type(PixelStorage s)
{
    return s == PixelStorage::Half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT;
}

/// The storage asked for a pass: the write's per-pass setting, else the pass's own hint.
PixelStorage asked_storage(const std::string &name, const Pass &p, const WriteOptions &options)
{
    if (auto it = options.storage.find(name); it != options.storage.end()) {
        return it->second;
    }
    return p.storage;
}

PixelStorage default_storage(const std::string &name)
{
    const std::string base = name.substr(0, name.find('@'));
    const pass::CanonicalPass *cp = pass::find_canonical(base);
    return cp && cp->half_by_default ? PixelStorage::Half : PixelStorage::Float;
}

bool is_data_pass(const std::string &name)
{
    const std::string base = name.substr(0, name.find('@'));
    return !(base == pass::kColor || base == pass::kAlbedo);
}

OIIO::ImageSpec fresh_spec(const Frame &frame)
{
    OIIO::ImageSpec spec(1, 1, 1, OIIO::TypeDesc::FLOAT);
    for (const OIIO::ParamValue &p : frame.attributes) {
        spec.extra_attribs.push_back(p);
    }
    write_camera(frame.camera, spec);
    return spec;
}

/// Insert a view into a channel name, OpenEXR's single-part multi-view way ("N.X" -> "N.right.X",
/// "R" -> "right.R").
std::string with_view(const std::string &name, const std::string &view)
{
    const auto dot = name.rfind('.');
    return dot == std::string::npos ? view + "." + name
                                    : name.substr(0, dot) + "." + view + name.substr(dot);
}

/// The name of a channel next to `sibling` in the same layer: "ViewLayer.Combined.R" + "A" ->
/// "ViewLayer.Combined.A".
std::string sibling_name(const std::string &sibling, const std::string &suffix)
{
    const auto dot = sibling.rfind('.');
    return dot == std::string::npos ? suffix : sibling.substr(0, dot + 1) + suffix;
}

void add_channel(OutPart &part, OutChannel c, const std::string &path)
{
    if (part.find(c.name) >= 0) {
        throw_runtime(path,
                      ": two passes would write channel \"",
                      c.name,
                      "\" (pass \"",
                      c.pass,
                      "\" and pass \"",
                      part.channels[std::size_t(part.find(c.name))].pass,
                      "\"); rename one with a channels node");
    }
    part.channels.push_back(std::move(c));
}

/// True when every value of channel k equals `v` (a constant channel a node left alone).
bool channel_is(const Image &img, int k, float v)
{
    const std::size_t n = img.pixel_count(), nch = std::size_t(img.channels());
    for (std::size_t i = 0; i < n; ++i) {
        if (img.data()[i * nch + std::size_t(k)] != v) {
            return false;
        }
    }
    return true;
}

/// True when channel k, mapped back through its origin, holds only whole numbers a uint channel
/// stores exactly (a node that moved ids by the nearest pixel, as lens and transform do).
bool holds_uints(const Image &img, int k, const ChannelOrigin &o)
{
    if (o.scale != 1.0f || o.offset != 0.0f) {
        return false;
    }
    const std::size_t n = img.pixel_count(), nch = std::size_t(img.channels());
    for (std::size_t i = 0; i < n; ++i) {
        const float v = img.data()[i * nch + std::size_t(k)];
        if (!(v >= 0.0f && v <= 4294967295.0f) || v != std::floor(v)) {
            return false;
        }
    }
    return true;
}

/// True for a luminance file's colour (R, G and B read from one Y channel) that a node left gray,
/// bit for bit: its Y channel takes it back alone. A node that made it coloured writes RGB.
bool gray_from_one_channel(const Pass &p)
{
    const std::size_t nch = std::size_t(p.image->channels());
    if (p.origin.size() < 3 || nch < 3 || p.origin[0].part < 0) {
        return false;
    }
    const ChannelOrigin &o = p.origin[0];
    for (std::size_t k = 1; k < 3; ++k) {
        const ChannelOrigin &q = p.origin[k];
        if (q.part != o.part || q.channel != o.channel || q.scale != o.scale ||
            q.offset != o.offset) {
            return false;
        }
    }
    const float *d = p.image->data();
    for (std::size_t i = 0, n = p.image->pixel_count(); i < n; ++i) {
        const float *px = d + i * nch;
        if (std::memcmp(px, px + 1, sizeof(float)) != 0 ||
            std::memcmp(px, px + 2, sizeof(float)) != 0) {
            return false;
        }
    }
    return true;
}

/// Samples of `size` bytes over `cut` from samples over `from` (row-major): where `cut`
/// reaches beyond `from` (a part a node widened) the samples are zero, as the reader fills a
/// window's outside.
std::shared_ptr<const std::vector<unsigned char>> slice_samples(
    const std::vector<unsigned char> &samples, std::size_t size, const Rect &from, const Rect &cut)
{
    auto out = std::make_shared<std::vector<unsigned char>>(std::size_t(cut.width()) *
                                                            std::size_t(cut.height()) * size);
    const Rect both = cut.intersect(from);
    if (both.empty()) {
        return out;
    }
    const std::size_t row = std::size_t(both.width()) * size;
    for (int y = both.y0; y < both.y1; ++y) {
        const std::size_t at = (std::size_t(y - from.y0) * std::size_t(from.width()) +
                                std::size_t(both.x0 - from.x0)) *
                               size;
        const std::size_t to =
            (std::size_t(y - cut.y0) * std::size_t(cut.width()) + std::size_t(both.x0 - cut.x0)) *
            size;
        std::memcpy(out->data() + to, samples.data() + at, row);
    }
    return out;
}

/// True when channel k of `img` (over `frame`) holds other than `outside` somewhere outside
/// `inner` (bit for bit: a NaN differs).
bool differs_outside(const Image &img, int k, const Rect &frame, const Rect &inner, float outside)
{
    const std::size_t nch = std::size_t(img.channels());
    std::uint32_t want;
    std::memcpy(&want, &outside, sizeof(want));
    for (int y = frame.y0; y < frame.y1; ++y) {
        const bool row_inside = y >= inner.y0 && y < inner.y1;
        const float *row = img.pixel(0, y - frame.y0);
        for (int x = frame.x0; x < frame.x1; ++x) {
            if (row_inside && x >= inner.x0 && x < inner.x1) {
                x = inner.x1 - 1;  // skip the inside
                continue;
            }
            std::uint32_t bits;
            std::memcpy(&bits, row + std::size_t(x - frame.x0) * nch + std::size_t(k), 4);
            if (bits != want) {
                return true;
            }
        }
    }
    return false;
}

/// A channel written under a canonical name with storage "auto" keeps the pixel type of the
/// file's channel it came from: half and float as they were, a uint id while it holds whole
/// numbers (from the file's own samples where a float cannot hold them, over `window`).
void set_source_type(OutChannel &c, const Pass &p, int k, const SourceFile &src, const Rect &window)
{
    const ChannelOrigin &o = p.origin[std::size_t(k)];
    if (o.part < 0 || o.part >= int(src.parts.size())) {
        return;
    }
    const SourcePart &sp = src.parts[std::size_t(o.part)];
    const OIIO::TypeDesc file_type = sp.spec.channelformat(o.channel);
    if (file_type.basetype == OIIO::TypeDesc::HALF || file_type.basetype == OIIO::TypeDesc::FLOAT) {
        c.type = file_type;
        return;
    }
    if (file_type.basetype != OIIO::TypeDesc::UINT || !holds_uints(*p.image, k, o)) {
        return;
    }
    const auto raw = src.raw.find({o.part, o.channel});
    if (raw == src.raw.end()) {
        c.type = file_type;  // the floats hold the ids exactly
    } else if (p.untouched()) {
        c.type = file_type;  // ids beyond 2^24: the file's own
        c.raw_slice = slice_samples(*raw->second, file_type.size(), sp.data_window(), window);
        c.raw = c.raw_slice.get();
    }
}

/// Add the pass `name` to `part` under canonical channel names ("N.X"; with `view`, OpenEXR's
/// single-part multi-view names "N.right.X"). `layer` names the channels: the pass's name, or
/// for another view's pass ("N@right") its base name.
void add_canonical(OutPart &part,
                   const std::string &name,
                   const Pass &p,
                   const WriteOptions &options,
                   const std::string &view,
                   const std::string &path,
                   const std::string &layer,
                   const SourceFile *src)
{
    PixelStorage s = asked_storage(name, p, options);
    const bool auto_storage = s == PixelStorage::Auto;
    if (auto_storage) {
        s = default_storage(name);
    }
    std::vector<std::string> exr = pass::exr_channel_names(layer, p.channels);
    const bool sourced = std::any_of(p.origin.begin(), p.origin.end(), [](const ChannelOrigin &o) {
        return o.part >= 0 || o.part == kRenamedPart;
    });
    const bool gray = gray_from_one_channel(p);  // a luminance file's: Y again
    if (gray) {
        exr[0] = pass::exr_channel_names(layer, {"Y"})[0];
    }
    for (std::size_t k = 0; k < exr.size(); ++k) {
        if (gray && (k == 1 || k == 2)) {
            continue;
        }
        // A constant the reader made up beside channels of the file (alpha of an RGB file)
        // stays out here too, unless a node made it vary.
        if (sourced && k < p.origin.size() && p.origin[k].part == -1 &&
            (p.untouched() || channel_is(*p.image, int(k), p.origin[k].offset))) {
            continue;
        }
        OutChannel c;
        c.name = view.empty() ? exr[k] : with_view(exr[k], view);
        c.type = storage_type(s);
        if (auto_storage && src && k < p.origin.size()) {
            set_source_type(c, p, int(k), *src, part.data_window);
        }
        c.pass = name;
        c.data_pass = is_data_pass(name);
        c.untouched = p.untouched();  // (what a stale preview is judged by; values as the pass)
        c.image = p.image.get();
        c.k = int(k);
        add_channel(part, std::move(c), path);
    }
}

}  // namespace

std::vector<std::string> passes_to_write(const Frame &frame, const WriteOptions &options)
{
    std::vector<std::string> names = options.passes;
    if (!names.empty()) {
        return names;
    }
    names = frame.pass_names();
    std::stable_sort(names.begin(), names.end(), [](const std::string &a, const std::string &b) {
        auto rank = [](const std::string &n) {
            int i = 0;
            for (const pass::CanonicalPass &cp : pass::canonical_passes()) {
                if (cp.name == n) {
                    return i;
                }
                ++i;
            }
            return 1000;
        };
        return rank(a) < rank(b);
    });
    return names;
}

std::vector<OutPart> rebuilt_layout(const Frame &frame,
                                    const std::vector<std::string> &names,
                                    bool multipart,
                                    const WriteOptions &options,
                                    const std::string &path)
{
    // A file with views keeps them: the frame's passes are its chosen view's, "N@right" the
    // right view's. One part names the views' channels OpenEXR's single-part way (the first
    // view's bare, "N.right.X" for the others) under a multiView list; a part per pass gives
    // each part its view, and a view's part the header of that view's first part.
    const SourceFile *src = frame.source.get();
    const std::vector<std::string> no_views;
    const std::vector<std::string> &views = src ? src->views : no_views;
    // A pass's view: "N@right"'s, else the view of the part it came from (a multi-part file's
    // part without a view stays without), else the chosen view.
    const auto view_of = [&](const std::string &name, const Pass &p) {
        const auto at = name.find('@');
        if (at != std::string::npos &&
            std::find(views.begin(), views.end(), name.substr(at + 1)) != views.end()) {
            return name.substr(at + 1);
        }
        if (views.empty()) {
            return std::string();
        }
        for (const ChannelOrigin &o : p.origin) {
            if (o.part >= 0 && o.part < int(src->parts.size()) && !src->single_part_views) {
                return src->parts[std::size_t(o.part)].view;
            }
        }
        return src->view;
    };
    std::vector<const char *> view_ptrs;
    for (const std::string &v : views) {
        view_ptrs.push_back(v.c_str());
    }
    std::vector<OutPart> parts;
    for (const std::string &name : names) {
        const Pass &p = frame.pass(name, path);
        const std::string view = view_of(name, p);
        const std::string layer =
            view.empty() || view == src->view ? name : name.substr(0, name.find('@'));
        if (multipart || parts.empty()) {
            OutPart part;
            part.spec = fresh_spec(frame);
            part.data_window = frame.data_window;
            // The view the part's header describes: its own, or one part's default view (the
            // one whose channels are bare). Another view than the chosen one takes the header
            // of that view's first part, and its camera (finish_specs).
            part.view = multipart || views.empty() ? view : views[0];
            if (!part.view.empty() && part.view != src->view) {
                const std::string wanted = part.view;
                part.view = src->view;  // a single-part source: its one header
                for (const SourcePart &sp : src->parts) {
                    if (sp.view == wanted) {
                        part.spec = OIIO::ImageSpec(1, 1, 1, OIIO::TypeDesc::FLOAT);
                        for (const OIIO::ParamValue &a : sp.spec.extra_attribs) {
                            if (!is_structural_attribute(a.name().string())) {
                                part.spec.extra_attribs.push_back(a);
                            }
                        }
                        part.header_source = &sp;
                        part.view = wanted;
                        break;
                    }
                }
            }
            for (const ChannelOrigin &o : p.origin) {
                if (o.part >= 0 && o.part < int(src ? src->parts.size() : 0)) {
                    part.compression_source = &src->parts[std::size_t(o.part)];
                    break;
                }
            }
            if (multipart) {
                const std::string base = layer == pass::kColor ? std::string("rgba") : layer;
                part.spec.attribute("name", view.empty() ? base : base + "." + view);
            }
            if (multipart && !view.empty()) {
                part.spec.attribute("view", view);
            }
            if (!views.empty()) {
                part.spec.attribute("multiView",
                                    OIIO::TypeDesc(OIIO::TypeDesc::STRING, int(views.size())),
                                    view_ptrs.data());
            }
            parts.push_back(std::move(part));
        }
        const bool view_in_name = !multipart && !view.empty() && view != views[0];
        add_canonical(parts.back(), name, p, options, view_in_name ? view : "", path, layer, src);
    }
    return parts;
}

std::vector<OutPart> source_layout(const Frame &frame,
                                   const std::vector<std::string> &names,
                                   const WriteOptions &options,
                                   const std::string &path)
{
    const SourceFile &src = *frame.source;
    std::vector<OutPart> parts(src.parts.size());
    for (std::size_t i = 0; i < parts.size(); ++i) {
        parts[i].source = &src.parts[i];
        parts[i].spec = src.parts[i].spec;
        // A part keeps its own window where the frame still has it; a crop (or a write's
        // crop to the display window) cuts it to the frame's data window.
        const Rect own = src.parts[i].data_window();
        const Rect cut = own.intersect(frame.data_window);
        parts[i].data_window = cut.empty() ? frame.data_window : cut;
        parts[i].cut = parts[i].data_window != own;
    }
    // A node may have made a pass reach beyond its part's window (a blur's spread, pixels set
    // from Python): that part takes the frame's data window then, so nothing it holds is cut
    // away (it was: the values outside went unwritten).
    for (const std::string &name : names) {
        const Pass &p = frame.pass(name, path);
        if (p.untouched()) {
            continue;
        }
        const std::string base = name.substr(0, name.find('@'));
        for (std::size_t k = 0; k < p.origin.size(); ++k) {
            const int at = p.origin[k].part;
            if (at < 0 || at >= int(parts.size()) ||
                parts[std::size_t(at)].data_window == frame.data_window) {
                continue;
            }
            OutPart &part = parts[std::size_t(at)];
            const float outside =
                pass::is_depth_pass(base) ? std::numeric_limits<float>::infinity() : 0.0f;
            if (differs_outside(*p.image, int(k), frame.data_window, part.data_window, outside)) {
                part.data_window = frame.data_window;
                part.cut = true;
            }
        }
    }
    std::set<std::pair<int, int>> written;  // source slots already filled
    std::vector<std::string> fresh;         // passes written under canonical names
    for (const std::string &name : names) {
        const Pass &p = frame.pass(name, path);
        const bool untouched = p.untouched();
        const bool gray = !untouched && gray_from_one_channel(p);  // G and B stay in Y
        bool mappable = !p.origin.empty();
        std::set<std::pair<int, int>> own;
        int first_sourced = -1;
        for (std::size_t k = 0; k < p.origin.size() && mappable; ++k) {
            const ChannelOrigin &o = p.origin[k];
            if (o.part < 0 || (gray && (k == 1 || k == 2))) {
                continue;
            }
            if (o.part >= int(parts.size()) || !own.insert({o.part, o.channel}).second ||
                o.scale == 0.0f) {
                mappable = untouched;  // shared or constant sources map back only untouched
            }
            if (first_sourced < 0) {
                first_sourced = int(k);
            }
        }
        // A made-up channel a node made vary joins its pass's part, which must then hold the
        // whole frame window (else the pass goes out whole under canonical names).
        for (std::size_t k = 0; k < p.origin.size() && mappable && first_sourced >= 0 && !untouched;
             ++k) {
            const ChannelOrigin &o = p.origin[k];
            const Rect &anchor_window =
                parts[std::size_t(p.origin[std::size_t(first_sourced)].part)].data_window;
            if (o.part < 0 && !channel_is(*p.image, int(k), o.offset) &&
                frame.data_window != anchor_window) {
                mappable = false;
            }
        }
        if (!mappable || first_sourced < 0) {
            fresh.push_back(name);
            continue;
        }
        const PixelStorage asked = asked_storage(name, p, options);
        const ChannelOrigin &anchor = p.origin[std::size_t(first_sourced)];
        for (std::size_t k = 0; k < p.origin.size(); ++k) {
            const ChannelOrigin &o = p.origin[k];
            OutChannel c;
            c.pass = name;
            c.data_pass = is_data_pass(name);
            c.untouched = untouched;
            c.image = p.image.get();
            c.k = int(k);
            if (o.part < 0) {
                // A constant the reader made up (alpha of an RGB file): written only when a node
                // made it vary.
                if (untouched || channel_is(*p.image, int(k), o.offset)) {
                    continue;
                }
                OutPart &part = parts[std::size_t(anchor.part)];
                c.name = sibling_name(part.spec.channel_name(anchor.channel), p.channels[k]);
                c.type = storage_type(asked == PixelStorage::Auto ? default_storage(name) : asked);
                add_channel(part, std::move(c), path);
                continue;
            }
            if ((gray && (k == 1 || k == 2)) || !written.insert({o.part, o.channel}).second) {
                continue;  // another pass (or this one's R) already put this channel back
            }
            OutPart &part = parts[std::size_t(o.part)];
            const OIIO::TypeDesc file_type = part.spec.channelformat(o.channel);
            c.name = part.spec.channel_name(o.channel);
            if (asked != PixelStorage::Auto) {
                c.type = storage_type(asked);
            } else if (file_type.basetype == OIIO::TypeDesc::HALF ||
                       file_type.basetype == OIIO::TypeDesc::FLOAT ||
                       (file_type.basetype == OIIO::TypeDesc::UINT &&
                        (untouched || holds_uints(*p.image, int(k), o)))) {
                c.type = file_type;
            } else {
                c.type = OIIO::TypeDesc::FLOAT;  // a node's fractions in a uint id channel
            }
            c.scale = o.scale;
            c.offset = o.offset;
            if (untouched && c.type == file_type) {
                if (auto it = src.raw.find({o.part, o.channel}); it != src.raw.end()) {
                    const OutPart &part = parts[std::size_t(o.part)];
                    if (!part.cut) {
                        c.raw = it->second.get();
                    } else {
                        c.raw_slice = slice_samples(*it->second,
                                                    file_type.size(),
                                                    part.source->data_window(),
                                                    part.data_window);
                        c.raw = c.raw_slice.get();
                    }
                }
            }
            add_channel(part, std::move(c), path);
        }
    }
    // Passes under canonical names: into part 0 of a single-part file (same window), else one
    // part each, in the chosen view.
    const bool default_view = src.views.empty() || src.view == src.views[0];
    for (const std::string &name : fresh) {
        const Pass &p = frame.pass(name, path);
        OutPart *part = nullptr;
        if (parts.size() == 1 && parts[0].data_window == frame.data_window) {
            part = &parts[0];
        } else {
            OutPart np;
            np.spec = fresh_spec(frame);
            np.data_window = frame.data_window;
            np.spec.attribute("name", src.view.empty() ? name : name + "." + src.view);
            if (!src.view.empty()) {
                np.spec.attribute("view", src.view);
            }
            parts.push_back(std::move(np));
            part = &parts.back();
        }
        const bool view_in_name = src.single_part_views && !default_view && part->source;
        add_canonical(*part, name, p, options, view_in_name ? src.view : "", path, name, &src);
    }
    // Parts nothing is written to are left out.
    parts.erase(
        std::remove_if(
            parts.begin(), parts.end(), [](const OutPart &p) { return p.channels.empty(); }),
        parts.end());
    return parts;
}

}  // namespace posthaste::io_detail
