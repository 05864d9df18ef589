#include "metrics/diff.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>

#include "core/error.h"

namespace posthaste::metrics {
namespace {

std::string join(const std::vector<std::string> &items)
{
    std::string s;
    for (const std::string &i : items) {
        s += (s.empty() ? "" : ", ") + i;
    }
    return s.empty() ? "none" : s;
}

std::string channel_name(const std::vector<std::string> &names, int c)
{
    return c >= 0 && c < int(names.size()) ? names[std::size_t(c)] : std::to_string(c);
}

/// "data window 8x8 at (0, 0) vs 16x16 at (0, 0)".
std::string windows_differ(const char *which, const Rect &wa, const Rect &wb)
{
    return str_cat(which,
                   " window ",
                   wa.width(),
                   "x",
                   wa.height(),
                   " at (",
                   wa.x0,
                   ", ",
                   wa.y0,
                   ") vs ",
                   wb.width(),
                   "x",
                   wb.height(),
                   " at (",
                   wb.x0,
                   ", ",
                   wb.y0,
                   ")");
}

PassDiff diff_pass(const std::string &name, const Pass &pa, const Pass &pb, const DiffOptions &o)
{
    PassDiff d;
    d.name = name;
    d.channels = pa.channels;
    const Image &a = *pa.image;
    const Image &b = *pb.image;
    if (a.channels() != b.channels()) {
        d.verdict = Verdict::SizeMismatch;
        d.note = str_cat("pass \"",
                         name,
                         "\": ",
                         a.channels(),
                         " channels (",
                         join(pa.channels),
                         ") vs ",
                         b.channels(),
                         " channels (",
                         join(pb.channels),
                         ")");
        return d;
    }
    if (a.width() != b.width() || a.height() != b.height()) {
        d.verdict = Verdict::SizeMismatch;
        d.note = str_cat("pass \"",
                         name,
                         "\": ",
                         a.width(),
                         "x",
                         a.height(),
                         " vs ",
                         b.width(),
                         "x",
                         b.height());
        return d;
    }
    d.compared = true;
    d.stats = compare(a, b, o.thresholds);
    d.verdict = verdict(d.stats, o.thresholds);
    if (pa.channels != pb.channels) {
        d.verdict = worse(d.verdict, Verdict::Warning);
        d.note = str_cat("pass \"",
                         name,
                         "\": channels differ in name (",
                         join(pa.channels),
                         " vs ",
                         join(pb.channels),
                         "); compared by position");
    }
    if (o.images) {
        d.difference = difference_image(a, b, o.difference_scale);
    }
    return d;
}

nlohmann::json number(double v)
{
    if (std::isnan(v)) {
        return "nan";
    }
    if (std::isinf(v)) {
        return v > 0 ? "inf" : "-inf";
    }
    return v;
}

nlohmann::json stats_json(const ErrorStats &s,
                          const std::vector<std::string> &channels,
                          std::uint64_t pixels)
{
    const double n = double(std::max<std::uint64_t>(pixels, 1));
    return {
        {"mean_error", number(s.mean_error)},
        {"rms_error", number(s.rms_error)},
        {"psnr", number(s.psnr)},
        {"peak", number(s.peak)},
        {"max_error", number(s.max_error)},
        {"max_pixel", {s.max_x, s.max_y}},
        {"max_channel", channel_name(channels, s.max_channel)},
        {"warn_pixels", s.warn_count},
        {"warn_percent", 100.0 * double(s.warn_count) / n},
        {"fail_pixels", s.fail_count},
        {"fail_percent", 100.0 * double(s.fail_count) / n},
    };
}

std::string short_number(double v)
{
    std::ostringstream os;
    os << std::setprecision(4) << v;
    return os.str();
}

}  // namespace

DiffReport diff_frames(const Frame &a, const Frame &b, const DiffOptions &options)
{
    if (!(options.difference_scale >= 0.0f)) {
        throw_usage("diff: difference scale must be >= 0, got ", options.difference_scale);
    }
    if (!(options.pixels_per_degree > 0.0f && options.pixels_per_degree <= kMaxPixelsPerDegree)) {
        throw_usage("diff: pixels per degree must lie in (0, ",
                    kMaxPixelsPerDegree,
                    "], got ",
                    options.pixels_per_degree);
    }
    DiffReport r;
    r.frame = a.number;
    r.width = a.width();
    r.height = a.height();
    r.thresholds = options.thresholds;
    if (a.data_window != b.data_window) {
        const Rect &wa = a.data_window, &wb = b.data_window;
        r.verdict = Verdict::SizeMismatch;
        // The summary line names the frame already ("frame 0: SIZE MISMATCH; frame 0: ...").
        r.messages.push_back(windows_differ("data", wa, wb));
        return r;
    }
    // The same pixels placed in another frame (a crop or overscan lost, a format changed): the
    // pixels compare, the file does not match (it passed without a word).
    if (a.display_window != b.display_window) {
        const Rect &wa = a.display_window, &wb = b.display_window;
        r.verdict = Verdict::Warning;
        r.messages.push_back(windows_differ("display", wa, wb));
    }

    std::vector<std::string> names;
    if (options.passes.empty()) {
        for (const std::string &n : a.pass_names()) {
            (b.has(n) ? names : r.only_in_a).push_back(n);
        }
        for (const std::string &n : b.pass_names()) {
            if (!a.has(n)) {
                r.only_in_b.push_back(n);
            }
        }
        if (!r.only_in_a.empty() || !r.only_in_b.empty()) {
            r.verdict = Verdict::Warning;
            r.messages.push_back(str_cat("passes differ: only in a: ",
                                         join(r.only_in_a),
                                         "; only in b: ",
                                         join(r.only_in_b)));
        }
    } else {
        for (const std::string &n : options.passes) {
            if (std::find(names.begin(), names.end(), n) != names.end()) {
                continue;
            }
            for (const auto &[frame, label] : {std::pair{&a, "a"}, std::pair{&b, "b"}}) {
                if (!frame->has(n)) {
                    r.verdict = Verdict::FileError;
                    r.messages.push_back(str_cat("frame ",
                                                 label,
                                                 " has no pass \"",
                                                 n,
                                                 "\" (have: ",
                                                 join(frame->pass_names()),
                                                 ")"));
                }
            }
            if (a.has(n) && b.has(n)) {
                names.push_back(n);
            }
        }
        std::sort(names.begin(), names.end());
    }
    if (names.empty() && r.messages.empty()) {
        r.verdict = worse(r.verdict, Verdict::Warning);
        r.messages.push_back("no passes to compare");
    }

    for (const std::string &n : names) {
        PassDiff d = diff_pass(n, a.pass(n), b.pass(n), options);
        r.verdict = worse(r.verdict, d.verdict);
        if (!d.note.empty()) {
            r.messages.push_back(d.note);
        }
        r.passes.push_back(std::move(d));
    }

    if (options.flip != FlipMode::Off) {
        const auto it = std::find_if(r.passes.begin(), r.passes.end(), [&](const PassDiff &d) {
            return d.name == options.flip_pass;
        });
        if (it == r.passes.end() || !it->compared) {
            r.messages.push_back(str_cat("flip: pass \"",
                                         options.flip_pass,
                                         "\" not compared in both frames; FLIP skipped"));
        } else if (a.image(options.flip_pass).channels() < 3) {
            r.messages.push_back(str_cat("flip: pass \"",
                                         options.flip_pass,
                                         "\" has ",
                                         a.image(options.flip_pass).channels(),
                                         " channels, FLIP needs RGB; skipped"));
        } else {
            FlipDiff f;
            f.pass = options.flip_pass;
            f.hdr = options.flip == FlipMode::Hdr;
            f.pixels_per_degree = options.pixels_per_degree;
            FlipOptions fo;
            fo.pixels_per_degree = options.pixels_per_degree;
            const Image &ia = a.image(options.flip_pass);
            const Image &ib = b.image(options.flip_pass);
            f.result = f.hdr ? flip_hdr(ia, ib, fo) : flip_ldr(ia, ib, fo);
            if (options.images) {
                f.heatmap = flip_heatmap(f.result.error_map, true);
            } else {
                f.result.error_map = Image();
            }
            r.flip = std::move(f);
        }
    }
    return r;
}

std::string to_json(const DiffReport &r)
{
    const Thresholds &t = r.thresholds;
    nlohmann::json j = {
        {"frame", r.frame},
        {"width", r.width},
        {"height", r.height},
        {"verdict", verdict_name(r.verdict)},
        {"exit_code", r.exit_code()},
        {"thresholds",
         {{"fail", number(t.fail)},
          {"fail_relative", number(t.fail_relative)},
          {"fail_percent", number(t.fail_percent)},
          {"hard_fail", number(t.hard_fail)},
          {"allow_failures", t.allow_failures},
          {"warn", number(t.warn)},
          {"warn_relative", number(t.warn_relative)},
          {"warn_percent", number(t.warn_percent)},
          {"hard_warn", number(t.hard_warn)}}},
        {"only_in_a", r.only_in_a},
        {"only_in_b", r.only_in_b},
        {"messages", r.messages},
    };
    nlohmann::json passes = nlohmann::json::array();
    for (const PassDiff &d : r.passes) {
        nlohmann::json p = {
            {"name", d.name},
            {"channels", d.channels},
            {"compared", d.compared},
            {"verdict", verdict_name(d.verdict)},
        };
        if (!d.note.empty()) {
            p["note"] = d.note;
        }
        if (d.compared) {
            p["stats"] = stats_json(d.stats.all, d.channels, d.stats.pixel_count);
            nlohmann::json per = nlohmann::json::object();
            for (std::size_t c = 0; c < d.stats.channels.size(); ++c) {
                per[channel_name(d.channels, int(c))] =
                    stats_json(d.stats.channels[c], d.channels, d.stats.pixel_count);
            }
            p["per_channel"] = per;
        }
        passes.push_back(p);
    }
    j["passes"] = passes;
    if (r.flip) {
        const FlipDiff &f = *r.flip;
        nlohmann::json fj = {
            {"pass", f.pass},
            {"mode", f.hdr ? "hdr" : "ldr"},
            {"pixels_per_degree", f.pixels_per_degree},
            {"mean", number(f.result.mean)},
            {"max", number(f.result.max)},
            {"max_pixel", {f.result.max_x, f.result.max_y}},
        };
        if (f.hdr) {
            fj["start_exposure"] = number(f.result.start_exposure);
            fj["stop_exposure"] = number(f.result.stop_exposure);
            fj["num_exposures"] = f.result.num_exposures;
        }
        j["flip"] = fj;
    } else {
        j["flip"] = nullptr;
    }
    return j.dump(2);
}

std::string summary_line(const DiffReport &r)
{
    std::ostringstream os;
    os << "frame " << r.frame << ": " << verdict_name(r.verdict);
    for (const PassDiff &d : r.passes) {
        os << "; " << d.name;
        if (!d.compared) {
            os << " not compared";
            continue;
        }
        const ErrorStats &s = d.stats.all;
        os << " mean " << short_number(s.mean_error) << " rms " << short_number(s.rms_error)
           << " psnr " << short_number(s.psnr) << " max " << short_number(s.max_error);
        if (s.max_error != 0.0) {
            os << " @ (" << s.max_x << ", " << s.max_y << ", "
               << channel_name(d.channels, s.max_channel) << ")";
        }
        os << " fail " << s.fail_count << " (" << short_number(d.stats.fail_percent()) << "%)";
    }
    if (r.flip) {
        os << "; flip(" << (r.flip->hdr ? "hdr" : "ldr") << ") mean "
           << short_number(r.flip->result.mean) << " max " << short_number(r.flip->result.max);
    }
    for (const std::string &m : r.messages) {
        os << "; " << m;
    }
    return os.str();
}

}  // namespace posthaste::metrics
