// advise_huge_pages: only advice, so a buffer's contents survive it, any pointer and size are
// accepted, and images of every size keep their values. Where the system grants huge pages the
// test reports how much of a touched 16 MiB buffer they cover.
#include "core/memory.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "core/image.h"

namespace posthaste {
namespace {

/// AnonHugePages (kB) of the mapping that contains `p`, from /proc/self/smaps; -1 if unknown.
long huge_kb_at(const void *p)
{
    std::ifstream smaps("/proc/self/smaps");
    const auto addr = reinterpret_cast<unsigned long>(p);
    std::string line;
    bool inside = false;
    while (std::getline(smaps, line)) {
        unsigned long lo = 0, hi = 0;
        if (std::sscanf(line.c_str(), "%lx-%lx ", &lo, &hi) == 2 && line.find(':') > 8) {
            inside = addr >= lo && addr < hi;
        } else if (inside && line.rfind("AnonHugePages:", 0) == 0) {
            return std::stol(line.substr(14));
        }
    }
    return -1;
}

TEST(Memory, AdviceKeepsContentsAndAcceptsAnyBuffer)
{
    advise_huge_pages(nullptr, std::size_t(64) << 20);  // nothing to advise
    char small[64] = {1};
    advise_huge_pages(small, sizeof(small));  // under the threshold: left alone
    EXPECT_EQ(small[0], 1);

    const std::size_t bytes = std::size_t(16) << 20;
    std::vector<unsigned char> buffer(bytes + 4096);
    unsigned char *p = buffer.data() + 123;  // deliberately not page aligned
    for (std::size_t i = 0; i < bytes; ++i) {
        p[i] = static_cast<unsigned char>(i * 2654435761u >> 24);
    }
    advise_huge_pages(p, bytes);
    for (std::size_t i = 0; i < bytes; ++i) {
        ASSERT_EQ(p[i], static_cast<unsigned char>(i * 2654435761u >> 24)) << i;
    }
}

TEST(Memory, ImagesOfEverySizeKeepTheirValues)
{
    for (const int side : {1, 100, 1100}) {  // 1100^2 x 4 floats = 19 MB: advised
        Image a = Image::uninitialized(side, side, 4);
        for (std::size_t i = 0; i < a.value_count(); ++i) {
            a.data()[i] = float(i % 977);
        }
        const Image b = a;  // the copy is advised too
        for (std::size_t i = 0; i < b.value_count(); i += 17) {
            ASSERT_EQ(b.data()[i], float(i % 977));
        }
        if (side == 1100) {
            std::printf(
                "[ measured ] 19 MB image: %ld kB in huge pages (THP policy of this "
                "system decides)\n",
                huge_kb_at(b.data() + b.value_count() / 2));
        }
    }
}

// The scratch pool: whole, 2 MiB-aligned blocks; a freed block is handed out again for any
// size it holds, the smallest that fits first (stale contents, writable to its end); blocks of
// several users coexist.
TEST(Memory, ScratchBlocksAreAlignedAndReusedBestFit)
{
    constexpr std::uintptr_t kHuge = std::uintptr_t(2) << 20;
    const std::size_t n = 3 * 1000 * 1000;  // 12 MB of floats: rounded up to 12 MiB
    float *first = nullptr, *second = nullptr, *big_block = nullptr;
    {
        ScratchArray<float> a = scratch_array<float>(n);
        ASSERT_NE(a.get(), nullptr);
        EXPECT_EQ(reinterpret_cast<std::uintptr_t>(a.get()) % kHuge, 0u);
        a[0] = 1.0f;
        a[n - 1] = 2.0f;
        first = a.get();
    }
    {
        ScratchArray<float> smaller = scratch_array<float>(n / 2);  // the kept block holds it
        EXPECT_EQ(smaller.get(), first);
        smaller[n - 1] = 3.0f;                               // the whole block, past what was asked
        ScratchArray<float> same = scratch_array<float>(n);  // none kept now: a new block
        EXPECT_NE(same.get(), first);
        second = same.get();
        same[0] = 4.0f;
        EXPECT_EQ(smaller[n - 1], 3.0f);
    }
    {
        ScratchArray<float> big = scratch_array<float>(2 * n);  // no kept block holds 24 MiB
        EXPECT_NE(big.get(), first);
        EXPECT_NE(big.get(), second);
        big_block = big.get();
        big[2 * n - 1] = 5.0f;
    }
    {
        // Kept: two blocks of 12 MiB and one of 24. 20 MiB takes the 24; 4 MiB a 12, not the 24.
        ScratchArray<float> mid = scratch_array<float>(5 * 1000 * 1000);
        EXPECT_EQ(mid.get(), big_block);
        ScratchArray<float> small = scratch_array<float>(1000 * 1000);
        EXPECT_TRUE(small.get() == first || small.get() == second);
    }
    // A full pool (256 MiB) frees its oldest blocks for a newcomer: of three 100 MiB blocks
    // freed in turn, the first is gone and a request takes one of the last two. (The blocks are
    // never touched: no memory is committed for them.)
    {
        const std::size_t m = std::size_t(100) << 20;
        void *a = scratch_take(m), *b = scratch_take(m), *c = scratch_take(m);
        scratch_give(a, m);
        scratch_give(b, m);
        scratch_give(c, m);
        std::size_t got = 0;
        void *again = scratch_take(m, &got);
        EXPECT_TRUE(again == b || again == c);
        EXPECT_EQ(got, m);
        scratch_give(again, got);
    }
    ScratchArray<char> tiny = scratch_array<char>(1);  // at least one 2 MiB block
    ASSERT_NE(tiny.get(), nullptr);
    tiny[(std::size_t(2) << 20) - 1] = 'x';
}

}  // namespace
}  // namespace posthaste
