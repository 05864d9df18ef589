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

void Frame::check_size(const std::string &name, const Image &image)
{
    if (passes_.empty() && data_window.empty()) {
        set_size(image.width(), image.height());
    }
    if (image.width() != width() || image.height() != height()) {
        throw_runtime("pass \"",
                      name,
                      "\" is ",
                      image.width(),
                      "x",
                      image.height(),
                      " but the frame's data window is ",
                      width(),
                      "x",
                      height());
    }
}

std::vector<std::string> default_channel_names(const std::string &name, int count)
{
    std::vector<std::string> names;
    const pass::CanonicalPass *canonical = pass::find_canonical(name);
    const int known = canonical ? int(canonical->channels.size()) : 0;
    if (canonical && name == pass::kColor && count <= 2) {
        names = {"Y", "A"};  // luminance, and alpha
    } else if (canonical && count <= known) {
        names.assign(canonical->channels.begin(), canonical->channels.begin() + count);
    } else if (!canonical && (count == 1 || count == 3 || count == 4)) {
        names = count == 1 ? std::vector<std::string>{"Y"}
                           : std::vector<std::string>{"R", "G", "B", "A"};
    }
    names.resize(std::size_t(count));
    for (int c = 0; c < count; ++c) {
        if (names[std::size_t(c)].empty()) {
            names[std::size_t(c)] = std::to_string(c);
        }
    }
    return names;
}

void Frame::set(const std::string &name,
                ImagePtr image,
                std::vector<std::string> channels,
                PixelStorage storage)
{
    if (!image) {
        throw_runtime("pass \"", name, "\": no image");
    }
    check_size(name, *image);
    if (channels.empty()) {
        channels = default_channel_names(name, image->channels());
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
    Pass next{std::move(image), std::move(channels), storage, {}, {}};
    if (auto it = passes_.find(name); it != passes_.end()) {
        const Pass &old = it->second;
        if (old.origin.size() == next.channels.size() && old.channels == next.channels) {
            next.origin = old.origin;
            next.as_read = old.as_read;
            if (next.storage == PixelStorage::Auto) {
                next.storage = old.storage;
            }
        }
    }
    passes_[name] = std::move(next);
}

void Frame::set_pass(const std::string &name, Pass pass)
{
    if (!pass.image) {
        throw_runtime("pass \"", name, "\": no image");
    }
    check_size(name, *pass.image);
    passes_[name] = std::move(pass);
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
