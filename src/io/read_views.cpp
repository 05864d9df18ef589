// How a file's channels map onto views and passes (io/read_detail.h).

#include <algorithm>
#include <string>
#include <vector>

#include "core/error.h"
#include "core/text.h"
#include "io/read_detail.h"

namespace posthaste::io_detail {

namespace {

std::vector<std::string> split_dots(const std::string &name)
{
    std::vector<std::string> out;
    std::size_t start = 0;
    while (true) {
        const std::size_t dot = name.find('.', start);
        out.push_back(name.substr(start, dot - start));
        if (dot == std::string::npos) {
            return out;
        }
        start = dot + 1;
    }
}

}  // namespace

void assign_views(const std::vector<OIIO::ImageSpec> &specs,
                  FileInfo &info,
                  std::vector<MappedChannel> &channels,
                  bool &single_part_views)
{
    std::vector<std::string> multi_view;
    if (const OIIO::ParamValue *p = specs[0].find_attribute("multiView")) {
        if (p->type().basetype == OIIO::TypeDesc::STRING) {
            for (int i = 0; i < p->nvalues() * int(p->type().numelements()); ++i) {
                multi_view.emplace_back(p->get_ustring_indexed(i).string());
            }
        }
    }
    info.views = multi_view;
    bool parts_have_views = false;
    for (const FilePart &part : info.parts) {
        if (!part.view.empty()) {
            parts_have_views = true;
            if (std::find(info.views.begin(), info.views.end(), part.view) == info.views.end()) {
                info.views.push_back(part.view);
            }
        }
    }
    single_part_views = !parts_have_views && !multi_view.empty();
    // The first part of each view keeps bare channel names; later parts' bare names take the
    // part's layer ("depth.left" part, channel "Z" -> "depth.Z"), except the conventional "rgba".
    std::set<std::string> seen_view;
    for (std::size_t p = 0; p < info.parts.size(); ++p) {
        FilePart &part = info.parts[p];
        std::string layer = part.name;
        if (!part.view.empty() && layer.ends_with("." + part.view)) {
            layer.resize(layer.size() - part.view.size() - 1);
        }
        const bool first_of_view = seen_view.insert(part.view).second;
        for (std::size_t c = 0; c < part.channels.size(); ++c) {
            FileChannel &fc = part.channels[c];
            MappedChannel m{int(p), int(c), part.view, fc.name};
            if (single_part_views) {
                std::vector<std::string> parts = split_dots(fc.name);
                m.view = multi_view[0];
                if (parts.size() >= 2 &&
                    std::find(multi_view.begin(), multi_view.end(), parts[parts.size() - 2]) !=
                        multi_view.end()) {
                    m.view = parts[parts.size() - 2];
                    parts.erase(parts.end() - 2);
                    m.name.clear();
                    for (const std::string &s : parts) {
                        m.name += (m.name.empty() ? "" : ".") + s;
                    }
                }
            } else if (!first_of_view && !layer.empty() && layer != "rgba" &&
                       fc.name.find('.') == std::string::npos) {
                m.name = layer + "." + fc.name;
            }
            fc.view = m.view;
            channels.push_back(std::move(m));
        }
    }
}

std::vector<PassSource> map_views(const FileInfo &info,
                                  const std::vector<MappedChannel> &channels,
                                  const std::vector<AliasRule> &rules,
                                  const std::string &convention,
                                  std::vector<RefusedPass> *refused)
{
    std::vector<std::string> order = {info.view};
    for (const std::string &v : info.views) {
        if (v != info.view) {
            order.push_back(v);
        }
    }
    std::vector<PassSource> out;
    for (const std::string &view : order) {
        // map_channels sees one list of names per part; remember the real channel indices.
        std::vector<PartChannels> parts(info.parts.size());
        std::vector<std::vector<int>> index(info.parts.size());
        for (std::size_t p = 0; p < info.parts.size(); ++p) {
            parts[p].part_name = info.parts[p].name;
        }
        for (const MappedChannel &m : channels) {
            if (m.view == view || (m.view.empty() && view == info.view)) {
                parts[std::size_t(m.part)].names.push_back(m.name);
                index[std::size_t(m.part)].push_back(m.channel);
            }
        }
        std::vector<PassSource> mapped = map_channels(parts, rules, convention);
        if (view == info.view) {
            *refused = refused_passes(parts, mapped, info.width(), info.height(), convention);
        }
        for (PassSource ps : mapped) {
            for (ChannelSource &cs : ps.sources) {
                if (cs.part >= 0) {
                    cs.channel = index[std::size_t(cs.part)][std::size_t(cs.channel)];
                    cs.name =
                        info.parts[std::size_t(cs.part)].channels[std::size_t(cs.channel)].name;
                }
            }
            if (view != info.view) {
                ps.pass += "@" + view;
            }
            out.push_back(std::move(ps));
        }
    }
    return out;
}

}  // namespace posthaste::io_detail
