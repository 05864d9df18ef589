#include "core/memory.h"

#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
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

    void *take(std::size_t bytes)
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            for (std::size_t i = 0; i < free_.size(); ++i) {
                if (free_[i].bytes == bytes) {
                    void *p = free_[i].p;
                    kept_ -= bytes;
                    free_.erase(free_.begin() + std::ptrdiff_t(i));
                    return p;
                }
            }
        }
        constexpr std::size_t kHuge = std::size_t(2) << 20;
        void *p = std::aligned_alloc(kHuge, bytes);
        if (!p) {
            throw std::bad_alloc();
        }
        advise_huge_pages(p, bytes);
        return p;
    }

    void give(void *p, std::size_t bytes)
    {
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            if (kept_ + bytes <= kPoolBytes) {
                free_.push_back({p, bytes});
                kept_ += bytes;
                return;
            }
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

void *scratch_take(std::size_t bytes)
{
    return ScratchPool::instance().take(bytes);
}

void scratch_give(void *block, std::size_t bytes)
{
    if (block) {
        ScratchPool::instance().give(block, bytes);
    }
}

}  // namespace posthaste
