// Atomic writes (image_file.h): a file is written under a temporary name beside its target and
// renamed into place, so that a failed or killed write never leaves a half-written file at the
// final name; temporaries a killed process left behind are tidied.

#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <random>
#include <set>

#include "core/error.h"
#include "io/image_file.h"

namespace posthaste {

namespace fs = std::filesystem;

namespace {

/// Remove temporary files of posthaste's naming (".NAME.tmpPID-N.ext") that a killed write left
/// in `dir`: those whose process is not alive here and that are over 10 minutes old (the age
/// keeps a live write of another host on a shared file system safe). Once per directory and
/// process; failures are ignored (the directory is someone else's to tidy).
void remove_stale_temporaries(const fs::path &dir)
{
    static std::mutex mutex;
    static std::set<std::string> done;
    {
        std::lock_guard lock(mutex);
        if (!done.insert(dir.string()).second) {
            return;
        }
    }
    std::error_code ec;
    const auto now = fs::file_time_type::clock::now();
    for (fs::directory_iterator it(dir.empty() ? fs::path(".") : dir, ec), end; !ec && it != end;
         it.increment(ec)) {
        const std::string name = it->path().filename().string();
        const auto tmp = name.rfind(".tmp");
        if (name.size() < 6 || name[0] != '.' || tmp == std::string::npos || tmp == 0) {
            continue;
        }
        const auto dash = name.find('-', tmp);
        if (dash == std::string::npos) {
            continue;
        }
        const std::string pid_text = name.substr(tmp + 4, dash - tmp - 4);
        if (pid_text.empty() || pid_text.find_first_not_of("0123456789") != std::string::npos ||
            pid_text.size() > 9) {
            continue;
        }
        const int pid = std::stoi(pid_text);
        if (pid == ::getpid() || ::kill(pid, 0) == 0 || errno != ESRCH) {
            continue;  // alive (or not ours to judge)
        }
        std::error_code age_ec;
        const auto mtime = fs::last_write_time(it->path(), age_ec);
        if (age_ec || now - mtime < std::chrono::minutes(10)) {
            continue;
        }
        fs::remove(it->path(), age_ec);
    }
}

/// The temporaries being written now, for a SIGINT or SIGTERM to remove before the process
/// ends (a killed write left a partial ".NAME.tmpPID-N.exr" that only a later run, ten minutes
/// on, tidied). Fixed slots and async-signal-safe calls only: the handler runs anywhere.
constexpr int kSlots = 64;
char g_temporary[kSlots][4096];
std::atomic<pid_t> g_owner[kSlots];  // the process that registered the slot
std::atomic<bool> g_slot_used[kSlots];

void remove_temporaries_and_die(int sig)
{
    // A child forked without exec inherits the slots: it leaves its parent's files alone.
    const pid_t self = ::getpid();
    for (int i = 0; i < kSlots; ++i) {
        if (g_slot_used[i].load(std::memory_order_acquire) &&
            g_owner[i].load(std::memory_order_relaxed) == self) {
            ::unlink(g_temporary[i]);
        }
    }
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

/// Install the handler for SIGINT and SIGTERM, once, where nobody else handles them (the Python
/// module's interpreter keeps its own).
void install_signal_cleanup()
{
    static std::once_flag once;
    std::call_once(once, [] {
        for (const int sig : {SIGINT, SIGTERM}) {
            struct sigaction old {};
            if (::sigaction(sig, nullptr, &old) == 0 && old.sa_handler == SIG_DFL) {
                struct sigaction sa {};
                sa.sa_handler = &remove_temporaries_and_die;
                sigemptyset(&sa.sa_mask);
                ::sigaction(sig, &sa, nullptr);
            }
        }
    });
}

/// A temporary registered for the handler while it exists (no slot free: not registered).
class TemporaryGuard {
   public:
    explicit TemporaryGuard(const std::string &path)
    {
        if (path.size() >= sizeof(g_temporary[0])) {
            return;
        }
        for (int i = 0; i < kSlots; ++i) {
            bool expected = false;
            if (g_slot_busy[i].compare_exchange_strong(expected, true)) {
                std::memcpy(g_temporary[i], path.c_str(), path.size() + 1);
                g_owner[i].store(::getpid(), std::memory_order_relaxed);
                g_slot_used[i].store(true, std::memory_order_release);
                slot_ = i;
                return;
            }
        }
    }
    ~TemporaryGuard()
    {
        if (slot_ >= 0) {
            g_slot_used[slot_].store(false, std::memory_order_release);
            g_slot_busy[slot_].store(false, std::memory_order_release);
        }
    }
    TemporaryGuard(const TemporaryGuard &) = delete;
    TemporaryGuard &operator=(const TemporaryGuard &) = delete;

   private:
    static inline std::atomic<bool> g_slot_busy[kSlots];
    int slot_ = -1;
};

}  // namespace

void atomic_write(const std::string &path, const std::function<void(const std::string &)> &write)
{
    std::error_code ec;
    // A link is written through (the rename replaced the link with a file and left its
    // target as it was).
    fs::path target(path);
    for (int hops = 0; hops < 40 && fs::is_symlink(target, ec); ++hops) {
        const fs::path to = fs::read_symlink(target, ec);
        if (ec) {
            break;
        }
        target = (to.is_absolute() ? to : target.parent_path() / to).lexically_normal();
    }
    // A device, FIFO or socket would be replaced by the rename: refused (write_file_bytes
    // writes text and bytes into a pipe or terminal in place).
    if (const fs::file_status st = fs::status(target, ec);
        !ec && fs::exists(st) && !fs::is_regular_file(st) && !fs::is_directory(st)) {
        throw_runtime(path,
                      ": not a regular file (a device, pipe or socket): an image is written to a "
                      "temporary file and renamed onto its path");
    }
    if (target.has_parent_path()) {
        fs::create_directories(target.parent_path(), ec);
        if (ec) {
            throw_runtime(path,
                          ": cannot create directory ",
                          target.parent_path().string(),
                          ": ",
                          ec.message());
        }
    }
    remove_stale_temporaries(target.parent_path());
    // Keep the extension last: OIIO picks the writer from it.
    thread_local std::mt19937 rng(std::random_device{}());
    // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) on "." + std::string here.
    std::string suffix = ".tmp";
    suffix += std::to_string(::getpid());
    suffix += '-';
    suffix += std::to_string(rng() % 100000);
    suffix += target.extension().string();
    // The stem is cut where the temporary's name would pass the file system's 255 bytes (a
    // valid long name failed for its temporary's).
    std::string stem = target.stem().string();
    stem.resize(
        std::min(stem.size(), std::size_t(255) - std::min<std::size_t>(255, 1 + suffix.size())));
    std::string name = ".";
    name += stem;
    name += suffix;
    const std::string tmp = (target.parent_path() / name).string();
    install_signal_cleanup();
    const TemporaryGuard guard(tmp);
    try {
        write(tmp);
    } catch (const Error &e) {
        // The libraries say "file output failed"; say why when the disk is the reason.
        std::error_code space_ec;
        const std::uintmax_t written = fs::file_size(tmp, space_ec);
        const fs::space_info space =
            fs::space(target.has_parent_path() ? target.parent_path() : fs::path("."), space_ec);
        fs::remove(tmp, ec);
        const std::string what = e.what();
        // Another cause the library named, or a file system with no capacity at all (/proc,
        // /sys: 0 KiB free, but not full), is not a full disk.
        const bool other_cause = space.capacity == 0 ||
                                 what.find(std::strerror(ENOENT)) != std::string::npos ||
                                 what.find(std::strerror(EACCES)) != std::string::npos ||
                                 what.find(std::strerror(EROFS)) != std::string::npos;
        if (!space_ec && !other_cause &&
            space.available < std::max<std::uintmax_t>(written, 1) + (64u << 10)) {
            // Where the library already gave the cause (strerror's words), only the free space.
            const bool said = what.find(std::strerror(ENOSPC)) != std::string::npos;
            throw Error(e.code(),
                        what + (said ? " (" : " (no space left on the device: ") +
                            std::to_string(space.available >> 10) + " KiB free)");
        }
        throw;
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    // A file written again keeps its permissions, and its owner where this process may give it.
    struct stat was {};
    if (::stat(target.c_str(), &was) == 0 && S_ISREG(was.st_mode)) {
        ::chmod(tmp.c_str(), was.st_mode & 07777);
        if (was.st_uid != ::geteuid() || was.st_gid != ::getegid()) {
            [[maybe_unused]] const int ignored = ::chown(tmp.c_str(), was.st_uid, was.st_gid);
        }
    }
    fs::rename(tmp, target, ec);
    if (ec) {
        const std::string why = ec.message();  // before the removal's own code replaces it
        fs::remove(tmp, ec);
        throw_runtime(path, ": cannot rename temporary file into place: ", why);
    }
}

void write_file_bytes(const std::string &path, const void *data, std::size_t size)
{
    // A terminal, a pipe or /dev/stdout is written in place: a rename would replace it with a
    // file (--json /dev/full became a regular file, and a FIFO was replaced unread).
    std::error_code ec;
    const fs::file_status st = fs::status(path, ec);
    const bool stream = !ec && (fs::is_character_file(st) || fs::is_fifo(st));
    const auto write = [&](const std::string &file) {
        errno = 0;
        std::FILE *f = std::fopen(file.c_str(), "wb");
        if (!f) {
            throw_runtime(path, ": cannot write: ", std::strerror(errno));
        }
        const bool ok = std::fwrite(data, 1, size, f) == size;
        const int write_errno = errno;
        if (std::fclose(f) != 0 || !ok) {
            const int e = ok ? errno : write_errno;
            throw_runtime(path, ": cannot write: ", e != 0 ? std::strerror(e) : "short write");
        }
    };
    if (stream) {
        write(path);
    } else {
        atomic_write(path, write);
    }
}

void write_text_file(const std::string &path, const std::string &text)
{
    write_file_bytes(path, text.data(), text.size());
}

}  // namespace posthaste
