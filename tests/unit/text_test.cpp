// Text for messages: printable_line keeps well-formed UTF-8 and writes every other byte so that
// a terminal, a log and Python can take the line.

#include "core/text.h"

#include <gtest/gtest.h>

#include <string>

namespace posthaste {
namespace {

TEST(Text, PrintableLineEscapesWhatIsNotWellFormedUtf8)
{
    EXPECT_EQ(printable_line("plain ascii: ok"), "plain ascii: ok");
    EXPECT_EQ(printable_line("two\nlines\r\tend"), "two lines  end");
    // Well-formed UTF-8 passes: é (2 bytes), € (3), 𝄞 (4).
    EXPECT_EQ(printable_line("caf\xC3\xA9 \xE2\x82\xAC \xF0\x9D\x84\x9E"),
              "caf\xC3\xA9 \xE2\x82\xAC \xF0\x9D\x84\x9E");
    // A stray byte, a control character and DEL are written in hex.
    EXPECT_EQ(printable_line("a\xFFz"), "a\\xffz");
    EXPECT_EQ(printable_line(std::string("nul\0bell\a", 9)), "nul\\x00bell\\x07");
    EXPECT_EQ(printable_line("\x7F"), "\\x7f");
    // Cut short, overlong, a surrogate, beyond U+10FFFF: each byte on its own.
    EXPECT_EQ(printable_line("\xE2\x82"), "\\xe2\\x82");
    EXPECT_EQ(printable_line("\xC0\xAF"), "\\xc0\\xaf");
    EXPECT_EQ(printable_line("\xE0\x80\xAF"), "\\xe0\\x80\\xaf");
    EXPECT_EQ(printable_line("\xED\xA0\x80"), "\\xed\\xa0\\x80");
    EXPECT_EQ(printable_line("\xF4\x90\x80\x80"), "\\xf4\\x90\\x80\\x80");
    // A lead byte followed by ASCII: the lead byte escaped, the ASCII kept.
    EXPECT_EQ(printable_line("\xC3(x"), "\\xc3(x");
}

}  // namespace
}  // namespace posthaste
