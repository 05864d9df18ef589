#include "core/text.h"

#include <charconv>

namespace posthaste {

std::string join(const std::vector<std::string> &items, std::string_view sep)
{
    std::string s;
    for (const std::string &i : items) {
        if (!s.empty()) {
            s += sep;
        }
        s += i;
    }
    return s;
}

std::string printable_line(std::string_view text)
{
    const auto byte = [&](std::size_t i) { return static_cast<unsigned char>(text[i]); };
    std::string out;
    out.reserve(text.size());
    for (std::size_t i = 0; i < text.size();) {
        const unsigned char c = byte(i);
        // The length of the well-formed UTF-8 sequence that starts here (RFC 3629), or 0.
        std::size_t n = c >= 0x20 && c < 0x7F    ? 1
                        : c >= 0xC2 && c <= 0xDF ? 2
                        : c >= 0xE0 && c <= 0xEF ? 3
                        : c >= 0xF0 && c <= 0xF4 ? 4
                                                 : 0;
        bool whole = n > 0 && i + n <= text.size();
        for (std::size_t k = 1; whole && k < n; ++k) {
            whole = (byte(i + k) & 0xC0) == 0x80;
        }
        if (whole && n >= 3) {  // no overlong forms, surrogates or code points past U+10FFFF
            const unsigned char d = byte(i + 1);
            whole = !(c == 0xE0 && d < 0xA0) && !(c == 0xED && d >= 0xA0) &&
                    !(c == 0xF0 && d < 0x90) && !(c == 0xF4 && d >= 0x90);
        }
        if (whole) {
            out.append(text.substr(i, n));
            i += n;
            continue;
        }
        if (c == '\n' || c == '\r' || c == '\t') {
            out += ' ';
        } else {
            static const char digits[] = "0123456789abcdef";
            out += "\\x";
            out += digits[c >> 4];
            out += digits[c & 15];
        }
        ++i;
    }
    return out;
}

std::string xml_escape(const std::string &text)
{
    std::string out;
    out.reserve(text.size());
    for (char c : text) {
        switch (c) {
            case '&':
                out += "&amp;";
                break;
            case '<':
                out += "&lt;";
                break;
            case '>':
                out += "&gt;";
                break;
            case '"':
                out += "&quot;";
                break;
            case '\'':
                out += "&#39;";
                break;
            default:
                if (static_cast<unsigned char>(c) >= 0x20 || c == '\t' || c == '\n' || c == '\r') {
                    out += c;
                }
        }
    }
    return out;
}

std::optional<int> parse_int(std::string_view text)
{
    int value = 0;
    const char *end = text.data() + text.size();
    const auto [ptr, ec] = std::from_chars(text.data(), end, value);
    if (text.empty() || ec != std::errc() || ptr != end) {
        return std::nullopt;
    }
    return value;
}

}  // namespace posthaste
