// graph/mask.cpp: the engine's mask on colour nodes (graph/mask.h).

#include "graph/mask.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "core/error.h"
#include "core/parallel.h"

namespace posthaste {

bool alpha_made_by_reader(const Pass &p)
{
    const Image &img = *p.image;
    if (img.channels() != 4 || p.origin.size() != 4 || p.origin[3].part != -1) {
        return false;
    }
    if (p.untouched()) {
        return true;
    }
    const float made = p.origin[3].offset;
    for (std::size_t i = 0; i < img.pixel_count(); ++i) {
        if (img.data()[4 * i + 3] != made) {
            return false;
        }
    }
    return true;
}

namespace {

/// The channel of the mask pass the mask is (0..3, 4 for the luminance, kMaskGrey), or an error
/// naming the pass and channel when the frame on the mask port cannot give it.
int mask_channel(const std::string &who, const MaskSettings &m, const Frame &mask)
{
    const std::string &name = m.pass;
    const Image &src = mask.image(name, who + ": mask input");
    // r, g, b, a, luminance; a one-channel pass (a matte) is its own mask whichever is named.
    int channel = src.channels() == 1 ? 0 : int(m.channel);
    // An alpha the file lacks is the reader's 1, a mask that is everywhere: a matte written as
    // luminance alone (Blender's matte outputs: Y) is then its own mask, as a one-channel pass.
    if (channel == 3 && alpha_made_by_reader(mask.pass(name))) {
        channel = kMaskGrey;
    }
    if (channel < 4 && channel >= src.channels()) {
        throw_runtime(who,
                      ": mask pass \"",
                      name,
                      "\" has ",
                      src.channels(),
                      " channels, no ",
                      "rgba"[channel],
                      " (mask_channel)");
    }
    if (channel == 4 && src.channels() < 3) {
        throw_runtime(who,
                      ": mask luminance needs 3 channels in pass \"",
                      name,
                      "\", it has ",
                      src.channels());
    }
    return channel;
}

/// The mask over `window` (absolute): the channel or luminance of `pass`, clamped to [0, 1]
/// (NaN: 0), inverted on request; 0 outside the mask frame's data window.
Image mask_image(const std::string &who,
                 const MaskSettings &m,
                 const Frame &mask,
                 const Rect &window)
{
    const Image &src = mask.image(m.pass, who + ": mask input");
    const int channel = mask_channel(who, m, mask);
    const bool invert = m.invert;
    Image one(mask.width(), mask.height(), 1);
    parallel_for(0, one.height(), [&](int y) {
        for (int x = 0; x < one.width(); ++x) {
            const float *p = src.pixel(x, y);
            float m = mask_sample(p, channel);
            m = std::isnan(m) ? 0.0f : std::clamp(m, 0.0f, 1.0f);
            one.at(x, y, 0) = invert ? 1.0f - m : m;
        }
    });
    // Outside the mask's window: no mask (0), which inverted is 1.
    return place_in_window(one, mask.data_window, window, {invert ? 1.0f : 0.0f});
}

}  // namespace

void apply_mask(const std::string &who,
                const NodeParams &params,
                const Frame &in,
                const Frame &mask,
                Frame &out)
{
    const MaskSettings m = fill(params, kMaskFields);
    mask_channel(who, m, mask);  // a mask that cannot be is an error, used or not
    std::vector<std::string> changed;
    for (const auto &[name, pass] : out.passes()) {
        if (!in.has(name)) {
            continue;
        }
        const Pass &before = in.pass(name);
        if (before.image == pass.image || before.image->width() != pass.image->width() ||
            before.image->height() != pass.image->height() ||
            before.image->channels() != pass.image->channels() ||
            in.data_window != out.data_window) {
            continue;
        }
        changed.push_back(name);
    }
    if (changed.empty()) {
        return;
    }
    // Another view's pass ("color@right") takes that view's mask ("matte@right") where the mask
    // frame has it (it took the chosen view's), else the mask as named.
    std::map<std::string, Image> masks;
    for (const std::string &name : changed) {
        const auto at = name.find('@');
        MaskSettings mv = m;
        if (at != std::string::npos && mask.has(m.pass + name.substr(at))) {
            mv.pass = m.pass + name.substr(at);
        }
        if (!masks.count(mv.pass)) {
            masks.emplace(mv.pass, mask_image(who, mv, mask, out.data_window));
        }
        const Image &mi = masks.at(mv.pass);
        const Pass &p = out.pass(name);
        const Image &a = *in.pass(name).image, &b = *p.image;
        Image blended = Image::uninitialized(b.width(), b.height(), b.channels());
        const int nc = b.channels();
        parallel_for(0, b.height(), [&](int y) {
            const float *pa = a.pixel(0, y), *pb = b.pixel(0, y);
            const float *pm = mi.pixel(0, y);
            float *d = blended.pixel(0, y);
            for (int x = 0; x < b.width(); ++x) {
                const float t = pm[x];
                for (int c = 0; c < nc; ++c, ++pa, ++pb, ++d) {
                    // Exactly the input at 0 and the node's value at 1.
                    *d = mask_mix(*pa, *pb, t);
                }
            }
        });
        out.set(name, std::make_shared<const Image>(std::move(blended)), p.channels, p.storage);
    }
}

}  // namespace posthaste
