// advise_huge_pages: only advice, so a buffer's contents survive it, any pointer and size are
// accepted, and images of every size keep their values. Where the system grants huge pages the
// test reports how much of a touched 16 MiB buffer they cover.
#include "core/memory.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace posthaste
