// Test support for the EXR reader/writer: generates a corpus of small EXR files with OpenEXR's
// own C++ API (data/display windows, tiled and mip-mapped environment maps, every compression,
// channel sets, multi-part and multi-view, deep) and checks files independently of posthaste's
// code (lossless pass-through comparison, reference deep flattening, luminance/chroma to RGBA).
#pragma once

#include <string>
#include <vector>

namespace posthaste::test::corpus {

/// What a corpus file holds, so a test knows how to read it back.
enum class Kind { Flat, Deep, LumaChroma, LumaOnly };

/// One corpus file.
struct Entry {
    std::string name;  ///< Short id, e.g. "overscan_around".
    std::string path;  ///< File written.
    Kind kind;         ///< How the file is meant to be read.
    std::string what;  ///< One line: what this case exercises.
};

/// Write every corpus file into `dir` (created if missing) and return the entries in a fixed
/// order. Images are small (<= 64x64 mostly; files of 0.4 to 90 KB, about 520 KB in all).
/// Pixel values are hashes of (x, y, channel, part, level): half channels mix simple fractions
/// k/16 with arbitrary half bit patterns, float channels hold values no half represents, uint
/// channels start with 0xFFFFFFF0, 16777217, 0xFFFFFFFF, 0, 16777216. Images over 64x64 and the
/// comp_* files are mostly ramps (so that codecs really compress) with hashed samples mixed in.
/// "types_mixed" also starts with -0, +-inf, denormals, the largest finite values and quiet
/// NaNs. Throws on any OpenEXR or file-system error.
std::vector<Entry> write_corpus(const std::string &dir);

/// Compare two EXR files for a lossless pass-through: same number of parts in the same order;
/// per part: name (if any), view (if any), type (scanline/tiled/deep), data window, display
/// window, tile description (x/y size, level mode, rounding mode) for tiled parts, channel
/// list (names, pixel types, x/y sampling, pLinear), and every channel's samples bit-identical
/// at every mip/rip level. Also the attributes "multiView" (string vector) and "envmap" when
/// present in A must be present and equal in B. Compression and other attributes may differ.
/// A "name" present in B only is accepted for single-part files (writers may add one).
/// Returns "" when equal, else ONE line saying the first difference (part, channel, level,
/// pixel x y, values as hex bits). Never throws: errors come back as a one-line message.
std::string compare_exr(const std::string &a, const std::string &b);

/// Compare the header attributes of two EXR files, part by part: the same names, types and
/// value bytes (as OpenEXR writes them), except the names in `ignore`. "" when equal, else one
/// line naming the first difference.
std::string compare_attributes(const std::string &a,
                               const std::string &b,
                               const std::vector<std::string> &ignore);

/// A flattened deep image: the data window and 5 floats per pixel (R, G, B, A, Z), row-major.
struct Flat {
    int x0, y0, width, height;
    std::vector<float> rgbaz;
};

/// Flat RGBA + Z expected from a deep file, computed here independently: per pixel, samples
/// sorted by Z (front first; ties keep file order), composited front to back with `over` on
/// premultiplied R,G,B,A (C += (1 - A_acc) * c; A_acc += (1 - A_acc) * a), Z = the smallest Z
/// of the pixel (+inf when the pixel has no samples; R=G=B=A=0 then). Returned over the data
/// window of part 0 (level 0 when tiled), row-major, 5 floats per pixel (R,G,B,A,Z), with the
/// window. A missing R, G or B channel counts as 0, a missing A as 1; Z is required. Throws
/// when the file cannot be read, part 0 is not deep or has no Z channel.
Flat flatten_deep(const std::string &path);

/// An RGBA image: the data window and 4 floats per pixel (R, G, B, A), row-major.
struct Rgba {
    int x0, y0, width, height;
    std::vector<float> rgba;
};

/// RGBA as OpenEXR's RgbaInputFile converts a luminance/chroma (Y, RY, BY, subsampled) or
/// luminance-only file, over the data window, 4 floats per pixel, with the window. Throws when
/// the file cannot be read.
Rgba rgba_of(const std::string &path);

}  // namespace posthaste::test::corpus
