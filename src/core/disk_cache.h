#pragma once
// A cache on disk for tables a process would otherwise build at start-up (the atmosphere's LUTs,
// the tonal art maps, the scene's meshes): each costs tens of milliseconds to build and is the
// same for every process of the same binary, so a short run (`posthaste run` over one small
// frame, `posthaste test`, a farm chunk) would pay them again and again.
//
// An entry is keyed by everything its contents depend on: the caller's parameters (its bytes),
// the kind of table, this binary's build ID (the linker's hash of the code, so a rebuilt binary
// never reads an older build's tables) and the SIMD level asked for. The file holds the whole key
// and a checksum; a load that finds another key, a short file or a wrong checksum is a miss, and
// the table is built and stored again. Writes go to a temporary name and are renamed into place,
// so processes sharing the folder (farm jobs on a shared home) never see half an entry. Failures
// to read or write are misses: the cache never fails a run and never changes a result.
//
// Folder: $POSTHASTE_CACHE_DIR, else $XDG_CACHE_HOME/posthaste, else $HOME/.cache/posthaste.
// Off: POSTHASTE_CACHE=off in the environment, or disk_cache::set_enabled(false) (the CLI's
// --no-cache). Entries not used for 30 days are removed when a new one is stored.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace posthaste::disk_cache {

/// Append n bytes at p to `out` (resize and copy: GCC 12 warns falsely on vector::insert here).
inline void append(std::vector<unsigned char> &out, const void *p, std::size_t n)
{
    if (n == 0) {
        return;
    }
    const std::size_t at = out.size();
    out.resize(at + n);
    std::memcpy(out.data() + at, p, n);
}

/// Whether loads and stores happen (false without a build ID, a folder, or when turned off).
bool enabled();
/// Turn the cache on or off for this process (the CLI's --no-cache; tests).
void set_enabled(bool on);
/// The folder entries live in (see the header); "" when none can be named.
std::string directory();
/// Use `dir` instead of the environment's folder ("" goes back to the environment's); tests.
void set_directory(const std::string &dir);
/// This binary's GNU build ID as hex ("" when the linker wrote none: the cache is then off).
const std::string &build_id();

/// Counters of this process, for tests and the start-up table.
struct Stats {
    int hits = 0, misses = 0, stores = 0, rejected = 0;  ///< rejected: a corrupt or foreign file
};
Stats stats();

/// The bytes a key is made of. Add every value the entry's contents depend on.
class Key {
   public:
    explicit Key(std::string_view kind) : kind_(kind) {}
    template <typename T>
    Key &add(const T &value)
    {
        static_assert(std::is_trivially_copyable_v<T>, "add trivially copyable values");
        append(bytes_, &value, sizeof(T));
        return *this;
    }
    Key &add_string(std::string_view s)
    {
        add(std::uint64_t(s.size()));
        append(bytes_, s.data(), s.size());
        return *this;
    }
    const std::string &kind() const { return kind_; }
    const std::vector<unsigned char> &bytes() const { return bytes_; }

   private:
    std::string kind_;
    std::vector<unsigned char> bytes_;
};

/// The payload stored under `key`, or nothing (off, absent, unreadable, corrupt: a miss).
std::optional<std::vector<unsigned char>> load(const Key &key);
/// Store `payload` under `key` atomically; failures are ignored (see the header).
void store(const Key &key, std::span<const unsigned char> payload);

/// Appends values to a payload.
class Writer {
   public:
    template <typename T>
    void put(const T &value)
    {
        static_assert(std::is_trivially_copyable_v<T>);
        append(bytes_, &value, sizeof(T));
    }
    template <typename T>
    void put_vector(const std::vector<T> &v)
    {
        static_assert(std::is_trivially_copyable_v<T>);
        put(std::uint64_t(v.size()));
        append(bytes_, v.data(), v.size() * sizeof(T));
    }
    const std::vector<unsigned char> &bytes() const { return bytes_; }

   private:
    std::vector<unsigned char> bytes_;
};

/// Reads values back in the order written; throws std::out_of_range past the end (which a caller
/// treats as a miss: the checksum already passed, so only a changed layout can cause it).
class Reader {
   public:
    explicit Reader(std::span<const unsigned char> bytes) : bytes_(bytes) {}
    template <typename T>
    T get()
    {
        static_assert(std::is_trivially_copyable_v<T>);
        need(sizeof(T));
        T value;
        std::memcpy(&value, bytes_.data() + pos_, sizeof(T));
        pos_ += sizeof(T);
        return value;
    }
    template <typename T>
    std::vector<T> get_vector(std::size_t max_count)
    {
        const auto n = get<std::uint64_t>();
        if (n > max_count) {
            throw std::out_of_range("disk_cache: vector too long");
        }
        need(std::size_t(n) * sizeof(T));
        std::vector<T> v(static_cast<std::size_t>(n));
        std::memcpy(v.data(), bytes_.data() + pos_, std::size_t(n) * sizeof(T));
        pos_ += std::size_t(n) * sizeof(T);
        return v;
    }
    bool at_end() const { return pos_ == bytes_.size(); }

   private:
    void need(std::size_t n) const
    {
        if (n > bytes_.size() - pos_) {
            throw std::out_of_range("disk_cache: payload too short");
        }
    }
    std::span<const unsigned char> bytes_;
    std::size_t pos_ = 0;
};

/// The usual pattern: load and decode, else build, encode and store. `decode(Reader&)` returns
/// the value (throwing std::out_of_range on a short payload, which counts as a miss);
/// `encode(const T&, Writer&)` writes what decode reads.
template <typename T, typename Build, typename Encode, typename Decode>
T cached(const Key &key, Build &&build, Encode &&encode, Decode &&decode)
{
    if (std::optional<std::vector<unsigned char>> bytes = load(key)) {
        try {
            Reader r(*bytes);
            T value = decode(r);
            if (r.at_end()) {
                return value;
            }
        } catch (const std::out_of_range &) {
        }
    }
    T value = build();
    if (enabled()) {
        Writer w;
        encode(value, w);
        store(key, w.bytes());
    }
    return value;
}

}  // namespace posthaste::disk_cache
