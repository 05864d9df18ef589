#include "io/color.h"

#include <OpenColorIO/OpenColorIO.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <sstream>
#include <utility>
#include <vector>

#include "core/error.h"
#include "core/parallel.h"
#include "core/text.h"
#include "io/io_detail.h"

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
        // OpenColorIO's own warnings ("[OpenColorIO Warning]: At line 39, unknown key ...") as
        // the project's: one line each, prefixed "warning:".
        OCIO::SetLoggingFunction([](const char *message) {
            std::string m = message ? message : "";
            std::string label = "warning: OpenColorIO: ";  // its warnings and errors
            if (m.rfind("[OpenColorIO ", 0) == 0 && m.find("]: ") != std::string::npos) {
                const std::string level = m.substr(13, m.find("]: ") - 13);
                label = level == "Info" || level == "Debug" ? "OpenColorIO: " : label;
                m.erase(0, m.find("]: ") + 3);
            }
            while (!m.empty() && (m.back() == '\n' || m.back() == '\r' || m.back() == ' ')) {
                m.pop_back();
            }
            std::replace(m.begin(), m.end(), '\n', ' ');
            std::fprintf(stderr, "%s%s\n", label.c_str(), printable_line(m).c_str());
        });
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

}  // namespace

struct ColorProcessor::Impl {
    OCIO::ConstCPUProcessorRcPtr cpu;
    /// For 8-bit output of a transform without channel crosstalk: the same transform over
    /// half-float input, which OpenColorIO's optimiser turns into one table lookup a channel
    /// (a 65536-entry 1D LUT, one per half value) instead of evaluating each op; null otherwise.
    OCIO::ConstCPUProcessorRcPtr cpu_half;
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

/// `param`: the parameter that named it, for the message ("" for none).
void require_space(const std::string &name, const std::string &where, const std::string &param)
{
    const auto &cfg = config_holder().config;
    if (!cfg->getColorSpace(name.c_str())) {
        throw_usage(where,
                    param.empty() ? "" : ": param \"" + param + "\"",
                    ": unknown color space \"",
                    name,
                    "\" in ",
                    color_config_source(),
                    " (have: ",
                    join(color_space_names()),
                    ")");
    }
}

}  // namespace

ColorProcessor ColorProcessor::between(const std::string &from,
                                       const std::string &to,
                                       const std::string &where,
                                       const std::string &from_param,
                                       const std::string &to_param)
{
    require_space(from, where, from_param);
    require_space(to, where, to_param);
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
                                            bool for_8bit,
                                            const std::string &from_param)
{
    require_space(from, where, from_param);
    const std::vector<std::string> displays = color_display_names();
    if (std::find(displays.begin(), displays.end(), display) == displays.end()) {
        throw_usage(where,
                    from_param.empty() ? "" : ": param \"display\"",
                    ": unknown display \"",
                    display,
                    "\" (have: ",
                    join(displays),
                    ")");
    }
    const std::vector<std::string> views = color_view_names(display);
    if (std::find(views.begin(), views.end(), view) == views.end()) {
        throw_usage(where,
                    from_param.empty() ? "" : ": param \"view\"",
                    ": unknown view \"",
                    view,
                    "\" for display \"",
                    display,
                    "\" (have: ",
                    join(views),
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
        if (for_8bit && !impl->noop && !proc->hasChannelCrosstalk()) {
            impl->cpu_half = proc->getOptimizedCPUProcessor(
                OCIO::BIT_DEPTH_F16, OCIO::BIT_DEPTH_F32, OCIO::OPTIMIZATION_DRAFT);
        }
    } catch (const OCIO::Exception &e) {
        throw_usage(where, ": OpenColorIO: ", e.what());
    }
    ColorProcessor p;
    p.impl_ = std::move(impl);
    return p;
}

ColorProcessor ColorProcessor::grade(const Grade &g, const std::string &where)
{
    auto impl = std::make_shared<Impl>();
    try {
        auto group = OCIO::GroupTransform::Create();
        auto matrix = OCIO::MatrixTransform::Create();
        const double m44[16] = {g.matrix[0],
                                g.matrix[1],
                                g.matrix[2],
                                0,
                                g.matrix[3],
                                g.matrix[4],
                                g.matrix[5],
                                0,
                                g.matrix[6],
                                g.matrix[7],
                                g.matrix[8],
                                0,
                                0,
                                0,
                                0,
                                1};
        matrix->setMatrix(m44);
        group->appendTransform(matrix);
        auto cdl = OCIO::CDLTransform::Create();
        cdl->setStyle(OCIO::CDL_NO_CLAMP);
        cdl->setSlope(g.slope);
        cdl->setOffset(g.offset);
        cdl->setPower(g.power);
        cdl->setSat(g.saturation);
        group->appendTransform(cdl);
        auto lift_gain = OCIO::MatrixTransform::Create();
        const double lg[16] = {g.gain[0] - g.lift[0],
                               0,
                               0,
                               0,
                               0,
                               g.gain[1] - g.lift[1],
                               0,
                               0,
                               0,
                               0,
                               g.gain[2] - g.lift[2],
                               0,
                               0,
                               0,
                               0,
                               1};
        const double lg_offset[4] = {g.lift[0], g.lift[1], g.lift[2], 0};
        lift_gain->setMatrix(lg);
        lift_gain->setOffset(lg_offset);
        group->appendTransform(lift_gain);
        auto gamma = OCIO::ExponentTransform::Create();
        const double inverse[4] = {1.0 / g.gamma[0], 1.0 / g.gamma[1], 1.0 / g.gamma[2], 1.0};
        gamma->setValue(inverse);
        gamma->setNegativeStyle(OCIO::NEGATIVE_PASS_THRU);
        group->appendTransform(gamma);
        if (!g.lut.empty()) {
            auto file = OCIO::FileTransform::Create();
            file->setSrc(g.lut.c_str());
            file->setInterpolation(g.interpolation == "nearest"       ? OCIO::INTERP_NEAREST
                                   : g.interpolation == "linear"      ? OCIO::INTERP_LINEAR
                                   : g.interpolation == "tetrahedral" ? OCIO::INTERP_TETRAHEDRAL
                                                                      : OCIO::INTERP_BEST);
            group->appendTransform(file);
        }
        auto proc = config_holder().config->getProcessor(group);
        impl->noop = proc->isNoOp();
        impl->cpu = proc->getDefaultCPUProcessor();
    } catch (const OCIO::Exception &e) {
        std::string what = e.what();
        std::replace(what.begin(), what.end(), '\n', ' ');
        throw_usage(where, ": OpenColorIO: ", what);
    }
    ColorProcessor p;
    p.impl_ = std::move(impl);
    return p;
}

void planckian_xy(double kelvin, double tint, double &x, double &y)
{
    auto locus = [](double t, double &lx, double &ly) {
        const double t1 = 1e3 / t, t2 = t1 * t1, t3 = t2 * t1;  // in thousands of kelvin
        lx = t <= 4000.0 ? -0.2661239 * t3 - 0.2343589 * t2 + 0.8776956 * t1 + 0.179910
                         : -3.0258469 * t3 + 2.1070379 * t2 + 0.2226347 * t1 + 0.240390;
        const double x2 = lx * lx, x3 = x2 * lx;
        ly = t <= 2222.0   ? -1.1063814 * x3 - 1.34811020 * x2 + 2.18555832 * lx - 0.20219683
             : t <= 4000.0 ? -0.9549476 * x3 - 1.37418593 * x2 + 2.09137015 * lx - 0.16748867
                           : 3.0817580 * x3 - 5.87338670 * x2 + 3.75112997 * lx - 0.37001483;
    };
    auto to_uv = [](double px, double py, double &u, double &v) {
        const double d = -2.0 * px + 12.0 * py + 3.0;
        u = 4.0 * px / d;
        v = 6.0 * py / d;
    };
    const double t = std::clamp(kelvin, 1667.0, 25000.0);
    locus(t, x, y);
    if (tint == 0.0) {
        return;
    }
    // The isotherm: perpendicular to the locus in uv, oriented toward green (+v).
    double xa, ya, xb, yb, ua, va, ub, vb, u, v;
    locus(std::max(1667.0, t - 10.0), xa, ya);
    locus(std::min(25000.0, t + 10.0), xb, yb);
    to_uv(xa, ya, ua, va);
    to_uv(xb, yb, ub, vb);
    to_uv(x, y, u, v);
    double nu = -(vb - va), nv = ub - ua;
    const double len = std::sqrt(nu * nu + nv * nv);
    nu /= len;
    nv /= len;
    if (nv < 0.0) {
        nu = -nu;
        nv = -nv;
    }
    u += nu * tint * 1e-3;
    v += nv * tint * 1e-3;
    const double d = 2.0 * u - 8.0 * v + 4.0;
    x = 3.0 * u / d;
    y = 2.0 * v / d;
}

std::array<double, 9> white_balance_matrix(double kelvin,
                                           double tint,
                                           double target_kelvin,
                                           double target_tint)
{
    if (kelvin == target_kelvin && tint == target_tint) {
        return {1, 0, 0, 0, 1, 0, 0, 0, 1};
    }
    using M = std::array<double, 9>;
    auto mul = [](const M &a, const M &b) {
        M c{};
        for (int r = 0; r < 3; ++r) {
            for (int k = 0; k < 3; ++k) {
                for (int j = 0; j < 3; ++j) {
                    c[r * 3 + j] += a[r * 3 + k] * b[k * 3 + j];
                }
            }
        }
        return c;
    };
    auto inverse = [](const M &m) {
        const double a = m[0], b = m[1], c = m[2], d = m[3], e = m[4], f = m[5], g = m[6], h = m[7],
                     i = m[8];
        const double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
        return M{(e * i - f * h) / det,
                 (c * h - b * i) / det,
                 (b * f - c * e) / det,
                 (f * g - d * i) / det,
                 (a * i - c * g) / det,
                 (c * d - a * f) / det,
                 (d * h - e * g) / det,
                 (b * g - a * h) / det,
                 (a * e - b * d) / det};
    };
    // Linear Rec.709 (D65) to CIE XYZ, and Bradford's cone response.
    const M rgb_to_xyz = {0.4124564,
                          0.3575761,
                          0.1804375,
                          0.2126729,
                          0.7151522,
                          0.0721750,
                          0.0193339,
                          0.1191920,
                          0.9503041};
    const M bradford = {0.8951, 0.2664, -0.1614, -0.7502, 1.7135, 0.0367, 0.0389, -0.0685, 1.0296};
    auto white = [&](double k, double t) {
        double x, y;
        planckian_xy(k, t, x, y);
        const double xyz[3] = {x / y, 1.0, (1.0 - x - y) / y};
        std::array<double, 3> lms{};
        for (int r = 0; r < 3; ++r) {
            lms[std::size_t(r)] = bradford[std::size_t(r) * 3] * xyz[0] +
                                  bradford[std::size_t(r) * 3 + 1] * xyz[1] +
                                  bradford[std::size_t(r) * 3 + 2] * xyz[2];
        }
        return lms;
    };
    const auto src = white(kelvin, tint), dst = white(target_kelvin, target_tint);
    const M scale = {dst[0] / src[0], 0, 0, 0, dst[1] / src[1], 0, 0, 0, dst[2] / src[2]};
    const M adapt = mul(inverse(bradford), mul(scale, bradford));
    return mul(inverse(rgb_to_xyz), mul(adapt, rgb_to_xyz));
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
    // Alpha 1 (most pixels) skips the division and the product: the same bits either way.
    constexpr float kMinAlpha = 1e-6f;
    auto divides = [&](float a) { return unpremult && a > kMinAlpha && a != 1.0f; };
    auto premultiply_again = [&] {
        for (int x = 0; unpremult && x < width; ++x) {
            float *p = row + std::size_t(x) * std::size_t(nch);
            if (divides(p[3])) {
                p[0] *= p[3];
                p[1] *= p[3];
                p[2] *= p[3];
            }
        }
    };
    // The row's RGB as floats; channels beyond RGB (alpha, extra) are skipped through the
    // strides.
    OCIO::PackedImageDesc rgb_row(row,
                                  width,
                                  1,
                                  OCIO::CHANNEL_ORDERING_RGB,
                                  OCIO::BIT_DEPTH_F32,
                                  sizeof(float),
                                  std::ptrdiff_t(sizeof(float)) * nch,
                                  std::ptrdiff_t(sizeof(float)) * nch * width);
    if (impl_->cpu_half) {
        // RGB as halves through the table, written back as floats over the row's RGB (alpha
        // and extra channels untouched). Finite values past half's range are saturated first,
        // so they stay as bright (or as dark) as they were instead of turning infinite;
        // infinities and NaN come out as they went in (the table's entries for them are not
        // what the exact transform gives: +inf would read as its brightest finite value).
        thread_local std::vector<unsigned char> halves;
        thread_local std::vector<std::pair<std::size_t, float>> odd;  // (value index, value)
        halves.resize(std::size_t(width) * 6);
        odd.clear();
        for (int x = 0; x < width; ++x) {
            float *p = row + std::size_t(x) * std::size_t(nch);
            const bool d = divides(nch >= 4 ? p[3] : 1.0f);
            for (int c = 0; c < 3; ++c) {
                const float v = d ? p[c] / p[3] : p[c];
                if (std::isfinite(v)) {
                    p[c] = std::clamp(v, -65504.0f, 65504.0f);
                } else {
                    p[c] = v;
                    odd.emplace_back(std::size_t(x) * std::size_t(nch) + std::size_t(c), v);
                }
            }
        }
        io_detail::floats_to_halves(row, 3, width, halves.data(), 6, nch);
        const OCIO::PackedImageDesc src(halves.data(),
                                        width,
                                        1,
                                        OCIO::CHANNEL_ORDERING_RGB,
                                        OCIO::BIT_DEPTH_F16,
                                        2,
                                        6,
                                        std::ptrdiff_t(6) * width);
        impl_->cpu_half->apply(src, rgb_row);
        for (const auto &[i, v] : odd) {
            row[i] = v;
        }
        premultiply_again();
        return;
    }
    if (nch == 4) {
        // Packed RGBA is OpenColorIO's in-place path (no conversion to its working buffer):
        // several times faster than RGB with a stride. Alpha is put back afterwards bit for
        // bit (a matrix's 0 * inf in R would otherwise reach it). One pass before, one after.
        std::vector<float> alpha(static_cast<std::size_t>(width));
        for (int x = 0; x < width; ++x) {
            float *p = row + std::size_t(x) * 4;
            alpha[std::size_t(x)] = p[3];
            if (divides(p[3])) {
                p[0] /= p[3];
                p[1] /= p[3];
                p[2] /= p[3];
            }
        }
        OCIO::PackedImageDesc rgba(row, width, 1, 4);
        impl_->cpu->apply(rgba);
        for (int x = 0; x < width; ++x) {
            float *p = row + std::size_t(x) * 4;
            const float a = alpha[std::size_t(x)];
            p[3] = a;
            if (divides(a)) {
                p[0] *= a;
                p[1] *= a;
                p[2] *= a;
            }
        }
        return;
    }
    for (int x = 0; unpremult && x < width; ++x) {
        float *p = row + std::size_t(x) * std::size_t(nch);
        if (divides(p[3])) {
            p[0] /= p[3];
            p[1] /= p[3];
            p[2] /= p[3];
        }
    }
    impl_->cpu->apply(rgb_row);
    premultiply_again();
}

void ColorProcessor::apply(Image &image, bool unpremultiply) const
{
    if (impl_->noop || image.channels() < 3) {
        return;
    }
    // Whole rows: one OpenColorIO call each (a call has a fixed cost).
    parallel_for(0, image.height(), [&](int y) {
        apply_row(image.pixel(0, y), image.width(), image.channels(), unpremultiply);
    });
}

}  // namespace posthaste
