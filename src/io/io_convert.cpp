// Pixel conversions between the file's channel types and the pass planes (io_detail.h):
// floats to halves (F16C where the CPU has it, round to nearest even either way), interleaved
// floats scattered to planes, and one channel of any supported type to floats.
#include <Imath/half.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "core/error.h"
#include "core/simd.h"
#include "io/io_detail.h"

namespace posthaste::io_detail {

namespace {

/// The smallest magnitude a half rounds to infinity (65504 and the half-way point to 65536).
constexpr float kHalfOverflow = 65520.0f;

/// Whether a finite float becomes an infinite half.
bool overflows_half(float v)
{
    const float a = std::abs(v);
    return a >= kHalfOverflow && a <= std::numeric_limits<float>::max();
}

/// Convert `count` pixels of `channels` floats to halves; pixel i's halves go to
/// dst + i * dst_stride. Rounds to nearest even, like Imath::half. Returns how many finite
/// values became infinite.
std::size_t floats_to_halves_portable(const float *src,
                                      int channels,
                                      int count,
                                      unsigned char *dst,
                                      std::size_t dst_stride,
                                      int src_stride)
{
    std::size_t over = 0;
    for (int x = 0; x < count; ++x, dst += dst_stride, src += src_stride) {
        for (int c = 0; c < channels; ++c) {
            const Imath::half h(src[c]);
            std::memcpy(dst + std::size_t(c) * 2, &h, 2);
            over += overflows_half(src[c]) ? 1 : 0;
        }
    }
    return over;
}

#if defined(__x86_64__) && defined(__GNUC__)
__attribute__((target("f16c"))) std::size_t floats_to_halves_f16c(const float *src,
                                                                  int channels,
                                                                  int count,
                                                                  unsigned char *dst,
                                                                  std::size_t dst_stride,
                                                                  int src_stride)
{
    std::size_t over = 0;
    const __m128 abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fffffff));
    const __m128 lo = _mm_set1_ps(kHalfOverflow);
    const __m128 hi = _mm_set1_ps(std::numeric_limits<float>::max());
    for (int x = 0; x < count; ++x, dst += dst_stride, src += src_stride) {
        if (channels == 4) {
            const __m128 v = _mm_loadu_ps(src);
            const __m128i h = _mm_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT);
            _mm_storel_epi64(reinterpret_cast<__m128i *>(dst), h);
            const __m128 a = _mm_and_ps(v, abs_mask);
            over += std::size_t(std::popcount(
                unsigned(_mm_movemask_ps(_mm_and_ps(_mm_cmpge_ps(a, lo), _mm_cmple_ps(a, hi))))));
            continue;
        }
        for (int c = 0; c < channels; ++c) {
            const unsigned short h = _cvtss_sh(src[c], _MM_FROUND_TO_NEAREST_INT);
            std::memcpy(dst + std::size_t(c) * 2, &h, 2);
            over += overflows_half(src[c]) ? 1 : 0;
        }
    }
    return over;
}
#endif

}  // namespace

/// floats_to_halves_portable, with the CPU's F16C instructions where it has them (the software
/// conversion was a quarter of a 1080p all-pass write).
std::size_t floats_to_halves(const float *src,
                             int channels,
                             int count,
                             unsigned char *dst,
                             std::size_t dst_stride,
                             int src_stride)
{
    if (src_stride <= 0) {
        src_stride = channels;
    }
#if defined(__x86_64__) && defined(__GNUC__)
    static const bool has_f16c = simd::cpu_has_f16c();
    if (has_f16c) {
        return floats_to_halves_f16c(src, channels, count, dst, dst_stride, src_stride);
    }
#endif
    return floats_to_halves_portable(src, channels, count, dst, dst_stride, src_stride);
}

namespace {

/// Copy `count` pixels of `channels` floats to dst + i * dst_stride. The per-pixel copy has a
/// size known at compile time so it inlines (a libc memmove per pixel dominated the write).
template <int N>
void scatter_floats_n(
    const float *src, int count, unsigned char *dst, std::size_t dst_stride, int src_stride)
{
    for (int x = 0; x < count; ++x, dst += dst_stride, src += src_stride) {
        std::memcpy(dst, src, N * sizeof(float));
    }
}

}  // namespace

void scatter_floats(const float *src,
                    int channels,
                    int count,
                    unsigned char *dst,
                    std::size_t dst_stride,
                    int src_stride)
{
    if (src_stride <= 0) {
        src_stride = channels;
    }
    switch (channels) {
        case 1:
            return scatter_floats_n<1>(src, count, dst, dst_stride, src_stride);
        case 2:
            return scatter_floats_n<2>(src, count, dst, dst_stride, src_stride);
        case 3:
            return scatter_floats_n<3>(src, count, dst, dst_stride, src_stride);
        case 4:
            return scatter_floats_n<4>(src, count, dst, dst_stride, src_stride);
        default:
            for (int x = 0; x < count; ++x, dst += dst_stride, src += src_stride) {
                std::memcpy(dst, src, std::size_t(channels) * sizeof(float));
            }
    }
}

void convert_channel(const unsigned char *src,
                     std::size_t stride,
                     OIIO::TypeDesc type,
                     float *dst,
                     std::size_t dst_stride,
                     int count)
{
    switch (type.basetype) {
        case OIIO::TypeDesc::HALF:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                Imath::half h;
                std::memcpy(&h, src, sizeof(h));
                *dst = float(h);
            }
            break;
        case OIIO::TypeDesc::FLOAT:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::memcpy(dst, src, sizeof(float));
            }
            break;
        case OIIO::TypeDesc::DOUBLE:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                double d;
                std::memcpy(&d, src, sizeof(d));
                *dst = float(d);
            }
            break;
        case OIIO::TypeDesc::UINT:  // ids: integers, not normalised
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::uint32_t u;
                std::memcpy(&u, src, sizeof(u));
                *dst = float(u);
            }
            break;
        case OIIO::TypeDesc::UINT8:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                *dst = float(*src) * (1.0f / 255.0f);
            }
            break;
        case OIIO::TypeDesc::UINT16:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::uint16_t u;
                std::memcpy(&u, src, sizeof(u));
                *dst = float(u) * (1.0f / 65535.0f);
            }
            break;
        case OIIO::TypeDesc::INT8:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                *dst = std::max(-1.0f, float(std::int8_t(*src)) * (1.0f / 127.0f));
            }
            break;
        case OIIO::TypeDesc::INT16:
            for (int i = 0; i < count; ++i, src += stride, dst += dst_stride) {
                std::int16_t v;
                std::memcpy(&v, src, sizeof(v));
                *dst = std::max(-1.0f, float(v) * (1.0f / 32767.0f));
            }
            break;
        default:
            for (int i = 0; i < count; ++i, dst += dst_stride) {
                *dst = 0.0f;  // types refused when the part is read
            }
            break;
    }
}

bool supported_native(OIIO::TypeDesc t)
{
    switch (t.basetype) {
        case OIIO::TypeDesc::HALF:
        case OIIO::TypeDesc::FLOAT:
        case OIIO::TypeDesc::DOUBLE:
        case OIIO::TypeDesc::UINT:
        case OIIO::TypeDesc::UINT8:
        case OIIO::TypeDesc::UINT16:
        case OIIO::TypeDesc::INT8:
        case OIIO::TypeDesc::INT16:
            return t.aggregate == OIIO::TypeDesc::SCALAR;
        default:
            return false;
    }
}

}  // namespace posthaste::io_detail
