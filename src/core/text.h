#pragma once
// Text for messages and reports: lists joined for one-line errors, escaping for the HTML, SVG
// and XML reports (bench charts, diff and suite reports, JUnit), and whole numbers of options.

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace posthaste {

/// The items with `sep` between them ("a, b, c"; empty for none).
std::string join(const std::vector<std::string> &items, std::string_view sep = ", ");

/// `text` safe inside XML or HTML text and attribute values: & < > " ' escaped, and the control
/// characters XML 1.0 does not allow (all below 0x20 but tab, newline and carriage return)
/// dropped.
std::string xml_escape(const std::string &text);

/// `text` as one printable line for an error: newlines, carriage returns and tabs become spaces;
/// other control characters and bytes that are not well-formed UTF-8 are written as "\xff" (a
/// raw byte from a file name or a JSON error's "last read" reached the terminal as it was, and
/// Python refused the message as undecodable).
std::string printable_line(std::string_view text);

/// `text` as a whole decimal integer (an optional minus, digits, nothing else), or nothing.
std::optional<int> parse_int(std::string_view text);

}  // namespace posthaste
