#pragma once
// Errors carry their context (file, JSON path, node, parameter, channel) in the message and an
// exit code. Only main() catches them: it prints one line and exits with exit_code().

#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

namespace posthaste {

/// Process exit codes, documented in README.md.
enum class ExitCode : int {
    Ok = 0,
    Runtime = 1,  ///< I/O or evaluation failed (missing file, bad pixels, ...).
    Usage = 2,    ///< The command line or the graph is invalid; nothing was computed.
};

/// Concatenate anything that streams into one string: str_cat("frame ", 12, ": ", msg).
template <typename... Args>
std::string str_cat(Args &&...args)
{
    std::ostringstream os;
    (os << ... << std::forward<Args>(args));
    return os.str();
}

/// The one exception type of posthaste. The message is complete and printable as is.
class Error : public std::runtime_error {
   public:
    Error(ExitCode code, std::string message) : std::runtime_error(std::move(message)), code_(code)
    {
    }
    ExitCode code() const { return code_; }
    int exit_code() const { return static_cast<int>(code_); }

   private:
    ExitCode code_;
};

/// An error of a sink writing its output (a full disk, a path that is a directory): never a
/// bad input frame that --skip-bad-frames may pass over.
class OutputError : public Error {
   public:
    using Error::Error;
};

/// A usage or graph error (exit code 2).
template <typename... Args>
[[noreturn]] void throw_usage(Args &&...args)
{
    throw Error(ExitCode::Usage, str_cat(std::forward<Args>(args)...));
}

/// An I/O or runtime error (exit code 1).
template <typename... Args>
[[noreturn]] void throw_runtime(Args &&...args)
{
    throw Error(ExitCode::Runtime, str_cat(std::forward<Args>(args)...));
}

/// Quote a user-supplied string for an error message: "name".
inline std::string quoted(const std::string &s)
{
    return "\"" + s + "\"";
}

}  // namespace posthaste
