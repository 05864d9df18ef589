#pragma once
// Each subcommand adds itself to the CLI11 app; its callback throws posthaste::Error on failure
// and stores its exit code in `exit_code` otherwise.

#include <CLI/CLI.hpp>
#include <functional>
#include <map>
#include <string>
#include <type_traits>
#include <vector>

#include "graph/run.h"

namespace posthaste::cli {

/// Refuses a value that is empty or blank: CLI11 took --frames "" as not given (every frame).
inline CLI::Validator not_empty()
{
    return CLI::Validator(
        [](std::string &s) {
            return s.find_first_not_of(" \t") == std::string::npos ? std::string("an empty value")
                                                                   : std::string();
        },
        "",
        "not empty");
}

/// CLI11's Range, refusing a value that is not a number as such: Range called "abc" a value out
/// of range. "expected a whole number in 0..1024, got "abc"".
template <typename T>
CLI::Validator in_range(T lo, T hi)
{
    const std::string kind = std::is_integral_v<T> ? "a whole number" : "a number";
    const std::string range = CLI::detail::to_string(lo) + ".." + CLI::detail::to_string(hi);
    return CLI::Validator(
        [=](std::string &text) {
            T value{};
            if (!CLI::detail::lexical_cast(text, value) ||
                !(value >= lo && value <= hi)) {  // NaN too
                std::string why = "expected ";    // appended: GCC 12's -Wrestrict false positive
                why += kind;
                why += " in ";
                why += range;
                why += ", got \"";
                why += text;
                why += '"';
                return why;
            }
            return std::string();
        },
        std::string(CLI::detail::type_name<T>()) + " in [" + CLI::detail::to_string(lo) + " - " +
            CLI::detail::to_string(hi) + "]",
        "in_range");
}

void add_render_command(CLI::App &app, int &exit_code);

void add_run_command(CLI::App &app, int &exit_code);
void add_info_command(CLI::App &app, int &exit_code);
void add_nodes_command(CLI::App &app, int &exit_code);
void add_diff_command(CLI::App &app, int &exit_code);
void add_bench_command(CLI::App &app, int &exit_code);
void add_farm_command(CLI::App &app, int &exit_code);
void add_test_command(CLI::App &app, int &exit_code);

}  // namespace posthaste::cli
