#pragma once
// Text for the HTML, SVG and XML reports (bench charts, diff and suite reports, JUnit).

#include <string>

namespace posthaste {

/// `text` safe inside XML or HTML text and attribute values: & < > " ' escaped, and the control
/// characters XML 1.0 does not allow (all below 0x20 but tab, newline and carriage return)
/// dropped.
std::string xml_escape(const std::string &text);

}  // namespace posthaste
