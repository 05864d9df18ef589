// Fuzz target: the bench spec reader.

#include "bench/bench.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size)
{
    using namespace posthaste;
    fuzz::expect_clean([&] { bench::parse_spec(fuzz::text_of(data, size), "fuzz.json", "/tmp"); });
    return 0;
}
