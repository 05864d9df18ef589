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

/// A pass image refused by the memory budget (--max-memory) while it was shared: a run with
/// several frames in flight runs the frame again with fewer (graph/run.cpp).
class MemoryBudgetError : public Error {
   public:
    MemoryBudgetError(ExitCode code, std::string message, bool output = false)
        : Error(code, std::move(message)), output_(output)
    {
    }
    /// Refused to a sink: with one frame in flight it fails the run as an OutputError does.
    bool output() const { return output_; }

   private:
    bool output_;
};

/// `e` again with `prefix` before its message, of its own kind (a budget refusal stays one).
[[noreturn]] inline void rethrow_with_prefix(const Error &e, const std::string &prefix)
{
    if (const auto *m = dynamic_cast<const MemoryBudgetError *>(&e)) {
        throw MemoryBudgetError(e.code(), prefix + e.what(), m->output());
    }
    if (dynamic_cast<const OutputError *>(&e)) {
        throw OutputError(e.code(), prefix + e.what());
    }
    throw Error(e.code(), prefix + e.what());
}

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
