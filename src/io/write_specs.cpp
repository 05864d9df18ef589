// The EXR writer's part headers (io/write_layout.h): each output part's spec filled in from its
// channels and windows, its compression, mip levels, camera (the chosen view's, or another
// view's own) and the attributes nodes changed or removed.

#include <cstring>

#include "core/error.h"
#include "io/image_file.h"
#include "io/io_detail.h"
#include "io/write_layout.h"

namespace posthaste::io_detail {

void finish_specs(std::vector<OutPart> &parts,
                  const Frame &frame,
                  const WriteOptions &options,
                  const std::string &path)
{
    const SourceFile *src = frame.source.get();
    // Attributes a node added or changed (compared with the source's chosen-view part).
    OIIO::ParamValueList changed;
    const OIIO::ImageSpec *first = nullptr;
    const SourcePart *first_part = nullptr;
    if (src) {
        for (const SourcePart &sp : src->parts) {
            if (sp.view == src->view) {
                first = &sp.spec;
                first_part = &sp;
                break;
            }
        }
        // A single-part multi-view file's one part has no view of its own: it is the part.
        if (!first_part && !src->parts.empty()) {
            first = &src->parts[0].spec;
            first_part = &src->parts[0];
        }
    }
    // And those it removed: the source's that the read put into the frame and the frame lacks.
    std::vector<OIIO::ustring> removed;
    if (first) {
        for (const OIIO::ParamValue &p : first->extra_attribs) {
            if (is_frame_attribute(p.name().string()) &&
                !frame.attributes.find_pv(p.name().string(), OIIO::TypeUnknown, true)) {
                removed.push_back(p.name());
            }
        }
    }
    for (const OIIO::ParamValue &p : frame.attributes) {
        const OIIO::ParamValue *old = first ? first->find_attribute(p.name().string()) : nullptr;
        if (!old || old->type() != p.type() || old->nvalues() != p.nvalues() ||
            std::memcmp(old->data(), p.data(), p.type().size() * std::size_t(p.nvalues())) != 0) {
            changed.push_back(p);
        }
    }
    for (OutPart &part : parts) {
        if (!part.header_source) {
            part.header_source = part.source ? part.source : first_part;
        }
        OIIO::ImageSpec &spec = part.spec;
        // A part the write builds anew keeps the picture's pixel aspect (a structural attribute
        // the frame does not carry: a rebuilt layout wrote 0.5 for 2, from the densities).
        if (!part.source && first && !spec.find_attribute("PixelAspectRatio")) {
            if (const OIIO::ParamValue *par = first->find_attribute("PixelAspectRatio")) {
                spec.extra_attribs.push_back(*par);
            }
        }
        spec.nchannels = int(part.channels.size());
        spec.channelnames.clear();
        spec.channelformats.clear();
        spec.alpha_channel = spec.z_channel = -1;
        for (const OutChannel &c : part.channels) {
            spec.channelnames.push_back(c.name);
            spec.channelformats.push_back(c.type);
        }
        spec.format = part.channels[0].type;
        spec.x = part.data_window.x0;
        spec.y = part.data_window.y0;
        spec.width = part.data_window.width();
        spec.height = part.data_window.height();
        spec.full_x = frame.display_window.x0;
        spec.full_y = frame.display_window.y0;
        spec.full_width = frame.display_window.width();
        spec.full_height = frame.display_window.height();
        spec.z = spec.full_z = 0;
        spec.depth = spec.full_depth = 1;
        if (spec.tile_width > 0) {
            spec.tile_depth = 1;
        }
        std::string compression = options.compression;
        if (compression == "auto") {
            const SourcePart *like = part.source ? part.source : part.compression_source;
            const std::string was = like ? like->spec.get_string_attribute("compression") : "";
            compression = was.empty() ? "piz" : is_lossy_compression(was) ? "zip" : was;
        }
        const std::string base = compression.substr(0, compression.find(':'));
        if (is_lossy_compression(base) && !options.allow_lossy_data) {
            for (const OutChannel &c : part.channels) {
                if (c.data_pass) {
                    throw_usage(path,
                                ": compression \"",
                                compression,
                                "\" is lossy on data pass \"",
                                c.pass,
                                "\"; choose a lossless compression or allow lossy data passes");
                }
            }
        }
        spec.attribute("compression", compression);
        // Mip levels travel only with a part written whole and untouched.
        part.copy_levels = false;
        if (part.source && !part.cut && !part.source->levels.empty() &&
            int(part.channels.size()) == part.source->spec.nchannels) {
            part.copy_levels = true;
            for (const OutChannel &c : part.channels) {
                const int i = part.source->spec.channelindex(c.name);
                part.copy_levels = part.copy_levels && i >= 0 && c.untouched &&
                                   c.type == part.source->spec.channelformat(i);
            }
        }
        part.make_levels =
            !part.copy_levels && part.source && part.source->mip_levels > 1 && spec.tile_width > 0;
        if (!part.copy_levels && !part.make_levels) {
            spec.attribute("openexr:levelmode", 0);  // one level (OIIO would make textures MIP)
        }
        const bool chosen_view =
            !src || (part.source ? part.source->view == src->view || part.source->view.empty()
                                 : part.view.empty() || part.view == src->view);
        const std::string &view = part.source ? part.source->view : part.view;
        const auto other = frame.view_cameras.find(view);
        if (!chosen_view && other != frame.view_cameras.end() && part.header_source) {
            // Another view's part: its own camera, as moved by the graph's nodes.
            Camera was;
            read_camera(part.header_source->spec, was);
            write_camera(other->second, spec, &was);
        }
        if (chosen_view) {
            write_camera(frame.camera, spec, src && part.source ? &src->camera : nullptr);
        }
        // The frame's number is every view's (it was set on the chosen view's parts only).
        if (spec.get_int_attribute(attr::kFrameNumber, frame.number - 1) != frame.number) {
            spec.attribute(attr::kFrameNumber, frame.number);
        }
        for (const OIIO::ParamValue &p : changed) {
            spec.extra_attribs.remove(p.name());
            spec.extra_attribs.push_back(p);
        }
        for (const OIIO::ustring &name : removed) {
            spec.extra_attribs.remove(name);
        }
        spec.erase_attribute("oiio:subimages");
        spec.erase_attribute("openexr:chunkCount");
    }
}

}  // namespace posthaste::io_detail
