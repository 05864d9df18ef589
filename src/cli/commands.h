#pragma once
// Each subcommand adds itself to the CLI11 app; its callback throws posthaste::Error on failure
// and stores its exit code in `exit_code` otherwise.

#include <CLI/CLI.hpp>

namespace posthaste::cli {

void add_run_command(CLI::App &app, int &exit_code);
void add_info_command(CLI::App &app, int &exit_code);
void add_nodes_command(CLI::App &app, int &exit_code);
void add_diff_command(CLI::App &app, int &exit_code);
void add_bench_command(CLI::App &app, int &exit_code);

/// True when stderr is a terminal (progress bars) and NO_COLOR-style plain output is not forced.
bool stderr_is_terminal();

}  // namespace posthaste::cli
