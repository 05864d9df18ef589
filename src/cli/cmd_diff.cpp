// posthaste diff A B: regression diff of two files or two frame sequences, pass by pass, with
// idiff's thresholds and exit codes (0 ok, 1 warning, 2 failure, 3 size mismatch, 4 file error);
// the exit code is the worst verdict over frames. Optional difference images, FLIP heat maps and
// a JSON report covering every frame. The comparison itself is metrics::diff_frames.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>

#include "cli/commands.h"
#include "core/error.h"
#include "core/parallel.h"
#include "core/passes.h"
#include "core/text.h"
#include "graph/graph.h"
#include "io/image_file.h"
#include "io/sequence.h"
#include "metrics/diff.h"
#include "metrics/report.h"

namespace posthaste::cli {
namespace {

struct DiffCliOptions {
    std::string a, b;
    std::string frames;
    std::vector<std::string> passes;
    metrics::Thresholds thresholds;
    std::string flip = "hdr";
    float ppd = metrics::kDefaultPixelsPerDegree;
    std::string diff_image;
    float diff_scale = 1.0f;
    std::string flip_map;
    std::string json;
    std::string report_dir;
    std::string junit;
    int threads = 0;
    bool quiet = false;
    bool frames_given = false;  ///< --frames was on the command line ("" is refused).
};

std::vector<int> frames_to_compare(const DiffCliOptions &o)
{
    if (o.frames_given) {
        // Two single files compared N times reported "N frames".
        if (!has_frame_placeholder(o.a) && !has_frame_placeholder(o.b)) {
            throw_usage("--frames: neither ", o.a, " nor ", o.b, " has a frame placeholder (####)");
        }
        return parse_frame_list(o.frames, "--frames");
    }
    if (!has_frame_placeholder(o.a)) {
        return {0};
    }
    std::vector<int> frames = find_frames_on_disk(o.a);
    if (frames.empty()) {
        throw Error(ExitCode(metrics::exit_code(metrics::Verdict::FileError)),
                    str_cat(o.a,
                            ": no files match this pattern (give --frames to compare a "
                            "range and report the missing ones)"));
    }
    return frames;
}

void check_output_pattern(const std::string &pattern, const char *option, std::size_t frames)
{
    if (!pattern.empty() && frames > 1 && !has_frame_placeholder(pattern)) {
        throw_usage(option,
                    " ",
                    quoted(pattern),
                    ": comparing several frames needs a frame placeholder (#### or %04d)");
    }
}

/// The difference images of every compared pass, as one frame (same pass and channel names).
Frame difference_frame(const metrics::DiffReport &report, const Frame &a)
{
    Frame f;
    f.number = report.frame;
    f.set_size(report.width, report.height);
    for (const metrics::PassDiff &d : report.passes) {
        if (d.compared && !d.difference.empty()) {
            f.set(d.name,
                  std::make_shared<const Image>(d.difference),
                  a.pass(d.name).channels,
                  PixelStorage::Float);
        }
    }
    return f;
}

void write_flip_map(const metrics::FlipDiff &flip, const std::string &path, int frame_number)
{
    if (is_exr_path(path)) {
        Frame f;
        f.number = frame_number;
        f.set_size(flip.heatmap.width(), flip.heatmap.height());
        f.set(pass::kColor,
              std::make_shared<const Image>(flip.heatmap),
              {"R", "G", "B"},
              PixelStorage::Half);
        f.set("flip",
              std::make_shared<const Image>(flip.result.error_map),
              {"Y"},
              PixelStorage::Float);
        write_exr(f, path, WriteOptions{});
    } else {
        write_preview(metrics::flip_heatmap(flip.result.error_map, false), path, false);
    }
}

int run(const DiffCliOptions &o)
{
    using metrics::Verdict;
    set_thread_count(o.threads);
    metrics::DiffOptions options;
    options.thresholds = o.thresholds;
    for (const std::string &p : o.passes) {
        for (const std::string &name : split_list(p)) {
            options.passes.push_back(name);
        }
    }
    options.flip = o.flip == "off"   ? metrics::FlipMode::Off
                   : o.flip == "ldr" ? metrics::FlipMode::Ldr
                                     : metrics::FlipMode::Hdr;
    options.pixels_per_degree = o.ppd;
    options.difference_scale = o.diff_scale;
    options.images = !o.diff_image.empty() || !o.flip_map.empty() || !o.report_dir.empty();
    std::vector<metrics::ReportEntry> entries;
    const bool collect = !o.report_dir.empty() || !o.junit.empty();

    const std::vector<int> frames = frames_to_compare(o);
    check_output_pattern(o.diff_image, "--diff-image", frames.size());
    if (const std::string ext = std::filesystem::path(o.diff_image).extension().string();
        !o.diff_image.empty() && ext != ".exr" && ext != ".EXR") {
        // It wrote an EXR under any name ("d.png" held OpenEXR data).
        throw_usage(
            "--diff-image: the difference is written as EXR (float, NaN kept): give a "
            "name ending in .exr, got ",
            o.diff_image);
    }
    check_output_pattern(o.flip_map, "--flip-map", frames.size());
    if (!o.flip_map.empty() && options.flip == metrics::FlipMode::Off) {
        throw_usage("--flip-map: FLIP is off (--flip off), so there is no map to write");
    }
    const std::set<std::string> wanted(options.passes.begin(), options.passes.end());
    ReadOptions read_options;
    read_options.linearize = false;  // compare stored values, as idiff does

    const bool sequence = has_frame_placeholder(o.a) || has_frame_placeholder(o.b);
    Verdict worst = Verdict::Pass;
    int counts[5] = {};
    nlohmann::json frames_json = nlohmann::json::array();
    for (int frame : frames) {
        const auto t0 = std::chrono::steady_clock::now();
        const std::string path_a = expand_frame_pattern(o.a, frame);
        const std::string path_b = expand_frame_pattern(o.b, frame);
        Frame fa, fb;
        std::string file_error;
        for (const auto &[path, target] : {std::pair{&path_a, &fa}, std::pair{&path_b, &fb}}) {
            try {
                *target = metrics::read_for_comparison(*path, wanted, frame, read_options);
            } catch (const Error &e) {
                file_error = e.what();
                break;
            }
        }
        if (!file_error.empty()) {
            worst = metrics::worse(worst, Verdict::FileError);
            ++counts[int(Verdict::FileError)];
            if (sequence) {
                std::fprintf(stderr,
                             "frame %d: FILE ERROR: %s\n",
                             frame,
                             printable_line(file_error).c_str());
            } else {
                std::fprintf(stderr, "error: %s\n", printable_line(file_error).c_str());
            }
            frames_json.push_back({{"frame", frame},
                                   {"a", path_a},
                                   {"b", path_b},
                                   {"verdict", metrics::verdict_name(Verdict::FileError)},
                                   {"exit_code", metrics::exit_code(Verdict::FileError)},
                                   {"messages", {file_error}}});
            if (collect) {
                entries.push_back(
                    metrics::file_error_entry("diff", frame, path_a, path_b, file_error));
            }
            continue;
        }
        const metrics::DiffReport report = metrics::diff_frames(fa, fb, options);
        worst = metrics::worse(worst, report.verdict);
        ++counts[int(report.verdict)];
        if (!o.quiet) {
            std::printf("%s\n", metrics::summary_line(report).c_str());
        }
        if (!o.diff_image.empty() && report.verdict != Verdict::SizeMismatch) {
            const Frame d = difference_frame(report, fa);
            if (!d.passes().empty()) {
                write_exr(d, expand_frame_pattern(o.diff_image, frame), WriteOptions{});
            }
        }
        if (!o.flip_map.empty() && report.flip) {
            write_flip_map(*report.flip, expand_frame_pattern(o.flip_map, frame), frame);
        }
        if (collect) {
            metrics::ReportEntry e = metrics::report_entry("diff", report, path_a, path_b);
            if (!o.report_dir.empty()) {
                e.images = metrics::report_images(fa, fb, report);
            }
            e.seconds =
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
            entries.push_back(std::move(e));
        }
        if (!o.json.empty()) {
            nlohmann::json j = nlohmann::json::parse(metrics::to_json(report));
            j["a"] = path_a;
            j["b"] = path_b;
            frames_json.push_back(std::move(j));
        }
    }

    if (!o.json.empty()) {
        const nlohmann::json report = {
            {"a", o.a},
            {"b", o.b},
            {"verdict", metrics::verdict_name(worst)},
            {"exit_code", metrics::exit_code(worst)},
            {"frame_count", frames.size()},
            {"frames", frames_json},
        };
        write_text_file(o.json, report.dump(2) + "\n");
    }
    if (!o.report_dir.empty()) {
        const std::string page = (std::filesystem::path(o.report_dir) / "index.html").string();
        write_text_file(page, metrics::html_report("posthaste diff " + o.a + " " + o.b, entries));
        if (!o.quiet) {
            std::printf("report: %s\n", page.c_str());
        }
    }
    if (!o.junit.empty()) {
        write_text_file(o.junit, metrics::junit_xml("diff", entries));
    }
    if (!o.quiet && frames.size() > 1) {
        std::printf(
            "%zu frames: %d pass, %d warning, %d failure, %d size mismatch, %d file "
            "error; %s\n",
            frames.size(),
            counts[0],
            counts[1],
            counts[2],
            counts[3],
            counts[4],
            metrics::verdict_name(worst));
    }
    return metrics::exit_code(worst);
}

/// A number above `low` (or at least it), and at most `high`: "must be a number above 0, got
/// 0", where CLI11's checks wrote out a range up to DBL_MAX. NaN is refused (a NaN threshold
/// turned a FAILURE into a WARNING); "inf" passes where high is infinite (a hard limit off).
CLI::Validator bounded_below(double low,
                             bool inclusive,
                             double high = std::numeric_limits<double>::infinity())
{
    const std::string bound = str_cat(inclusive ? "of at least " : "above ",
                                      low,
                                      std::isinf(high) ? "" : str_cat(" and at most ", high));
    return CLI::Validator(
        [low, inclusive, high, bound](std::string &text) -> std::string {
            char *end = nullptr;
            const double v = std::strtod(text.c_str(), &end);
            const bool ok = end != text.c_str() && *end == '\0' &&
                            (inclusive ? v >= low : v > low) && v <= high;
            return ok ? std::string() : "must be a number " + bound + ", got " + text;
        },
        str_cat(inclusive ? ">= " : "> ", low));
}

}  // namespace

void add_diff_command(CLI::App &app, int &exit_code)
{
    auto o = std::make_shared<DiffCliOptions>();
    CLI::App *cmd = app.add_subcommand(
        "diff",
        "Compare two images or frame sequences (idiff thresholds and exit codes: 0 ok, "
        "1 warning, 2 failure, 3 size mismatch, 4 file error)");
    cmd->add_option("a", o->a, "Reference: file or frame pattern (#### or %04d)")->required();
    cmd->add_option("b", o->b, "Test: file or frame pattern")->required();
    CLI::Option *frames = cmd->add_option("--frames,-f",
                                          o->frames,
                                          "Frames: 1-48, 1-48x2, 1,5,10-20 (default: the "
                                          "frames of A found on disk)")
                              ->check(not_empty());
    cmd->add_option("--pass,-p",
                    o->passes,
                    "Passes to compare, comma-separated (default: every pass in both)")
        ->allow_extra_args(false);
    metrics::Thresholds &t = o->thresholds;
    cmd->add_option("--fail", t.fail, "Failure threshold on |a - b|")
        ->check(bounded_below(0.0, true))
        ->capture_default_str();
    cmd->add_option(
           "--failrelative", t.fail_relative, "Relative failure threshold (of mean |a|, |b|)")
        ->check(bounded_below(0.0, true));
    cmd->add_option("--failpercent", t.fail_percent, "Percent of pixels allowed over --fail")
        ->check(bounded_below(0.0, true, 100.0))
        ->capture_default_str();
    cmd->add_option("--hardfail", t.hard_fail, "Fail if any error is above this")
        ->check(bounded_below(0.0, true));
    cmd->add_option(
           "--allowfailures", t.allow_failures, "Pass outright when at most this many pixels fail")
        ->check(bounded_below(0.0, true));
    cmd->add_option("--warn", t.warn, "Warning threshold on |a - b|")
        ->check(bounded_below(0.0, true))
        ->capture_default_str();
    cmd->add_option("--warnrelative", t.warn_relative, "Relative warning threshold")
        ->check(bounded_below(0.0, true));
    cmd->add_option("--warnpercent", t.warn_percent, "Percent of pixels allowed over --warn")
        ->check(bounded_below(0.0, true, 100.0))
        ->capture_default_str();
    cmd->add_option("--hardwarn", t.hard_warn, "Warn if any error is above this")
        ->check(bounded_below(0.0, true));
    cmd->add_option("--flip",
                    o->flip,
                    "FLIP on the color pass: hdr (scene-linear), ldr "
                    "(sRGB in [0,1]) or off; reported, never a verdict")
        ->check(CLI::IsMember({"hdr", "ldr", "off"}))
        ->capture_default_str();
    cmd->add_option("--ppd", o->ppd, "FLIP pixels per degree")
        ->check(bounded_below(0.0, false, metrics::kMaxPixelsPerDegree))
        ->capture_default_str();
    cmd->add_option("--diff-image",
                    o->diff_image,
                    "Write |a - b| * --diff-scale per pass to this EXR (pattern)");
    cmd->add_option("--diff-scale", o->diff_scale, "Scale of the difference images")
        ->check(bounded_below(0.0, true))
        ->capture_default_str();
    cmd->add_option("--flip-map",
                    o->flip_map,
                    "Write the FLIP heat map here (PNG: display-encoded; EXR: linear + error)");
    cmd->add_option("--json", o->json, "Write a JSON report of every frame");
    cmd->add_option("--report",
                    o->report_dir,
                    "Write an HTML report (DIR/index.html, self-contained: thumbnails of "
                    "reference, result, difference and FLIP; failures first)");
    cmd->add_option("--junit",
                    o->junit,
                    "Write JUnit XML: a test case per frame and pass, failures with their metrics");
    cmd->add_option("--threads,-t", o->threads, "Worker threads (default: all cores)")
        ->check(in_range(0, 1024));
    cmd->add_flag("--quiet,-q", o->quiet, "Print nothing but errors");
    cmd->callback([o, frames, &exit_code] {
        o->frames_given = frames->count() > 0;
        // What is not a usage error (an output that cannot be written, memory) is idiff's file
        // error, 4: exit 1 read as a WARNING and hid a FAILURE from a pipeline.
        const ExitCode file_error = ExitCode(metrics::exit_code(metrics::Verdict::FileError));
        try {
            exit_code = run(*o);
        } catch (const Error &e) {
            throw e.code() == ExitCode::Usage ? e : Error(file_error, e.what());
        } catch (const std::exception &e) {
            throw Error(file_error, std::string("out of memory or another failure: ") + e.what());
        }
    });
}

}  // namespace posthaste::cli
