// posthaste: the command line. Exit codes: 0 success, 1 I/O or runtime error, 2 usage or graph
// error (README.md "Exit codes"). Every error is one line on stderr.

#include <malloc.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <string>

#include "cli/commands.h"
#include "core/disk_cache.h"
#include "core/error.h"
#include "core/simd.h"
#include "core/text.h"

namespace {

/// What a command printed must have reached its destination: `posthaste nodes > /dev/full`
/// exited 0 with nothing written. Flushes stdout; on a failure names it on stderr and returns
/// the worse of `code` and the command's exit code for an output it cannot write (diff's and
/// test's FILE ERROR, 4; else 1).
int check_stdout(int code, const char *command)
{
    errno = 0;
    const bool failed = std::fflush(stdout) != 0 || std::ferror(stdout) != 0;
    if (!failed) {
        return code;
    }
    std::fprintf(
        stderr, "error: standard output: %s\n", errno != 0 ? std::strerror(errno) : "write failed");
    const std::string c = command ? command : "";
    const int mine = c == "diff" || c == "test" ? 4 : int(posthaste::ExitCode::Runtime);
    return code > mine ? code : mine;
}

}  // namespace

int main(int argc, char **argv)
{
    using namespace posthaste;
    // Pass images are large (8 MB per channel at 1080p) and made anew every frame. glibc serves
    // blocks this size with mmap and unmaps them on free, so each frame would page-fault its
    // images in again; keep freed memory in the heap for the next frame instead.
    mallopt(M_MMAP_THRESHOLD, 1 << 30);
    mallopt(M_TRIM_THRESHOLD, 1 << 30);
    if (const std::string bad = simd::environment_error(); !bad.empty()) {
        std::fprintf(stderr, "error: %s\n", printable_line(bad).c_str());
        return int(ExitCode::Usage);
    }
    CLI::App app{"posthaste: a node-graph compositor for multi-layer OpenEXR frame sequences"};
    app.set_version_flag("--version", std::string("posthaste ") + POSTHASTE_VERSION);
    app.require_subcommand(1);
    app.footer(
        "Exit codes: 0 success, 1 I/O or runtime error, 2 usage or graph error\n"
        "(diff: idiff's 0 ok, 1 warning, 2 failure, 3 size mismatch, 4 file error).\n"
        "Run 'posthaste COMMAND --help' for a command's options.");
    // Options of the whole program, accepted before or after the command's own.
    app.fallthrough();
    app.add_flag_callback(
           "--no-cache",
           [] { disk_cache::set_enabled(false); },
           "Neither read nor write the cache of start-up tables (atmosphere LUTs, hatching "
           "maps, voxel meshes) in $POSTHASTE_CACHE_DIR, else $XDG_CACHE_HOME/posthaste, else "
           "~/.cache/posthaste")
        ->trigger_on_parse();
    int exit_code = 0;
    cli::add_run_command(app, exit_code);
    cli::add_render_command(app, exit_code);
    cli::add_info_command(app, exit_code);
    cli::add_nodes_command(app, exit_code);
    cli::add_diff_command(app, exit_code);
    cli::add_bench_command(app, exit_code);
    cli::add_farm_command(app, exit_code);
    cli::add_test_command(app, exit_code);
    std::string command_line;
    for (int i = 0; i < argc; ++i) {
        command_line += (i ? " " : "") + std::string(argv[i]);
    }
    // A first word that is no command: name it and the commands (CLI11 would say only that a
    // command is required).
    if (argc > 1 && argv[1][0] != '-') {
        std::string names;
        bool known = false;
        for (const CLI::App *sub : app.get_subcommands({})) {
            known = known || sub->get_name() == argv[1];
            names += (names.empty() ? "" : ", ") + sub->get_name();
        }
        if (!known) {
            std::fprintf(stderr,
                         "error: unknown command \"%s\" (commands: %s)\n",
                         printable_line(argv[1]).c_str(),
                         names.c_str());
            return int(ExitCode::Usage);
        }
    }
    try {
        app.parse(argc, argv);
    } catch (const CLI::ParseError &e) {
        if (e.get_exit_code() == 0) {
            return check_stdout(app.exit(e), nullptr);  // --help, --version
        }
        std::fprintf(stderr, "error: %s (see --help)\n", printable_line(e.what()).c_str());
        return int(ExitCode::Usage);
    } catch (const Error &e) {
        std::string msg = printable_line(e.what());
        if (command_line.find("--set") != std::string::npos) {
            msg += " [command line: " + printable_line(command_line) + "]";
        }
        std::fprintf(stderr, "error: %s\n", msg.c_str());
        return e.exit_code();
    } catch (const std::exception &e) {
        std::fprintf(stderr, "error: %s\n", printable_line(e.what()).c_str());
        return int(ExitCode::Runtime);
    }
    return check_stdout(exit_code, argc > 1 ? argv[1] : nullptr);
}
