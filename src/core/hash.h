#pragma once
// Stateless hashing for per-pixel randomness: hash(x, y, sample, seed). Same inputs give the same
// numbers on every thread, which keeps outputs independent of the thread count.

#include <cstddef>
#include <cstdint>
#include <cstring>

namespace posthaste {

/// PCG-style 32-bit mix (Jarzynski & Olano 2020, "Hash Functions for GPU Rendering").
constexpr std::uint32_t pcg_hash(std::uint32_t v)
{
    const std::uint32_t state = v * 747796405u + 2891336453u;
    const std::uint32_t word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

constexpr std::uint32_t hash4(std::uint32_t x, std::uint32_t y, std::uint32_t s, std::uint32_t seed)
{
    return pcg_hash(x ^ pcg_hash(y ^ pcg_hash(s ^ pcg_hash(seed))));
}

/// Uniform float in [0, 1) from a hash (24 high bits).
constexpr float hash_to_unit(std::uint32_t h)
{
    return float(h >> 8) * (1.0f / 16777216.0f);
}

/// Uniform float in [0, 1) for pixel (x, y), sample index and seed.
constexpr float hash_unit(int x, int y, int sample, std::uint32_t seed)
{
    return hash_to_unit(hash4(std::uint32_t(x), std::uint32_t(y), std::uint32_t(sample), seed));
}

/// Van der Corput radical inverse in base 2 (bit reversal), in [0, 1) with 24 bits: the second
/// coordinate of a Hammersley point set.
constexpr float radical_inverse_base2(std::uint32_t i)
{
    i = (i << 16u) | (i >> 16u);
    i = ((i & 0x55555555u) << 1u) | ((i & 0xAAAAAAAAu) >> 1u);
    i = ((i & 0x33333333u) << 2u) | ((i & 0xCCCCCCCCu) >> 2u);
    i = ((i & 0x0F0F0F0Fu) << 4u) | ((i & 0xF0F0F0F0u) >> 4u);
    i = ((i & 0x00FF00FFu) << 8u) | ((i & 0xFF00FF00u) >> 8u);
    return float(i >> 8) * (1.0f / 16777216.0f);
}

/// A 64-bit hash of bytes, eight at a time (FNV-1a's multiply on words, with a shift that mixes
/// the high bits down), continued from `h` (start from kHashBytesSeed): names and checks files
/// (the disk cache's entries, the farm's outputs). Not cryptographic. Blocks fed in turn give the
/// hash of their concatenation when every block but the last is a multiple of 8 bytes long.
inline constexpr std::uint64_t kHashBytesSeed = 0xcbf29ce484222325ull;
inline std::uint64_t hash_bytes(std::uint64_t h, const void *data, std::size_t n)
{
    const auto *p = static_cast<const unsigned char *>(data);
    std::size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        std::uint64_t w;
        std::memcpy(&w, p + i, 8);
        h = (h ^ w) * 0x100000001b3ull;
        h ^= h >> 29;
    }
    for (; i < n; ++i) {
        h = (h ^ p[i]) * 0x100000001b3ull;
    }
    return h;
}

}  // namespace posthaste
