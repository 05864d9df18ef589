#pragma once
// Shared by the libFuzzer targets: every posthaste::Error is an expected outcome (a clean,
// one-line rejection); anything else (a crash, a sanitizer report, another exception) is a
// finding.

#include <cstddef>
#include <cstdint>
#include <string>

#include "core/error.h"

namespace posthaste::fuzz {

/// The input as text.
inline std::string text_of(const std::uint8_t *data, std::size_t size)
{
    return std::string(reinterpret_cast<const char *>(data), size);
}

/// Run `fn`; swallow posthaste::Error (the documented rejection) and let anything else escape.
template <typename Fn>
void expect_clean(Fn &&fn)
{
    try {
        fn();
    } catch (const Error &) {
    }
}

}  // namespace posthaste::fuzz
