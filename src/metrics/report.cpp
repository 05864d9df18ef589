#include "metrics/report.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>

#include "core/error.h"
#include "core/passes.h"
#include "core/text.h"
#include "io/color.h"
#include "io/image_file.h"
#include "metrics/flip.h"

namespace posthaste::metrics {
namespace {

std::string number(double v, const char *format = "%.4g")
{
    if (std::isnan(v)) {
        return "nan";
    }
    if (std::isinf(v)) {
        return v > 0 ? "inf" : "-inf";
    }
    char buf[64];
    std::snprintf(buf, sizeof(buf), format, v);
    return buf;
}

std::string thresholds_text(const Thresholds &t)
{
    std::string s = "fail " + number(t.fail) + ", failpercent " + number(t.fail_percent);
    if (t.fail_relative > 0.0f) {
        s += ", failrelative " + number(t.fail_relative);
    }
    if (std::isfinite(t.hard_fail)) {
        s += ", hardfail " + number(t.hard_fail);
    }
    if (t.allow_failures > 0) {
        s += ", allowfailures " + std::to_string(t.allow_failures);
    }
    s += ", warn " + number(t.warn) + ", warnpercent " + number(t.warn_percent);
    return s;
}

/// The first `channels` (at most 3) channels of `img`, non-finite values replaced (NaN and -inf
/// by 0, +inf by `inf_value`), scaled by `scale`, resized to at most `max_width` pixels wide.
Image thumbnail_source(const Image &img, float scale, float inf_value, int max_width)
{
    const int w = img.width(), h = img.height();
    Image rgb(w, h, 3);
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            const float *p = img.pixel(x, y);
            for (int c = 0; c < 3; ++c) {
                float v = p[std::min(c, img.channels() - 1)];
                v = std::isnan(v) ? 0.0f : std::isinf(v) ? (v > 0 ? inf_value : 0.0f) : v;
                rgb.at(x, y, c) = v * scale;
            }
        }
    }
    if (w <= max_width) {
        return rgb;
    }
    const int tw = max_width;
    const int th = std::max(1, int(std::lround(double(h) * tw / w)));
    OIIO::ImageBuf src(OIIO::ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT), rgb.data());
    OIIO::ImageBuf dst =
        OIIO::ImageBufAlgo::resize(src, "box", 0.0f, OIIO::ROI(0, tw, 0, th, 0, 1, 0, 3), 1);
    Image out(tw, th, 3);
    dst.get_pixels(OIIO::ROI(0, tw, 0, th, 0, 1, 0, 3), OIIO::TypeDesc::FLOAT, out.data());
    return out;
}

/// An 8-bit PNG in memory of display-encoded RGB values in [0, 1].
std::string png_bytes(const Image &display)
{
    const int w = display.width(), h = display.height();
    std::vector<unsigned char> pixels(std::size_t(w) * std::size_t(h) * 3);
    for (std::size_t i = 0; i < pixels.size(); ++i) {
        const float v = std::clamp(display.data()[i], 0.0f, 1.0f);
        pixels[i] = static_cast<unsigned char>(std::lround(v * 255.0f));
    }
    OIIO::Filesystem::IOVecOutput vec;
    auto out = OIIO::ImageOutput::create("png");
    OIIO::ImageSpec spec(w, h, 3, OIIO::TypeDesc::UINT8);
    spec.attribute("png:compressionLevel", 6);
    if (!out || !out->set_ioproxy(&vec) || !out->open("thumbnail.png", spec) ||
        !out->write_image(OIIO::TypeDesc::UINT8, pixels.data()) || !out->close()) {
        throw_runtime("report: cannot encode a PNG thumbnail: ",
                      out ? out->geterror() : OIIO::geterror());
    }
    return std::string(vec.buffer().begin(), vec.buffer().end());
}

const char *verdict_class(Verdict v)
{
    switch (v) {
        case Verdict::Pass:
            return "pass";
        case Verdict::Warning:
            return "warning";
        case Verdict::Failure:
            return "failure";
        case Verdict::SizeMismatch:
            return "mismatch";
        case Verdict::FileError:
            return "error";
    }
    return "error";
}

std::string image_cell(const std::string &png, const std::string &caption)
{
    if (png.empty()) {
        return "<td class=\"img\"><span class=\"none\">" + xml_escape(caption) +
               ": none</span></td>";
    }
    return "<td class=\"img\"><img class=\"thumb\" alt=\"" + xml_escape(caption) +
           "\" src=\"data:image/png;base64," + OIIO::Strutil::base64_encode(png) + "\"><br>" +
           xml_escape(caption) + "</td>";
}

}  // namespace

/// Read a frame for comparison. The reader fills channels a file lacks with constants (color
/// without alpha gets A = 1); those trailing constants are dropped again, so that stored
/// channels alone are compared, as idiff does (RGB against RGBA is then a channel mismatch).
Frame read_for_comparison(const std::string &path,
                          const std::set<std::string> &wanted,
                          int frame_number,
                          const ReadOptions &options)
{
    Frame frame = read_frame(path, wanted.empty() ? nullptr : &wanted, frame_number, options);
    for (const PassSource &ps : read_file_info(path, options).passes) {
        if (!frame.has(ps.pass)) {
            continue;
        }
        // The channels the file stores: not the constants the reader made up after them (an
        // RGB file's alpha), and each file channel once (a luminance file's Y made R, G and B:
        // compared as three, a Y file passed against an RGB file of the same gray).
        std::size_t last = ps.sources.size();
        while (last > 1 && ps.sources[last - 1].part < 0) {
            --last;
        }
        std::vector<std::size_t> keep;
        for (std::size_t k = 0; k < last; ++k) {
            const auto &src = ps.sources[k];
            const bool repeated =
                src.part >= 0 && std::any_of(keep.begin(), keep.end(), [&](std::size_t j) {
                    return ps.sources[j].part == src.part && ps.sources[j].channel == src.channel;
                });
            if (!repeated) {
                keep.push_back(k);
            }
        }
        const Pass &pass = frame.pass(ps.pass);
        if (keep.size() == ps.sources.size() || int(keep.size()) >= pass.image->channels()) {
            continue;
        }
        const Image &full = *pass.image;
        Image trimmed(full.width(), full.height(), int(keep.size()));
        for (int y = 0; y < full.height(); ++y) {
            for (int x = 0; x < full.width(); ++x) {
                for (std::size_t k = 0; k < keep.size(); ++k) {
                    trimmed.pixel(x, y)[k] = full.pixel(x, y)[keep[k]];
                }
            }
        }
        std::vector<std::string> names;
        for (std::size_t k : keep) {
            names.push_back(ps.origin == "luminance" && k == 0 ? "Y" : pass.channels[k]);
        }
        frame.set(ps.pass,
                  std::make_shared<const Image>(std::move(trimmed)),
                  std::move(names),
                  pass.storage);
    }
    return frame;
}

ReportEntry report_entry(const std::string &test,
                         const DiffReport &report,
                         const std::string &a,
                         const std::string &b)
{
    ReportEntry e;
    e.test = test;
    e.frame = report.frame;
    e.a = a;
    e.b = b;
    e.verdict = report.verdict;
    e.messages = report.messages;
    e.thresholds = thresholds_text(report.thresholds);
    for (const PassDiff &d : report.passes) {
        ReportEntry::Pass p;
        p.name = d.name;
        p.verdict = d.verdict;
        if (d.compared) {
            const ErrorStats &s = d.stats.all;
            p.metrics = "mean " + number(s.mean_error) + ", rms " + number(s.rms_error) +
                        ", psnr " + number(s.psnr, "%.2f") + " dB, max " + number(s.max_error) +
                        " at (" + std::to_string(s.max_x) + ", " + std::to_string(s.max_y) +
                        ") channel " +
                        (std::size_t(s.max_channel) < d.channels.size()
                             ? d.channels[std::size_t(s.max_channel)]
                             : std::to_string(s.max_channel)) +
                        ", " + std::to_string(s.fail_count) + " pixels over fail (" +
                        number(d.stats.fail_percent(), "%.3f") + " %)";
            e.worst_rms = std::max(e.worst_rms, std::isfinite(s.rms_error) ? s.rms_error : 1e30);
        } else {
            p.metrics = d.note.empty() ? "not compared" : d.note;
        }
        e.passes.push_back(std::move(p));
    }
    if (report.flip) {
        e.flip_mean = report.flip->result.mean;
    }
    return e;
}

ReportEntry file_error_entry(const std::string &test,
                             int frame,
                             const std::string &a,
                             const std::string &b,
                             const std::string &message)
{
    ReportEntry e;
    e.test = test;
    e.frame = frame;
    e.a = a;
    e.b = b;
    e.verdict = Verdict::FileError;
    e.messages = {message};
    e.worst_rms = 1e30;
    return e;
}

ReportImages report_images(const Frame &a, const Frame &b, const DiffReport &report, int max_width)
{
    ReportImages out;
    // The color pass when both have it, else the first compared pass.
    const PassDiff *shown = nullptr;
    for (const PassDiff &d : report.passes) {
        if (d.compared && (!shown || d.name == pass::kColor)) {
            shown = &d;
        }
    }
    if (!shown || !a.has(shown->name) || !b.has(shown->name)) {
        return out;
    }
    out.shown_pass = shown->name;
    const Image &ia = a.image(shown->name);
    const Image &ib = b.image(shown->name);
    if (shown->name == pass::kColor) {
        const ColorProcessor display =
            ColorProcessor::display_view("lin_rec709", "sRGB", "Standard", "report", true);
        for (const auto &[img, dst] :
             {std::pair{&ia, &out.reference}, std::pair{&ib, &out.result}}) {
            Image t = thumbnail_source(*img, 1.0f, 1.0f, max_width);
            display.apply(t, false);
            *dst = png_bytes(t);
        }
    } else {
        // Data passes: |value| / the largest finite |value| of the reference.
        float peak = 0.0f;
        for (std::size_t i = 0; i < ia.value_count(); ++i) {
            const float v = std::fabs(ia.data()[i]);
            if (std::isfinite(v)) {
                peak = std::max(peak, v);
            }
        }
        const float scale = peak > 0.0f ? 1.0f / peak : 1.0f;
        out.reference = png_bytes(thumbnail_source(ia, scale, 1.0f / scale, max_width));
        out.result = png_bytes(thumbnail_source(ib, scale, 1.0f / scale, max_width));
    }
    if (!shown->difference.empty()) {
        // |a - b| normalised by its largest value (black where the frames agree).
        const double peak = shown->stats.all.max_error;
        const float unit = std::isfinite(peak) && peak > 0.0 ? float(1.0 / peak) : 1.0f;
        out.difference_scale = unit;
        out.difference =
            png_bytes(thumbnail_source(shown->difference, unit, 1.0f / unit, max_width));
    }
    if (report.flip && !report.flip->result.error_map.empty()) {
        out.flip = png_bytes(thumbnail_source(
            flip_heatmap(report.flip->result.error_map, false), 1.0f, 1.0f, max_width));
    }
    return out;
}

std::string html_report(const std::string &title, std::vector<ReportEntry> entries)
{
    std::stable_sort(
        entries.begin(), entries.end(), [](const ReportEntry &x, const ReportEntry &y) {
            if (x.verdict != y.verdict) {
                return int(x.verdict) > int(y.verdict);
            }
            return x.worst_rms > y.worst_rms;
        });
    int counts[5] = {};
    for (const ReportEntry &e : entries) {
        ++counts[int(e.verdict)];
    }
    Verdict worst = Verdict::Pass;
    for (const ReportEntry &e : entries) {
        worst = metrics::worse(worst, e.verdict);
    }
    std::string h;
    h += "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\n<title>" +
         xml_escape(title) + "</title>\n";
    h += R"(<style>
body { font-family: sans-serif; margin: 16px; background: #fafafa; color: #222; }
table { border-collapse: collapse; }
td, th { border: 1px solid #ccc; padding: 4px 6px; vertical-align: top; font-size: 13px; }
td.verdict { width: 90px; font-weight: bold; text-align: center; }
tr.failure td.verdict, tr.mismatch td.verdict, tr.error td.verdict { background: #ff0000; color: #fff; }
tr.warning td.verdict { background: #ffaa00; }
tr.pass td.verdict { background: #00c000; color: #fff; }
td.img { text-align: center; font-size: 11px; }
img.thumb { max-width: 240px; image-rendering: pixelated; }
.summary span { margin-right: 16px; }
pre { margin: 0; white-space: pre-wrap; }
</style>
<script>
window.addEventListener('load', function () {
  var images = document.querySelectorAll('img.thumb'), decoded = 0;
  for (var i = 0; i < images.length; ++i) {
    if (images[i].complete && images[i].naturalWidth > 0) { ++decoded; }
  }
  document.getElementById('decoded').textContent = decoded + ' of ' + images.length;
});
</script>
</head><body>
)";
    h += "<h1>" + xml_escape(title) + "</h1>\n<p class=\"summary\">";
    h += "<span>verdict: <b>" + std::string(verdict_name(worst)) + "</b></span>";
    const char *names[5] = {"pass", "warning", "failure", "size mismatch", "file error"};
    for (int v = 0; v < 5; ++v) {
        h += "<span>" + std::string(names[v]) + ": <b id=\"count-" + verdict_class(Verdict(v)) +
             "\">" + std::to_string(counts[v]) + "</b></span>";
    }
    h += "<span>images decoded: <b id=\"decoded\">(script not run)</b></span></p>\n";
    h += "<table>\n<tr><th>verdict</th><th>test / frame</th><th>passes</th><th>reference</th>"
         "<th>result</th><th>|difference|</th><th>FLIP</th></tr>\n";
    for (const ReportEntry &e : entries) {
        h += "<tr class=\"entry " + std::string(verdict_class(e.verdict)) + "\">";
        h += "<td class=\"verdict\">" + std::string(verdict_name(e.verdict)) + "</td>";
        h += "<td><b>" + xml_escape(e.test) + "</b><br>frame " + std::to_string(e.frame) +
             "<br><small>" + xml_escape(e.a) + "<br>" + xml_escape(e.b) + "</small></td><td><pre>";
        for (const ReportEntry::Pass &p : e.passes) {
            h += xml_escape(p.name + " [" + verdict_name(p.verdict) + "]: " + p.metrics) + "\n";
        }
        if (e.flip_mean >= 0.0) {
            h += "FLIP mean " + number(e.flip_mean) + "\n";
        }
        for (const std::string &m : e.messages) {
            h += xml_escape(m) + "\n";
        }
        if (!e.thresholds.empty()) {
            h += "<small>" + xml_escape(e.thresholds) + "</small>";
        }
        h += "</pre></td>";
        const std::string pass =
            e.images.shown_pass.empty() ? "" : " (" + e.images.shown_pass + ")";
        h += image_cell(e.images.reference, "reference" + pass);
        h += image_cell(e.images.result, "result" + pass);
        h += image_cell(e.images.difference,
                        "|a - b| x " + number(e.images.difference_scale, "%.3g"));
        h += image_cell(e.images.flip, "FLIP");
        h += "</tr>\n";
    }
    h += "</table>\n</body></html>\n";
    return h;
}

std::string junit_xml(const std::string &name, const std::vector<ReportEntry> &entries)
{
    // Group by test, in first-seen order.
    std::vector<std::string> order;
    std::map<std::string, std::vector<const ReportEntry *>> by_test;
    for (const ReportEntry &e : entries) {
        if (!by_test.count(e.test)) {
            order.push_back(e.test);
        }
        by_test[e.test].push_back(&e);
    }
    struct Case {
        std::string name;
        double seconds = 0.0;
        std::string kind;  // "", "failure", "error"
        std::string message, text, out;
    };
    std::string body;
    int all_tests = 0, all_failures = 0, all_errors = 0;
    double all_seconds = 0.0;
    for (const std::string &test : order) {
        std::vector<Case> cases;
        for (const ReportEntry *e : by_test[test]) {
            char frame[32];
            std::snprintf(frame, sizeof(frame), "frame %04d", e->frame);
            const double share = e->seconds / double(std::max<std::size_t>(1, e->passes.size()));
            if (e->passes.empty() || e->verdict == Verdict::FileError ||
                e->verdict == Verdict::SizeMismatch) {
                Case c;
                c.name = frame;
                c.seconds = e->seconds;
                std::string all;
                for (const std::string &m : e->messages) {
                    all += (all.empty() ? "" : "; ") + m;
                }
                if (e->verdict == Verdict::FileError) {
                    c.kind = "error";
                } else if (e->verdict == Verdict::SizeMismatch || e->verdict == Verdict::Failure) {
                    c.kind = "failure";
                }
                c.message = std::string(verdict_name(e->verdict)) + ": " + all;
                c.text = e->a + " vs " + e->b + "\n" + all;
                cases.push_back(std::move(c));
                continue;
            }
            for (const ReportEntry::Pass &p : e->passes) {
                Case c;
                c.name = std::string(frame) + " " + p.name;
                c.seconds = share;
                const std::string detail =
                    p.name + ": " + p.metrics + " (thresholds: " + e->thresholds + ")";
                if (p.verdict == Verdict::Failure || p.verdict == Verdict::SizeMismatch) {
                    c.kind = "failure";
                    c.message = std::string(verdict_name(p.verdict)) + ": " + detail;
                    c.text = e->a + " vs " + e->b + "\n" + detail;
                } else if (p.verdict == Verdict::FileError) {
                    c.kind = "error";
                    c.message = detail;
                    c.text = detail;
                } else {
                    c.out = std::string(verdict_name(p.verdict)) + ": " + detail;
                }
                cases.push_back(std::move(c));
            }
        }
        int failures = 0, errors = 0;
        double seconds = 0.0;
        for (const Case &c : cases) {
            failures += c.kind == "failure";
            errors += c.kind == "error";
            seconds += c.seconds;
        }
        body += "  <testsuite name=\"" + xml_escape(test) + "\" tests=\"" +
                std::to_string(cases.size()) + "\" failures=\"" + std::to_string(failures) +
                "\" errors=\"" + std::to_string(errors) + "\" skipped=\"0\" time=\"" +
                number(seconds, "%.3f") + "\">\n";
        for (const Case &c : cases) {
            body += "    <testcase classname=\"" + xml_escape(name + "." + test) + "\" name=\"" +
                    xml_escape(c.name) + "\" time=\"" + number(c.seconds, "%.3f") + "\"";
            if (c.kind.empty() && c.out.empty()) {
                body += "/>\n";
                continue;
            }
            body += ">\n";
            if (!c.kind.empty()) {
                body += "      <" + c.kind + " message=\"" + xml_escape(c.message) + "\" type=\"" +
                        c.kind + "\">" + xml_escape(c.text) + "</" + c.kind + ">\n";
            }
            if (!c.out.empty()) {
                body += "      <system-out>" + xml_escape(c.out) + "</system-out>\n";
            }
            body += "    </testcase>\n";
        }
        body += "  </testsuite>\n";
        all_tests += int(cases.size());
        all_failures += failures;
        all_errors += errors;
        all_seconds += seconds;
    }
    return "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites name=\"" + xml_escape(name) +
           "\" tests=\"" + std::to_string(all_tests) + "\" failures=\"" +
           std::to_string(all_failures) + "\" errors=\"" + std::to_string(all_errors) +
           "\" time=\"" + number(all_seconds, "%.3f") + "\">\n" + body + "</testsuites>\n";
}

}  // namespace posthaste::metrics
