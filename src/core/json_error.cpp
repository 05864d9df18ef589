#include "core/json_error.h"

#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>
#include <vector>

#include "core/error.h"

namespace posthaste {

using json = nlohmann::json;

namespace {

/// "line L, column C: /json/pointer" of the literal quoted in `message` (nlohmann's text after
/// its "[json.exception...]" prefix), or "" when it cannot be found: nlohmann's
/// "number overflow parsing '1e999'" carries neither a position nor a path.
std::string json_overflow_where(const std::string &text, const std::string &message)
{
    const auto q0 = message.find('\''), q1 = message.rfind('\'');
    if (q0 == std::string::npos || q1 <= q0) {
        return "";
    }
    const std::string literal = message.substr(q0 + 1, q1 - q0 - 1);
    const auto at = text.find(literal);
    if (at == std::string::npos) {
        return "";
    }
    // Parse again with the literal replaced by a marker string, and find the marker's path.
    const std::string marker = "\\u0001posthaste-overflow";  // JSON escape of 0x01
    const json doc =
        json::parse(text.substr(0, at) + "\"" + marker + "\"" + text.substr(at + literal.size()),
                    nullptr,
                    false);
    std::string pointer;
    if (!doc.is_discarded()) {
        const json flat = doc.flatten();
        for (auto it = flat.begin(); it != flat.end(); ++it) {
            if (it->is_string() && it->get<std::string>() == "\x01posthaste-overflow") {
                pointer = it.key();
            }
        }
    }
    int line = 1, column = 1;
    for (std::size_t i = 0; i < at; ++i) {
        column = text[i] == '\n' ? 1 : column + 1;
        line += text[i] == '\n';
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(column) +
           (pointer.empty() ? "" : ": " + pointer);
}

/// The one-line reason of a nlohmann exception: its text without the "[json.exception.x.n] "
/// prefix.
std::string json_error_text(const std::string &what)
{
    const auto close = what.find("] ");
    return what.rfind("[json.exception", 0) == 0 && close != std::string::npos
               ? what.substr(close + 2)
               : what;
}

/// The first key that an object of `text` (valid JSON) gives twice, as "\"radius\" in
/// \"params\"" (its object's own key; "the top level" for the outermost), or "" when every key
/// is given once. nlohmann keeps the last of duplicates silently; the readers refuse them.
std::string json_duplicate_key(const std::string &text)
{
    using json = nlohmann::json;
    // Per open object: the keys seen and the key it stands under.
    struct Open {
        std::set<std::string> keys;
        std::string under;
    };
    std::vector<Open> open;
    std::string last_key, found;
    const json::parser_callback_t note = [&](int, json::parse_event_t event, json &parsed) {
        switch (event) {
            case json::parse_event_t::object_start:
                open.push_back({{}, open.empty() ? std::string() : last_key});
                break;
            case json::parse_event_t::object_end:
                open.pop_back();
                break;
            case json::parse_event_t::key:
                last_key = parsed.get<std::string>();
                if (found.empty() && !open.back().keys.insert(last_key).second) {
                    found = "\"" + last_key + "\" in " +
                            (open.size() == 1 ? std::string("the top level")
                                              : "\"" + open.back().under + "\"");
                }
                break;
            default:
                break;
        }
        return true;  // keep everything: a discarded object would not report its end
    };
    try {
        if (json::parse(text, note).is_discarded()) {
            return "";
        }
    } catch (const json::exception &) {
        return "";  // the reader reports what is wrong with the text itself
    }
    return found;
}

/// Line and column (1-based) of a byte offset.
std::string line_column(const std::string &text, std::size_t offset)
{
    int line = 1, col = 1;
    for (std::size_t i = 0; i < std::min(offset, text.size()); ++i) {
        col = text[i] == '\n' ? 1 : col + 1;
        line += text[i] == '\n';
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(col);
}

}  // namespace

nlohmann::json parse_json_document(const std::string &text, const std::string &origin)
{
    if (json_depth(text) > kMaxJsonDepth) {
        throw_usage(origin, ": arrays and objects nest more than ", kMaxJsonDepth, " levels deep");
    }
    json j;
    try {
        j = json::parse(text);
    } catch (const json::parse_error &e) {
        // nlohmann's text repeats the position in its own words: keep what went wrong.
        std::string what = e.what();
        if (const auto p = what.find(": syntax error"); p != std::string::npos) {
            what = what.substr(p + 2);
        } else {
            what = json_error_text(what);
        }
        throw_usage(origin,
                    ": ",
                    line_column(text, e.byte == 0 ? 0 : e.byte - 1),
                    ": invalid JSON: ",
                    what);
    } catch (const json::exception &e) {  // a number that overflows, say
        const std::string what = json_error_text(e.what());
        std::string where = json_overflow_where(text, what);
        if (!where.empty()) {
            where.insert(0, ": ");
        }
        throw_usage(origin, where, ": invalid JSON: ", what);
    }
    if (const std::string twice = json_duplicate_key(text); !twice.empty()) {
        throw_usage(origin, ": key ", twice, " is given twice (JSON would keep only the last)");
    }
    return j;
}

int json_depth(const std::string &text)
{
    int depth = 0, deepest = 0;
    bool in_string = false;
    for (std::size_t i = 0; i < text.size(); ++i) {
        const char c = text[i];
        if (in_string) {
            if (c == '\\') {
                ++i;  // the escaped character
            } else if (c == '"') {
                in_string = false;
            }
        } else if (c == '"') {
            in_string = true;
        } else if (c == '[' || c == '{') {
            deepest = std::max(deepest, ++depth);
        } else if (c == ']' || c == '}') {
            --depth;
        }
    }
    return deepest;
}

}  // namespace posthaste
