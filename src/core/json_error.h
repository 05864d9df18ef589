#pragma once
// Where a JSON reader error sits when nlohmann's exception does not say: its
// "[json.exception.out_of_range.406] number overflow parsing '1e999'" carries neither a position
// nor a path. Shared by the graph, scene and bench spec readers.

#include <nlohmann/json.hpp>
#include <string>

namespace posthaste {

/// "line L, column C: /json/pointer" of the literal quoted in `message` (nlohmann's text after
/// its "[json.exception...]" prefix), or "" when it cannot be found.
std::string json_overflow_where(const std::string &text, const std::string &message);

/// The one-line reason of a nlohmann exception: its text without the "[json.exception.x.n] "
/// prefix.
std::string json_error_text(const std::string &what);

/// The first key that an object of `text` (valid JSON) gives twice, as "\"radius\" in
/// \"params\"" (its object's own key; "the top level" for the outermost), or "" when every key
/// is given once. nlohmann keeps the last of duplicates silently; the readers refuse them.
std::string json_duplicate_key(const std::string &text);

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
