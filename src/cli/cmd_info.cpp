// posthaste info FILE: layers, channels, pixel types, windows, camera, attributes, and where each
// canonical pass comes from (or that it is absent).

#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include <cstdio>

#include "cli/commands.h"
#include "core/error.h"
#include "core/passes.h"
#include "core/text.h"
#include "io/cryptomatte.h"
#include "io/image_file.h"
#include "nodes/read_camera.h"

namespace posthaste::cli {
namespace {

void print_matrix(const char *name, const std::optional<glm::mat4> &m)
{
    if (!m) {
        std::printf("  %-18s absent\n", name);
        return;
    }
    const float *v = &(*m)[0][0];
    std::printf("  %-18s", name);
    for (int r = 0; r < 4; ++r) {
        std::printf("%s[%g %g %g %g]",
                    r ? " " : "",
                    v[r * 4 + 0],
                    v[r * 4 + 1],
                    v[r * 4 + 2],
                    v[r * 4 + 3]);
    }
    std::printf("\n");
}

void print_scalar(const char *name, const std::optional<float> &v, const char *unit)
{
    if (v) {
        std::printf("  %-18s %g%s\n", name, *v, unit);
    } else {
        std::printf("  %-18s absent\n", name);
    }
}

std::string window_text(const Rect &r)
{
    return "(" + std::to_string(r.x0) + "," + std::to_string(r.y0) + ")-(" +
           std::to_string(r.x1 - 1) + "," + std::to_string(r.y1 - 1) + ") " +
           std::to_string(r.width()) + "x" + std::to_string(r.height());
}

/// Where a pass's channels come from: "forward.u, -forward.v", a constant as its value.
std::string sources_text(const PassSource &ps)
{
    std::string from;
    for (const ChannelSource &c : ps.sources) {
        std::string one = c.name.empty() ? std::to_string(c.offset) : c.name;
        if (c.scale != 1.0f && !c.name.empty()) {
            one = (c.scale == -1.0f ? "-" : std::to_string(c.scale) + "*") + one;
        }
        from += (from.empty() ? "" : ", ") + one;
    }
    return from;
}

/// One attribute on one line: a value's newlines and tabs as \n and \t (oiiotool's history),
/// other control characters and bytes that are not UTF-8 as \x1b (a file's escape sequences
/// reached the terminal).
void print_attribute(const char *indent, const OIIO::ParamValue &p)
{
    std::printf("%s%-18s %s = %s\n",
                indent,
                printable_line(p.name().string()).c_str(),
                p.type().c_str(),
                printable_line(OIIO::Strutil::escape_chars(p.get_string(8))).c_str());
}

/// The file's camera as a read node would give it: the header's matrices, else the camera
/// solved from its position and depth passes, else none (with why).
Camera info_camera(const FileInfo &fi, const ReadOptions &options)
{
    Camera camera = fi.camera;
    if (camera.world_to_camera && camera.world_to_ndc) {
        camera.origin = "header";
        return camera;
    }
    bool position = false, depth = false;
    for (const PassSource &ps : fi.passes) {
        position = position || ps.pass == "position";
        depth = depth || ps.pass == "depth";
    }
    if (!position || !depth) {
        // Both matrices or none: one alone says which (it said "no matrices" beside the one
        // printed below).
        camera.origin = camera.world_to_camera ? "none: the header has worldToCamera but no "
                                                 "worldToNDC,"
                        : camera.world_to_ndc  ? "none: the header has worldToNDC but no "
                                                 "worldToCamera,"
                                               : "none: no matrices in the header";
        camera.origin += " and no position + depth passes to solve them from";
        return camera;
    }
    try {
        const std::set<std::string> wanted = {"position", "depth"};
        Frame f = read_frame(fi.path, &wanted, 0, options);
        nodes::solve_frame_camera(f, {}, fi.path);  // the read's defaults
        camera = f.camera;
    } catch (const Error &e) {
        camera.origin = std::string("none: ") + e.what();
    }
    return camera;
}

int info(const std::vector<std::string> &files, const std::string &convention)
{
    ReadOptions options;
    options.count_deep_samples = true;
    options.convention = convention;
    int failed = 0;  // the first bad file's exit code
    for (const std::string &path : files) {
        FileInfo fi;
        try {
            fi = read_file_info(path, options);
        } catch (const Error &e) {
            // The files after a bad one are still described (it stopped at the first).
            std::fflush(stdout);
            std::fprintf(stderr, "error: %s\n", printable_line(e.what()).c_str());
            failed = failed ? failed : e.exit_code();
            continue;
        }
        std::printf("%s\n", printable_line(path).c_str());
        std::printf("  format             %s, %zu part(s)%s%s\n",
                    fi.format.c_str(),
                    fi.parts.size(),
                    fi.conversion.empty() ? "" : ", read as ",
                    fi.conversion.c_str());
        std::printf("  display window     %s\n", window_text(fi.display_window).c_str());
        std::printf("  data window        %s (union of the parts')\n",
                    window_text(fi.data_window).c_str());
        if (!fi.views.empty()) {
            std::string views;
            for (const std::string &v : fi.views) {
                views += (views.empty() ? "" : ", ") + v;
            }
            std::printf("  views              %s; passes from \"%s\", others as pass@view\n",
                        views.c_str(),
                        fi.view.c_str());
        }
        std::printf(
            "  nodes work on      the data window of the parts read (every pass is its "
            "size);\n                     NDC and the sensor span the display window\n");
        for (std::size_t p = 0; p < fi.parts.size(); ++p) {
            const FilePart &part = fi.parts[p];
            std::string kind = part.deep ? "deep " : "";
            kind += part.tiled ? "tiled " + std::to_string(part.tile_width) + "x" +
                                     std::to_string(part.tile_height)
                               : "scanline";
            if (part.mip_levels > 1) {
                kind += part.level_mode == "ripmap"
                            ? ", ripmap " + std::to_string(part.rip_levels.first) + "x" +
                                  std::to_string(part.rip_levels.second) + " levels"
                            : ", " + part.level_mode + " " + std::to_string(part.mip_levels) +
                                  " levels";
            }
            if (!part.envmap.empty()) {
                kind += ", " + part.envmap + " environment";
            }
            std::printf("  part %zu%s%s%s%s%s: data %s, %s%s%s\n",
                        p,
                        part.name.empty() ? "" : " \"",
                        part.name.c_str(),
                        part.name.empty() ? "" : "\"",
                        part.view.empty() ? "" : " view ",
                        part.view.c_str(),
                        window_text(part.data_window).c_str(),
                        kind.c_str(),
                        part.compression.empty() ? "" : ", ",
                        part.compression.c_str());
            if (part.deep && part.deep_samples >= 0) {
                std::printf(
                    "    deep samples: %lld (%.3g per pixel, at most %d)\n",
                    static_cast<long long>(part.deep_samples),
                    double(part.deep_samples) /
                        double(std::int64_t(part.data_window.width()) * part.data_window.height()),
                    part.deep_max_samples);
            }
            std::string line;
            for (const FileChannel &c : part.channels) {
                line += (line.empty() ? "" : ", ") + c.name + " (" + c.type + ")";
            }
            std::printf("    channels: %s\n", line.c_str());
            // What this part's header says beyond the attributes listed below (another part's).
            for (const OIIO::ParamValue &a : part.own_attributes) {
                print_attribute("    attribute ", a);
            }
        }
        const Camera camera = info_camera(fi, options);
        std::printf("camera             %s\n", camera.origin.c_str());
        print_matrix("worldToCamera", camera.world_to_camera);
        print_matrix("worldToNDC", camera.world_to_ndc);
        print_matrix("prevWorldToCamera", fi.camera.prev_world_to_camera);
        print_matrix("prevWorldToNDC", fi.camera.prev_world_to_ndc);
        print_scalar("aperture", camera.fstop, " (f-number)");
        print_scalar("focus", camera.focus_distance, " m");
        print_scalar("focalLength", camera.focal_length_mm, " mm");
        print_scalar("sensorWidth", camera.sensor_width_mm, " mm");
        print_scalar("sensorHeight", camera.sensor_height_mm, " mm");
        print_scalar("shutter", camera.shutter, " (fraction of a frame)");
        print_scalar("nearClip", camera.near_clip, "");
        print_scalar("farClip", camera.far_clip, "");
        // Cryptomattes: their ranks and manifests, or why the file breaks the specification;
        // each on its own (one invalid layer hid the valid ones after it).
        std::vector<std::string> pass_names;
        for (const PassSource &ps : fi.passes) {
            pass_names.push_back(ps.pass);
        }
        std::vector<cryptomatte::Layer> layers;
        try {
            layers = cryptomatte::find_layers(fi.cryptomattes, fi.path);
        } catch (const Error &e) {
            std::printf("cryptomatte        invalid: %s\n", printable_line(e.what()).c_str());
        }
        for (const cryptomatte::Layer &l : layers) {
            try {
                if (!l.problem.empty()) {
                    throw_runtime(l.problem);
                }
                for (const cryptomatte::Layer &other : layers) {
                    if (&other != &l && !l.name.empty() && other.name == l.name) {
                        throw_runtime(fi.path,
                                      ": cryptomatte \"",
                                      l.name,
                                      "\" is declared twice, under keys ",
                                      l.key,
                                      " and ",
                                      other.key,
                                      " (a cryptomatte node refuses it)");
                    }
                }
                const std::vector<std::string> ranks =
                    cryptomatte::rank_passes(l, pass_names, fi.path);
                std::string manifest = "no manifest";
                if (l.has_manifest) {
                    manifest = "manifest of " + std::to_string(l.manifest.size()) + " names (" +
                               (l.manifest_from == "header" ? "header" : l.manifest_from) + ")";
                }
                std::printf("cryptomatte        %s (key %s): %zu rank layers (%zu ranks), %s\n",
                            printable_line(l.name).c_str(),
                            printable_line(l.key).c_str(),
                            ranks.size(),
                            2 * ranks.size(),
                            printable_line(manifest).c_str());
            } catch (const Error &e) {
                std::printf("cryptomatte        invalid: %s\n", printable_line(e.what()).c_str());
            }
        }
        std::printf("attributes\n");
        for (const OIIO::ParamValue &p : fi.attributes) {
            print_attribute("  ", p);
        }
        // The renderers whose pass names were recognised (mapped or refused).
        std::vector<std::string> conventions;
        auto note = [&](const std::string &o) {
            if (o != "canonical" && o != "layer" && o != "luminance" &&
                std::find(conventions.begin(), conventions.end(), o) == conventions.end()) {
                conventions.push_back(o);
            }
        };
        for (const PassSource &s : fi.passes) {
            note(s.origin);
        }
        for (const RefusedPass &r : fi.refused) {
            note(r.origin);
        }
        std::string names;
        for (const std::string &c : conventions) {
            names += (names.empty() ? "" : ", ") + c;
        }
        std::printf("conventions          %s\n",
                    names.empty() ? "posthaste (canonical names)" : names.c_str());
        std::printf("passes\n");
        for (const pass::CanonicalPass &cp : pass::canonical_passes()) {
            const PassSource *ps = nullptr;
            for (const PassSource &s : fi.passes) {
                if (s.pass == cp.name) {
                    ps = &s;
                }
            }
            if (!ps) {
                const std::string hint = fi.refusal_hint(std::string(cp.name));
                std::printf("  %-12s absent%s\n",
                            std::string(cp.name).c_str(),
                            hint.empty() ? "" : (" (" + hint.substr(2) + ")").c_str());
                continue;
            }
            std::printf("  %-12s <- %s (%s)\n",
                        std::string(cp.name).c_str(),
                        sources_text(*ps).c_str(),
                        ps->origin.c_str());
        }
        // Other views' passes ("depth@right"), mapped by the same rules, and other layers.
        for (const PassSource &s : fi.passes) {
            if (!pass::find_canonical(s.pass)) {
                const bool layer = s.origin.empty() || s.origin == "layer";
                std::printf("  %-12s <- %s (%s)\n",
                            s.pass.c_str(),
                            sources_text(s).c_str(),
                            layer ? "other layer" : s.origin.c_str());
            }
        }
    }
    return failed;
}

}  // namespace

/// Read every pixel of each file; one line per damaged file on stderr, exit 1 if any.
int verify(const std::vector<std::string> &files, bool quiet)
{
    int damaged = 0;
    for (const std::string &path : files) {
        const std::string problem = verify_image_file(path);
        if (!problem.empty()) {
            std::fprintf(stderr, "error: %s\n", printable_line(problem).c_str());
            ++damaged;
        } else if (!quiet) {
            std::printf("%s: ok\n", path.c_str());
        }
    }
    return damaged ? 1 : 0;
}

void add_info_command(CLI::App &app, int &exit_code)
{
    auto files = std::make_shared<std::vector<std::string>>();
    auto check = std::make_shared<bool>(false);
    auto quiet = std::make_shared<bool>(false);
    auto convention = std::make_shared<std::string>("auto");
    CLI::App *cmd = app.add_subcommand(
        "info", "Describe image files: parts, channels, camera, attributes, pass mapping");
    cmd->add_option("files", *files, "Image files")->required();
    cmd->add_flag("--verify",
                  *check,
                  "Read every pixel of every part and level instead (like exrcheck): one line "
                  "per damaged file, exit 1 if any");
    cmd->add_flag("--quiet,-q", *quiet, "With --verify: print nothing for whole files");
    std::vector<std::string> names = {"auto", "canonical"};
    for (const auto &[name, origin] : known_conventions()) {
        names.push_back(name);
    }
    cmd->add_option("--convention",
                    *convention,
                    "Whose pass names to recognise (as the read node's convention parameter)")
        ->check(CLI::IsMember(names))
        ->capture_default_str();
    cmd->callback([files, check, quiet, convention, &exit_code] {
        exit_code = *check ? verify(*files, *quiet) : info(*files, *convention);
    });
}

}  // namespace posthaste::cli
