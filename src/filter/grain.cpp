// Film grain (see grain.h).

#include "filter/grain.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <vector>

#include "core/hash.h"
#include "core/parallel.h"
#include "filter/fir_kernels.h"
#include "filter/grain_kernels.h"
#include "filter/rgba_rows.h"

namespace posthaste::filter {

static_assert(kRowPad >= kFirPad, "grain rows feed the FIR kernels");
namespace {

/// Rows [0, n) in parallel, in blocks of 16 (one writer per row).
template <typename Fn>
void for_rows(int n, const Fn &fn)
{
    parallel_for(0, (n + 15) / 16, [&](int b) {
        for (int y = b * 16; y < std::min(n, (b + 1) * 16); ++y) {
            fn(y);
        }
    });
}

}  // namespace

GrainField grain_field(int w, int h, int x0, int y0, int frame, const GrainParams &p)
{
    const int planes = p.color ? 3 : 1;
    const bool blur = p.size >= 0.3;
    const std::vector<float> k = blur ? gaussian_kernel(p.size, 3.0) : std::vector<float>{1.0f};
    const int taps = int(k.size()), r = taps / 2;
    // After the blur the field's variance is (sum k^2)^2 times the white noise's.
    double k2 = 0.0;
    for (float v : k) {
        k2 += double(v) * v;
    }
    // White noise: the sum of four hashed bytes, centred and scaled to unit variance (the
    // variance of a byte uniform on 0..255 is (256^2 - 1) / 12), divided by the blur's
    // standard-deviation factor sqrt((sum k^2)^2) = sum k^2.
    const float unit = float(1.0 / (std::sqrt(4.0 * (256.0 * 256.0 - 1.0) / 12.0) * k2));
    const int pw = w + 2 * r, ph = h + 2 * r;
    GrainField f;
    f.stride = std::size_t(w) + kRowPad;
    f.plane = f.stride * std::size_t(h);
    // Uninitialised: a serial zero fill of a 1080p plane cost more than the grain itself.
    f.data = scratch_array<float>(f.plane * std::size_t(planes));
    const std::size_t rows_stride = std::size_t(w) + kRowPad;
    const ScratchArray<float> rows = scratch_array<float>(rows_stride * std::size_t(ph));
    for (int c = 0; c < planes; ++c) {
        const std::uint32_t key =
            pcg_hash(std::uint32_t(c) ^ pcg_hash(std::uint32_t(frame) ^ pcg_hash(p.seed)));
        // Noise and the horizontal pass, a row at a time.
        parallel_for(0, (ph + 15) / 16, [&](int b) {
            std::vector<float> noise(std::size_t(pw) + kRowPad);
            for (int py = b * 16; py < std::min(ph, (b + 1) * 16); ++py) {
                const std::uint32_t row = pcg_hash(std::uint32_t(y0 + py - r) ^ key);
                grain_noise_row(row, x0 - r, pw, unit, noise.data());
                fir_row(
                    noise.data(), k.data(), taps, 1, w, rows.get() + std::size_t(py) * rows_stride);
            }
        });
        float *plane = f.data.get() + std::size_t(c) * f.plane;
        for_rows(h, [&](int y) {
            std::vector<const float *> src(static_cast<std::size_t>(taps));
            for (int i = 0; i < taps; ++i) {
                src[std::size_t(i)] = rows.get() + std::size_t(y + i) * rows_stride;
            }
            fir_columns(src.data(), k.data(), taps, w, plane + std::size_t(y) * f.stride);
        });
    }
    return f;
}

Image apply_grain(const Image &in, int x0, int y0, int frame, const GrainParams &p)
{
    const int w = in.width(), h = in.height(), nc = in.channels();
    const GrainField field = grain_field(w, h, x0, y0, frame, p);
    Image out = Image::uninitialized(w, h, nc);
    const float amount = float(p.intensity), response = float(p.response), offset = float(p.offset);
    for_rgba_rows(in, out, [&](int y, const float *src, float *dst, int n) {
        const float *fr = field.data.get() + std::size_t(y) * field.stride;
        const float *fg = p.color ? fr + field.plane : fr;
        const float *fb = p.color ? fr + 2 * field.plane : fr;
        grain_apply_rgba_row(src, dst, fr, fg, fb, n, amount, response, offset);
    });
    return out;
}

}  // namespace posthaste::filter
