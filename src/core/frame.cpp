#include "core/frame.h"

#include "core/error.h"
#include "core/passes.h"

namespace posthaste {

const Pass &Frame::pass(const std::string &name, const std::string &who) const
{
    auto it = passes_.find(name);
    if (it == passes_.end()) {
        std::string have;
        for (const auto &[n, p] : passes_) {
            have += (have.empty() ? "" : ", ") + n;
        }
        throw_runtime(who,
                      ": frame ",
                      number,
                      " has no pass \"",
                      name,
                      "\" (have: ",
                      have.empty() ? "none" : have,
                      ")");
    }
    return it->second;
}

void Frame::set(const std::string &name,
                ImagePtr image,
                std::vector<std::string> channels,
                PixelStorage storage)
{
    if (!image) {
        throw_runtime("pass \"", name, "\": no image");
    }
    if (passes_.empty() && width == 0 && height == 0) {
        width = image->width();
        height = image->height();
    }
    if (image->width() != width || image->height() != height) {
        throw_runtime("pass \"",
                      name,
                      "\" is ",
                      image->width(),
                      "x",
                      image->height(),
                      " but the frame is ",
                      width,
                      "x",
                      height);
    }
    if (channels.empty()) {
        const pass::CanonicalPass *canonical = pass::find_canonical(name);
        if (canonical && int(canonical->channels.size()) == image->channels()) {
            for (std::string_view c : canonical->channels) {
                channels.emplace_back(c);
            }
        } else {
            for (int c = 0; c < image->channels(); ++c) {
                channels.push_back(std::to_string(c));
            }
        }
    }
    if (int(channels.size()) != image->channels()) {
        throw_runtime("pass \"",
                      name,
                      "\": ",
                      channels.size(),
                      " channel names for ",
                      image->channels(),
                      " channels");
    }
    passes_[name] = Pass{std::move(image), std::move(channels), storage};
}

std::vector<std::string> Frame::pass_names() const
{
    std::vector<std::string> names;
    for (const auto &[n, p] : passes_) {
        names.push_back(n);
    }
    return names;
}

}  // namespace posthaste
