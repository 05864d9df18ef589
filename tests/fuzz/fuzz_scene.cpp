// Fuzz target: the scene reader of the bundled rasterizer.

#include "fuzz_common.h"
#include "raster/scene.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size)
{
    using namespace posthaste;
    fuzz::expect_clean([&] { raster::parse_scene(fuzz::text_of(data, size), "fuzz.json"); });
    return 0;
}
