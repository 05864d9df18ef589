#include "core/disk_cache.h"

#include <elf.h>
#include <fcntl.h>
#include <hwy/targets.h>
#include <link.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <mutex>
#include <random>

#include "core/hash.h"
#include "core/simd.h"

namespace posthaste::disk_cache {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'P', 'H', 'C', 'A', 'C', 'H', 'E', '1'};
constexpr std::uint64_t kMaxPayload = std::uint64_t(1) << 30;  // 1 GiB: anything larger is corrupt
constexpr std::uint64_t kMaxKey = std::uint64_t(1) << 28;      // a voxel grid's cells
constexpr auto kUnusedFor = std::chrono::hours(24 * 30);       // entries not used this long go

std::atomic<bool> g_enabled{true};
std::atomic<int> g_hits{0}, g_misses{0}, g_stores{0}, g_rejected{0};
std::mutex g_dir_mutex;
std::string g_dir_override;

/// The note segment's NT_GNU_BUILD_ID of the object that holds this function.
int find_build_id(dl_phdr_info *info, std::size_t, void *data)
{
    auto *out = static_cast<std::string *>(data);
    const auto self = reinterpret_cast<ElfW(Addr)>(&find_build_id);
    bool mine = false;
    for (int i = 0; i < info->dlpi_phnum; ++i) {
        const ElfW(Phdr) &ph = info->dlpi_phdr[i];
        const ElfW(Addr) begin = info->dlpi_addr + ph.p_vaddr;
        if (ph.p_type == PT_LOAD && self >= begin && self < begin + ph.p_memsz) {
            mine = true;
        }
    }
    if (!mine) {
        return 0;
    }
    for (int i = 0; i < info->dlpi_phnum; ++i) {
        const ElfW(Phdr) &ph = info->dlpi_phdr[i];
        if (ph.p_type != PT_NOTE) {
            continue;
        }
        const auto *p = reinterpret_cast<const unsigned char *>(info->dlpi_addr + ph.p_vaddr);
        const unsigned char *end = p + ph.p_memsz;
        while (p + sizeof(ElfW(Nhdr)) <= end) {
            const auto *nh = reinterpret_cast<const ElfW(Nhdr) *>(p);
            const unsigned char *name = p + sizeof(ElfW(Nhdr));
            const unsigned char *desc = name + ((nh->n_namesz + 3u) & ~3u);
            if (desc + nh->n_descsz > end) {
                break;
            }
            if (nh->n_type == NT_GNU_BUILD_ID && nh->n_namesz == 4 &&
                std::memcmp(name, "GNU", 4) == 0) {
                static const char hex[] = "0123456789abcdef";
                for (unsigned k = 0; k < nh->n_descsz; ++k) {
                    out->push_back(hex[desc[k] >> 4]);
                    out->push_back(hex[desc[k] & 15]);
                }
                return 1;
            }
            p = desc + ((nh->n_descsz + 3u) & ~3u);
        }
    }
    return 1;  // this object, without a build ID
}

std::string environment_directory()
{
    if (const char *d = std::getenv("POSTHASTE_CACHE_DIR"); d && *d) {
        return d;
    }
    if (const char *x = std::getenv("XDG_CACHE_HOME"); x && *x && x[0] == '/') {
        return std::string(x) + "/posthaste";
    }
    if (const char *h = std::getenv("HOME"); h && *h) {
        return std::string(h) + "/.cache/posthaste";
    }
    return "";
}

bool environment_off()
{
    const char *v = std::getenv("POSTHASTE_CACHE");
    if (!v) {
        return false;
    }
    const std::string s(v);
    return s == "off" || s == "0" || s == "no" || s == "false";
}

/// The whole key as stored: the caller's bytes behind the kind, the build ID and the SIMD
/// targets this process would dispatch to.
std::vector<unsigned char> full_key(const Key &key)
{
    Key k(key.kind());
    k.add_string(key.kind());
    k.add_string(build_id());
    k.add(std::int32_t(simd::requested()));
    k.add(std::int64_t(hwy::SupportedTargets()));
    std::vector<unsigned char> bytes = k.bytes();
    append(bytes, key.bytes().data(), key.bytes().size());
    return bytes;
}

std::string entry_path(const std::string &dir, const Key &key, const std::vector<unsigned char> &k)
{
    char name[64];
    std::snprintf(name,
                  sizeof name,
                  "-%016llx.bin",
                  static_cast<unsigned long long>(hash_bytes(kHashBytesSeed, k.data(), k.size())));
    std::string kind;
    for (char c : key.kind()) {
        kind.push_back((c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ? c : '_');
    }
    return dir + "/" + kind + name;
}

bool read_all(const std::string &path, std::vector<unsigned char> &out)
{
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) {
        return false;
    }
    struct stat st {};
    bool ok = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) &&
              std::uint64_t(st.st_size) <= kMaxPayload + kMaxKey + 64;
    if (ok) {
        out.resize(std::size_t(st.st_size));
        std::size_t got = 0;
        while (got < out.size()) {
            const ssize_t n = ::read(fd, out.data() + got, out.size() - got);
            if (n <= 0) {
                if (n < 0 && errno == EINTR) {
                    continue;
                }
                break;
            }
            got += std::size_t(n);
        }
        ok = got == out.size();
    }
    ::close(fd);
    return ok;
}

void prune(const std::string &dir)
{
    std::error_code ec;
    const auto now = fs::file_time_type::clock::now();
    for (fs::directory_iterator it(dir, ec), end; !ec && it != end; it.increment(ec)) {
        const std::string name = it->path().filename().string();
        const bool entry = name.size() > 4 && name.compare(name.size() - 4, 4, ".bin") == 0;
        const bool temporary = name.find(".bin.tmp") != std::string::npos;
        if (!entry && !temporary) {
            continue;  // not ours
        }
        std::error_code e2;
        const auto t = fs::last_write_time(it->path(), e2);
        // A temporary an hour old is a killed process's (a live write takes milliseconds).
        if (!e2 && now - t > (entry ? kUnusedFor : std::chrono::hours(1))) {
            fs::remove(it->path(), e2);
        }
    }
}

}  // namespace

const std::string &build_id()
{
    static const std::string id = [] {
        std::string s;
        dl_iterate_phdr(find_build_id, &s);
        return s;
    }();
    return id;
}

bool enabled()
{
    return g_enabled.load(std::memory_order_relaxed) && !environment_off() && !build_id().empty() &&
           !directory().empty();
}

void set_enabled(bool on)
{
    g_enabled.store(on, std::memory_order_relaxed);
}

std::string directory()
{
    {
        std::lock_guard lock(g_dir_mutex);
        if (!g_dir_override.empty()) {
            return g_dir_override;
        }
    }
    return environment_directory();
}

void set_directory(const std::string &dir)
{
    std::lock_guard lock(g_dir_mutex);
    g_dir_override = dir;
}

Stats stats()
{
    return {g_hits.load(), g_misses.load(), g_stores.load(), g_rejected.load()};
}

std::optional<std::vector<unsigned char>> load(const Key &key)
{
    if (!enabled()) {
        return std::nullopt;
    }
    const std::vector<unsigned char> k = full_key(key);
    const std::string path = entry_path(directory(), key, k);
    std::vector<unsigned char> file;
    if (!read_all(path, file)) {
        ++g_misses;
        return std::nullopt;
    }
    // magic, key length, key, payload length, payload, checksum of everything before it
    const auto reject = [&]() -> std::optional<std::vector<unsigned char>> {
        ++g_rejected;
        ++g_misses;
        return std::nullopt;
    };
    std::size_t pos = 0;
    const auto u64_at = [&](std::size_t at) {
        std::uint64_t v;
        std::memcpy(&v, file.data() + at, 8);
        return v;
    };
    if (file.size() < sizeof kMagic + 8 + 8 + 8 ||
        std::memcmp(file.data(), kMagic, sizeof kMagic) != 0) {
        return reject();
    }
    pos = sizeof kMagic;
    const std::uint64_t key_size = u64_at(pos);
    pos += 8;
    if (key_size != k.size() || file.size() - pos < key_size + 16 ||
        std::memcmp(file.data() + pos, k.data(), k.size()) != 0) {
        return reject();  // another key under the same name (a hash collision), or damage
    }
    pos += k.size();
    const std::uint64_t payload_size = u64_at(pos);
    pos += 8;
    if (payload_size > kMaxPayload || file.size() - pos != payload_size + 8) {
        return reject();
    }
    const std::uint64_t sum =
        hash_bytes(kHashBytesSeed, file.data(), pos + std::size_t(payload_size));
    if (sum != u64_at(pos + std::size_t(payload_size))) {
        return reject();
    }
    ++g_hits;
    // Mark the entry as used (for prune) at most once a day.
    std::error_code ec;
    const auto t = fs::last_write_time(path, ec);
    if (!ec && fs::file_time_type::clock::now() - t > std::chrono::hours(24)) {
        fs::last_write_time(path, fs::file_time_type::clock::now(), ec);
    }
    return std::vector<unsigned char>(file.begin() + std::ptrdiff_t(pos),
                                      file.begin() + std::ptrdiff_t(pos + payload_size));
}

void store(const Key &key, std::span<const unsigned char> payload)
{
    if (!enabled() || payload.size() > kMaxPayload) {
        return;
    }
    const std::string dir = directory();
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
        return;
    }
    const std::vector<unsigned char> k = full_key(key);
    const std::string path = entry_path(dir, key, k);
    std::vector<unsigned char> file;
    file.reserve(sizeof kMagic + 24 + k.size() + payload.size());
    append(file, kMagic, sizeof kMagic);
    const auto put_u64 = [&](std::uint64_t v) { append(file, &v, 8); };
    put_u64(k.size());
    append(file, k.data(), k.size());
    put_u64(payload.size());
    append(file, payload.data(), payload.size());
    put_u64(hash_bytes(kHashBytesSeed, file.data(), file.size()));

    static std::atomic<unsigned> counter{0};
    thread_local std::mt19937_64 rng{std::random_device{}()};
    char suffix[64];
    std::snprintf(suffix,
                  sizeof suffix,
                  ".tmp%ld-%u-%llx",
                  long(::getpid()),
                  counter.fetch_add(1),
                  static_cast<unsigned long long>(rng()));
    const std::string tmp = path + suffix;
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0) {
        return;
    }
    std::size_t done = 0;
    bool ok = true;
    while (done < file.size()) {
        const ssize_t n = ::write(fd, file.data() + done, file.size() - done);
        if (n < 0 && errno == EINTR) {
            continue;
        }
        if (n <= 0) {
            ok = false;
            break;
        }
        done += std::size_t(n);
    }
    ok = ::close(fd) == 0 && ok;
    if (!ok || ::rename(tmp.c_str(), path.c_str()) != 0) {
        ::unlink(tmp.c_str());
        return;
    }
    ++g_stores;
    prune(dir);
}

}  // namespace posthaste::disk_cache
