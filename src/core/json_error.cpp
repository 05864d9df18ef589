#include "core/json_error.h"

#include <nlohmann/json.hpp>

namespace posthaste {

using json = nlohmann::json;

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
    const json doc = json::parse(text.substr(0, at) + "\"" + marker + "\"" +
                                     text.substr(at + literal.size()),
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

std::string json_error_text(const std::string &what)
{
    const auto close = what.find("] ");
    return what.rfind("[json.exception", 0) == 0 && close != std::string::npos
               ? what.substr(close + 2)
               : what;
}

}  // namespace posthaste
