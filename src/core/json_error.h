#pragma once
// The JSON documents posthaste reads (graphs, scenes, bench specs, test specs, stability
// records): one-line errors with the place of what is wrong, nesting bounded, keys given once.

#include <nlohmann/json.hpp>
#include <string>

namespace posthaste {

/// How deep arrays and objects nest in `text` (JSON; brackets inside strings do not count).
/// The readers refuse more than kMaxJsonDepth: printing such a value for a message recursed
/// until the stack overflowed.
int json_depth(const std::string &text);
inline constexpr int kMaxJsonDepth = 64;

/// `text` as a JSON document, or a usage error naming `origin` and what is wrong: invalid JSON
/// (nlohmann's reason; a number that overflows with its place), nesting deeper than
/// kMaxJsonDepth, a key given twice.
nlohmann::json parse_json_document(const std::string &text, const std::string &origin);

}  // namespace posthaste
