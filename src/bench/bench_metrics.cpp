// The bench's measuring (bench_metrics.h): errors of a setting's output against the truth, with
// the sky left out when asked, and the thumbnails of the HTML page.

#include "bench/bench_metrics.h"

#include <algorithm>
#include <cmath>
#include <memory>

#include "core/error.h"
#include "core/text.h"
#include "graph/graph.h"
#include "metrics/flip.h"
#include "metrics/metrics.h"

namespace posthaste::bench {
namespace {

/// First three channels, sRGB-encoded, clamped, box-downscaled so the longer side is <= max_side.
Image display_thumbnail(const Image &img, float scale, int max_side = 160)
{
    const int step = std::max(1, (std::max(img.width(), img.height()) + max_side - 1) / max_side);
    const int w = std::max(1, img.width() / step), h = std::max(1, img.height() / step);
    Image out(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < 3; ++c) {
                double sum = 0.0;
                int n = 0;
                for (int yy = y * step; yy < std::min(img.height(), (y + 1) * step); ++yy) {
                    for (int xx = x * step; xx < std::min(img.width(), (x + 1) * step); ++xx) {
                        const float v = img.at(xx, yy, std::min(c, img.channels() - 1));
                        sum += std::isfinite(v) ? double(v) : 0.0;
                        ++n;
                    }
                }
                const float v = float(sum / std::max(n, 1)) * scale;
                out.at(x, y, c) = metrics::flip::linear_to_srgb(std::clamp(v, 0.0f, 1.0f));
            }
        }
    }
    return out;
}

}  // namespace

ImagePtr display_part(const Frame &frame, const ImagePtr &image)
{
    // An overscan's margin is the nodes' input, not their result, and a truth rendered without
    // it covers the display window alone.
    const Rect d = frame.display_window.intersect(frame.data_window);
    if (d == frame.data_window || d.empty()) {
        return image;
    }
    return std::make_shared<const Image>(place_in_window(*image, frame.data_window, d));
}

std::string listed(const Frame &frame)
{
    return join(frame.pass_names(), ", ");
}

FrameErrors frame_errors(
    const Image &ref, const Image &test, const Image *depth, bool flip, const std::string &where)
{
    FrameErrors e;
    if (!depth) {
        const metrics::CompareStats stats = metrics::compare(ref, test);
        e.rmse = stats.all.rms_error;
        e.psnr = stats.all.psnr;
        if (flip) {
            e.flip = metrics::flip_hdr(ref, test).mean;
        }
        return e;
    }
    std::vector<std::size_t> keep;
    for (std::size_t i = 0; i < depth->pixel_count(); ++i) {
        if (std::isfinite(depth->data()[i * std::size_t(depth->channels())])) {
            keep.push_back(i);
        }
    }
    if (keep.empty()) {
        // An error of no pixels is no number: RMSE 0 and PSNR inf would read as exact.
        throw_usage(where, ": no pixels left after exclude sky (every depth is infinite)");
    }
    const std::size_t nc = std::size_t(ref.channels());
    Image pa(int(keep.size()), 1, int(nc)), pb(int(keep.size()), 1, int(nc));
    for (std::size_t k = 0; k < keep.size(); ++k) {
        std::copy_n(ref.data() + keep[k] * nc, nc, pa.data() + k * nc);
        std::copy_n(test.data() + keep[k] * nc, nc, pb.data() + k * nc);
    }
    const metrics::CompareStats stats = metrics::compare(pa, pb);
    e.rmse = stats.all.rms_error;
    e.psnr = stats.all.psnr;
    if (flip) {
        // FLIP filters the whole image: the sky takes the truth's values, so it adds no
        // difference, and the map is averaged over the kept pixels alone, as RMSE is.
        Image masked(test);
        for (std::size_t i = 0; i < depth->pixel_count(); ++i) {
            if (!std::isfinite(depth->data()[i * std::size_t(depth->channels())])) {
                std::copy_n(ref.data() + i * nc, nc, masked.data() + i * nc);
            }
        }
        const Image map = metrics::flip_hdr(ref, masked).error_map;
        double sum = 0.0;
        for (std::size_t i : keep) {
            sum += double(map.data()[i * std::size_t(map.channels())]);
        }
        e.flip = sum / double(keep.size());
    }
    return e;
}

SettingResult measure_setting(const BenchSpec &spec,
                              const BenchSetting &setting,
                              const Graph &graph,
                              const std::vector<int> &frames,
                              const std::vector<ImagePtr> &truth)
{
    SettingResult r;
    r.setting = setting;
    double rmse = 0.0, psnr = 0.0, flip = 0.0;
    for (std::size_t i = 0; i < frames.size(); ++i) {
        const int f = frames[i];
        const Frame out = graph.evaluate(f);
        const std::string in = str_cat(" in setting ", quoted(setting.name), ", frame ", f);
        const std::string node = "node " + quoted(spec.node);
        // What the spec asks of the output is the spec's mistake: found here, before timing.
        if (!out.has(spec.pass)) {
            throw_usage(spec.origin,
                        ":/pass: ",
                        node,
                        " gives no pass ",
                        quoted(spec.pass),
                        " (have: ",
                        listed(out),
                        ")",
                        in);
        }
        if (spec.exclude_sky && !out.has("depth")) {
            throw_usage(spec.origin,
                        ":/exclude: ",
                        node,
                        " gives no pass \"depth\" to find the sky by (have: ",
                        listed(out),
                        ")",
                        in);
        }
        const std::string who = node + "," + in;
        const ImagePtr test_part = display_part(out, out.pass(spec.pass, who).image);
        const Image &test = *test_part;
        const Image &ref = *truth[i];
        if (spec.flip && test.channels() < 3) {
            throw_usage(spec.origin,
                        ":/metrics: flip needs RGB (3 channels), but pass ",
                        quoted(spec.pass),
                        " has ",
                        test.channels(),
                        " channel(s)",
                        in);
        }
        if (test.width() != ref.width() || test.height() != ref.height() ||
            test.channels() != ref.channels()) {
            throw_runtime(spec.origin,
                          ": ",
                          who,
                          ": pass ",
                          quoted(spec.pass),
                          " is ",
                          test.width(),
                          "x",
                          test.height(),
                          "x",
                          test.channels(),
                          " but the truth is ",
                          ref.width(),
                          "x",
                          ref.height(),
                          "x",
                          ref.channels());
        }
        ImagePtr depth;
        if (spec.exclude_sky) {
            depth = display_part(out, out.pass("depth", who).image);
        }
        const FrameErrors e = frame_errors(
            ref, test, depth.get(), spec.flip, str_cat(spec.origin, ":/exclude: ", who));
        rmse += e.rmse;
        psnr += e.psnr;
        flip += e.flip;
        if (i == 0) {
            r.thumbnail = display_thumbnail(test, 1.0f);
            r.difference =
                display_thumbnail(metrics::difference_image(ref, test, 1.0f), spec.diff_scale);
        }
    }
    const double n = double(frames.size());
    r.rmse = rmse / n;
    r.psnr = psnr / n;
    r.flip = spec.flip ? flip / n : kNaN;
    return r;
}

std::string valid_utf8(std::string_view text)
{
    static const std::string replacement = "\xEF\xBF\xBD";
    std::string out;
    out.reserve(text.size());
    const auto *s = reinterpret_cast<const unsigned char *>(text.data());
    const std::size_t n = text.size();
    for (std::size_t i = 0; i < n;) {
        const unsigned char c = s[i];
        std::size_t len = 0;
        unsigned char lo = 0x80, hi = 0xBF;  // the second byte's range (RFC 3629)
        if (c < 0x80) {
            len = 1;
        } else if (c >= 0xC2 && c <= 0xDF) {
            len = 2;
        } else if (c >= 0xE0 && c <= 0xEF) {
            len = 3;
            lo = c == 0xE0 ? 0xA0 : 0x80;
            hi = c == 0xED ? 0x9F : 0xBF;
        } else if (c >= 0xF0 && c <= 0xF4) {
            len = 4;
            lo = c == 0xF0 ? 0x90 : 0x80;
            hi = c == 0xF4 ? 0x8F : 0xBF;
        }
        bool ok = len > 0 && i + len <= n;
        for (std::size_t k = 1; ok && k < len; ++k) {
            ok = k == 1 ? s[i + 1] >= lo && s[i + 1] <= hi : s[i + k] >= 0x80 && s[i + k] <= 0xBF;
        }
        if (ok) {
            out.append(text.substr(i, len));
            i += len;
        } else {
            out += replacement;
            ++i;
        }
    }
    return out;
}

}  // namespace posthaste::bench
