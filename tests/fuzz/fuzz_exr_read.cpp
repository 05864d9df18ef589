// Fuzz target: the image reader (header, every part, every compression, windows, views, deep,
// luminance/chroma) through read_file_info, read_frame and verify_image_file. The input is
// written to a file in /dev/shm (the readers take paths), one per process.

#include <unistd.h>

#include <cstdio>
#include <fstream>

#include "core/memory.h"
#include "fuzz_common.h"
#include "io/image_file.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t *data, std::size_t size)
{
    using namespace posthaste;
    // A header may claim a large window (up to the documented limits, legitimately); the budget
    // turns those into clean errors instead of gigabyte allocations on every run.
    set_image_memory_budget(std::size_t(16) << 20);
    static const std::string path =
        "/dev/shm/posthaste-fuzz-" + std::to_string(::getpid()) + ".exr";
    {
        std::ofstream out(path, std::ios::binary | std::ios::trunc);
        out.write(reinterpret_cast<const char *>(data), std::streamsize(size));
    }
    // read_frame and read_file_info open a file the same way (open_file); info's own code runs
    // only past a successful open, so it is asked only then (a third of the time per input).
    bool opened = false;
    fuzz::expect_clean([&] {
        read_frame(path, nullptr, 1);
        opened = true;
    });
    if (opened) {
        fuzz::expect_clean([&] { read_file_info(path); });
    }
    (void)verify_image_file(path);
    return 0;
}
