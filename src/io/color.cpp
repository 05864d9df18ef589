#include "io/color.h"

#include <OpenColorIO/OpenColorIO.h>

#include <cstdlib>
#include <mutex>
#include <sstream>

#include "core/error.h"
#include "core/parallel.h"

namespace OCIO = OCIO_NAMESPACE;

namespace posthaste {

extern const char *const kBuiltinOcioConfig;  // generated from samples/ocio/config.ocio

namespace {

struct ConfigHolder {
    OCIO::ConstConfigRcPtr config;
    std::string source;
};

const ConfigHolder &config_holder()
{
    static const ConfigHolder holder = [] {
        ConfigHolder h;
        const char *env = std::getenv("OCIO");
        try {
            if (env && *env) {
                h.config = OCIO::Config::CreateFromFile(env);
                h.source = std::string("$OCIO=") + env;
            } else {
                std::istringstream is(kBuiltinOcioConfig);
                h.config = OCIO::Config::CreateFromStream(is);
                h.source = "built-in samples/ocio/config.ocio";
            }
        } catch (const OCIO::Exception &e) {
            throw_runtime(env ? std::string("$OCIO=") + env : std::string("built-in OCIO config"),
                          ": cannot load OpenColorIO config: ",
                          e.what());
        }
        return h;
    }();
    return holder;
}

std::string joined(const std::vector<std::string> &v)
{
    std::string s;
    for (const std::string &x : v) {
        s += (s.empty() ? "" : ", ") + x;
    }
    return s;
}

}  // namespace

struct ColorProcessor::Impl {
    OCIO::ConstCPUProcessorRcPtr cpu;
    bool noop = false;
};

std::string color_config_source()
{
    return config_holder().source;
}

std::vector<std::string> color_space_names()
{
    const auto &cfg = config_holder().config;
    std::vector<std::string> names;
    for (int i = 0; i < cfg->getNumColorSpaces(); ++i) {
        names.emplace_back(cfg->getColorSpaceNameByIndex(i));
    }
    return names;
}

std::vector<std::string> color_display_names()
{
    const auto &cfg = config_holder().config;
    std::vector<std::string> names;
    for (int i = 0; i < cfg->getNumDisplays(); ++i) {
        names.emplace_back(cfg->getDisplay(i));
    }
    return names;
}

std::vector<std::string> color_view_names(const std::string &display)
{
    const auto &cfg = config_holder().config;
    std::vector<std::string> names;
    for (int i = 0; i < cfg->getNumViews(display.c_str()); ++i) {
        names.emplace_back(cfg->getView(display.c_str(), i));
    }
    return names;
}

namespace {

void require_space(const std::string &name, const std::string &where)
{
    const auto &cfg = config_holder().config;
    if (!cfg->getColorSpace(name.c_str())) {
        throw_usage(where,
                    ": unknown color space \"",
                    name,
                    "\" in ",
                    color_config_source(),
                    " (have: ",
                    joined(color_space_names()),
                    ")");
    }
}

}  // namespace

ColorProcessor ColorProcessor::between(const std::string &from,
                                       const std::string &to,
                                       const std::string &where)
{
    require_space(from, where);
    require_space(to, where);
    auto impl = std::make_shared<Impl>();
    try {
        auto proc = config_holder().config->getProcessor(from.c_str(), to.c_str());
        impl->noop = proc->isNoOp();
        impl->cpu = proc->getDefaultCPUProcessor();
    } catch (const OCIO::Exception &e) {
        throw_usage(where, ": OpenColorIO: ", e.what());
    }
    ColorProcessor p;
    p.impl_ = std::move(impl);
    return p;
}

ColorProcessor ColorProcessor::display_view(const std::string &from,
                                            const std::string &display,
                                            const std::string &view,
                                            const std::string &where,
                                            bool for_8bit)
{
    require_space(from, where);
    const std::vector<std::string> displays = color_display_names();
    if (std::find(displays.begin(), displays.end(), display) == displays.end()) {
        throw_usage(where, ": unknown display \"", display, "\" (have: ", joined(displays), ")");
    }
    const std::vector<std::string> views = color_view_names(display);
    if (std::find(views.begin(), views.end(), view) == views.end()) {
        throw_usage(where,
                    ": unknown view \"",
                    view,
                    "\" for display \"",
                    display,
                    "\" (have: ",
                    joined(views),
                    ")");
    }
    auto impl = std::make_shared<Impl>();
    try {
        auto proc = config_holder().config->getProcessor(
            from.c_str(), display.c_str(), view.c_str(), OCIO::TRANSFORM_DIR_FORWARD);
        impl->noop = proc->isNoOp();
        // An 8-bit preview lets OpenColorIO replace curves by look-up tables (draft
        // optimisation): measured within one 8-bit code of the exact transform.
        impl->cpu = for_8bit
                        ? proc->getOptimizedCPUProcessor(
                              OCIO::BIT_DEPTH_F32, OCIO::BIT_DEPTH_F32, OCIO::OPTIMIZATION_DRAFT)
                        : proc->getDefaultCPUProcessor();
    } catch (const OCIO::Exception &e) {
        throw_usage(where, ": OpenColorIO: ", e.what());
    }
    ColorProcessor p;
    p.impl_ = std::move(impl);
    return p;
}

bool ColorProcessor::is_noop() const
{
    return impl_->noop;
}

void ColorProcessor::apply_rgb(float rgb[3]) const
{
    impl_->cpu->applyRGB(rgb);
}

void ColorProcessor::apply_row(float *row, int width, int nch, bool unpremultiply) const
{
    if (impl_->noop || nch < 3) {
        return;
    }
    const bool unpremult = unpremultiply && nch >= 4;
    // Below this alpha a pixel is left premultiplied: dividing by a near-zero alpha turns any
    // color into huge values that a non-linear transform overflows (found by the stability suite).
    constexpr float kMinAlpha = 1e-6f;
    if (unpremult) {
        for (int x = 0; x < width; ++x) {
            float *p = row + std::size_t(x) * std::size_t(nch);
            if (p[3] > kMinAlpha) {
                p[0] /= p[3];
                p[1] /= p[3];
                p[2] /= p[3];
            }
        }
    }
    // Channels beyond RGB (alpha, extra) are skipped through the strides.
    OCIO::PackedImageDesc desc(row,
                               width,
                               1,
                               OCIO::CHANNEL_ORDERING_RGB,
                               OCIO::BIT_DEPTH_F32,
                               sizeof(float),
                               std::ptrdiff_t(sizeof(float)) * nch,
                               std::ptrdiff_t(sizeof(float)) * nch * width);
    impl_->cpu->apply(desc);
    if (unpremult) {
        for (int x = 0; x < width; ++x) {
            float *p = row + std::size_t(x) * std::size_t(nch);
            if (p[3] > kMinAlpha) {
                p[0] *= p[3];
                p[1] *= p[3];
                p[2] *= p[3];
            }
        }
    }
}

void ColorProcessor::apply(Image &image, bool unpremultiply) const
{
    if (impl_->noop || image.channels() < 3) {
        return;
    }
    parallel_for_tiles(image.bounds(), [&](const Rect &tile) {
        for (int y = tile.y0; y < tile.y1; ++y) {
            apply_row(image.pixel(tile.x0, y), tile.width(), image.channels(), unpremultiply);
        }
    });
}

}  // namespace posthaste
