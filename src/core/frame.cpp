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
