#include "core/text.h"

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

}  // namespace posthaste
