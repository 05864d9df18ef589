#include "core/memory.h"

#include <atomic>
#include <cctype>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <mutex>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>

#include "core/error.h"
#endif

namespace posthaste {

void advise_huge_pages(void *data, std::size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    if (!data || bytes < kHugePageAdviceMinBytes) {
        return;
    }
    constexpr std::uintptr_t kHuge = std::uintptr_t(2) << 20;
    const std::uintptr_t begin =
        (reinterpret_cast<std::uintptr_t>(data) + kHuge - 1) & ~(kHuge - 1);
    const std::uintptr_t end = (reinterpret_cast<std::uintptr_t>(data) + bytes) & ~(kHuge - 1);
    if (end > begin) {
        madvise(reinterpret_cast<void *>(begin), end - begin, MADV_HUGEPAGE);  // advice only
    }
#else
    (void)data;
    (void)bytes;
#endif
}

namespace {

class ScratchPool {
   public:
    static ScratchPool &instance()
    {
        static ScratchPool pool;
        return pool;
    }

    void *take(std::size_t bytes, std::size_t &got)
    {
        {
            // The smallest kept block that holds `bytes`: the lighting split's crops and other
            // per-frame sizes change from frame to frame, and an exact-size match left them to
            // fresh memory, which the kernel clears and, with huge pages advised, may first
            // compact (the split's pack took 15-30 ms on such frames against 1-3 on a kept block).
            const std::lock_guard<std::mutex> lock(mutex_);
            std::size_t best = free_.size();
            for (std::size_t i = 0; i < free_.size(); ++i) {
                const std::size_t b = free_[i].bytes;
                if (b >= bytes && (best == free_.size() || b < free_[best].bytes)) {
                    best = i;
                }
            }
            if (best != free_.size()) {
                void *p = free_[best].p;
                got = free_[best].bytes;
                kept_ -= got;
                free_.erase(free_.begin() + std::ptrdiff_t(best));
                return p;
            }
        }
        constexpr std::size_t kHuge = std::size_t(2) << 20;
        void *p = std::aligned_alloc(kHuge, bytes);
        if (!p) {
            throw std::bad_alloc();
        }
        advise_huge_pages(p, bytes);
        got = bytes;
        return p;
    }

    void give(void *p, std::size_t bytes)
    {
        std::vector<void *> evicted;
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            if (bytes <= kPoolBytes) {
                // The newest block stays; the oldest go first (a size no longer asked for).
                while (kept_ + bytes > kPoolBytes && !free_.empty()) {
                    evicted.push_back(free_.front().p);
                    kept_ -= free_.front().bytes;
                    free_.erase(free_.begin());
                }
                free_.push_back({p, bytes});
                kept_ += bytes;
                p = nullptr;
            }
        }
        for (void *e : evicted) {
            std::free(e);
        }
        std::free(p);
    }

    ~ScratchPool()
    {
        for (const Block &b : free_) {
            std::free(b.p);
        }
    }

   private:
    static constexpr std::size_t kPoolBytes = std::size_t(256) << 20;
    struct Block {
        void *p;
        std::size_t bytes;
    };
    std::mutex mutex_;
    std::vector<Block> free_;
    std::size_t kept_ = 0;
};

}  // namespace

void *scratch_take(std::size_t bytes, std::size_t *got)
{
    std::size_t size = bytes;
    void *p = ScratchPool::instance().take(bytes, size);
    if (got) {
        *got = size;
    }
    return p;
}

void scratch_give(void *block, std::size_t bytes)
{
    if (block) {
        ScratchPool::instance().give(block, bytes);
    }
}

namespace {
std::atomic<std::size_t> g_budget{0};
std::atomic<std::size_t> g_in_use{0};
std::atomic<std::size_t> g_peak{0};
}  // namespace

void set_image_memory_budget(std::size_t bytes)
{
    g_budget = bytes;
}

std::size_t image_memory_budget()
{
    return g_budget.load();
}

std::size_t image_memory_in_use()
{
    return g_in_use.load();
}

std::size_t image_memory_peak()
{
    return g_peak.load();
}

void reset_image_memory_peak()
{
    g_peak = g_in_use.load();
}

void reserve_image_memory(std::size_t bytes, int width, int height, int channels)
{
    const std::size_t before = g_in_use.fetch_add(bytes);
    const std::size_t budget = g_budget.load();
    if (budget != 0 && before + bytes > budget) {
        g_in_use.fetch_sub(bytes);
        throw MemoryBudgetError(ExitCode::Runtime,
                                str_cat("memory budget: a ",
                                        width,
                                        "x",
                                        height,
                                        "x",
                                        channels,
                                        " image (",
                                        format_bytes(bytes),
                                        ") would take pass images to ",
                                        format_bytes(before + bytes),
                                        ", over --max-memory ",
                                        format_bytes(budget),
                                        " (fewer --jobs, a smaller frame, or a larger budget)"));
    }
    const std::size_t now = before + bytes;
    std::size_t peak = g_peak.load();
    while (now > peak && !g_peak.compare_exchange_weak(peak, now)) {
    }
}

std::string format_bytes(std::size_t bytes)
{
    if (bytes < 1024) {  // --max-memory 1 said "0 KiB"
        return std::to_string(bytes) + (bytes == 1 ? " byte" : " bytes");
    }
    return bytes < (std::size_t(1) << 20) ? std::to_string(bytes >> 10) + " KiB"
                                          : std::to_string(bytes >> 20) + " MiB";
}

void release_image_memory(std::size_t bytes)
{
    g_in_use.fetch_sub(bytes);
}

std::size_t available_memory_bytes()
{
    std::ifstream in("/proc/meminfo");
    std::string key;
    std::size_t value = 0;
    std::string unit;
    while (in >> key >> value >> unit) {
        if (key == "MemAvailable:") {
            return value * 1024;
        }
    }
    return 0;
}

std::size_t parse_memory_size(const std::string &text, const std::string &where)
{
    char *end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    std::string unit = end ? std::string(end) : "";
    for (char &c : unit) {
        c = char(std::tolower(static_cast<unsigned char>(c)));
    }
    if (unit.size() == 2 && unit[1] == 'b') {
        unit.resize(1);
    }
    double scale = 0.0;
    if (unit.empty() || unit == "b") {
        scale = 1.0;
    } else if (unit == "k") {
        scale = 1024.0;
    } else if (unit == "m") {
        scale = 1024.0 * 1024.0;
    } else if (unit == "g") {
        scale = 1024.0 * 1024.0 * 1024.0;
    } else if (unit == "t") {
        scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
    }
    if (text.empty() || end == text.c_str() || scale == 0.0 || !(v >= 0.0) || v * scale > 1e18) {
        throw_usage(
            where, ": expected a size such as 8G, 512M or 0 (no budget), got \"", text, "\"");
    }
    return std::size_t(v * scale);
}

}  // namespace posthaste
