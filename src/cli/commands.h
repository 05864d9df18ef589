#pragma once
// Each subcommand adds itself to the CLI11 app; its callback throws posthaste::Error on failure
// and stores its exit code in `exit_code` otherwise.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "graph/run.h"

namespace posthaste::cli {

void add_render_command(CLI::App &app, int &exit_code);

void add_run_command(CLI::App &app, int &exit_code);
void add_info_command(CLI::App &app, int &exit_code);
void add_nodes_command(CLI::App &app, int &exit_code);
void add_diff_command(CLI::App &app, int &exit_code);
void add_bench_command(CLI::App &app, int &exit_code);
void add_farm_command(CLI::App &app, int &exit_code);
void add_test_command(CLI::App &app, int &exit_code);

}  // namespace posthaste::cli
