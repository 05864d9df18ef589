// core/cryptomatte_id.cpp: MurmurHash3_x86_32 and the specification's float conversion.

#include "core/cryptomatte_id.h"

#include <cstdio>

namespace posthaste::cryptomatte {

namespace {

constexpr std::uint32_t rotl(std::uint32_t x, int r) { return (x << r) | (x >> (32 - r)); }

/// The 4-byte block at p, little-endian whatever the host.
std::uint32_t block_at(const unsigned char *p)
{
    return std::uint32_t(p[0]) | std::uint32_t(p[1]) << 8 | std::uint32_t(p[2]) << 16 |
           std::uint32_t(p[3]) << 24;
}

}  // namespace

std::uint32_t murmur3_32(std::string_view data, std::uint32_t seed)
{
    constexpr std::uint32_t c1 = 0xcc9e2d51u, c2 = 0x1b873593u;
    const auto *bytes = reinterpret_cast<const unsigned char *>(data.data());
    const std::size_t n = data.size(), blocks = n / 4;
    std::uint32_t h = seed;
    const auto mix_in = [&](std::uint32_t k) {
        k *= c1;
        k = rotl(k, 15);
        k *= c2;
        return k;
    };
    for (std::size_t i = 0; i < blocks; ++i) {
        h ^= mix_in(block_at(bytes + 4 * i));
        h = rotl(h, 13);
        h = h * 5u + 0xe6546b64u;
    }
    // The 1..3 bytes left over, the first the lowest.
    std::uint32_t tail = 0;
    for (std::size_t i = n & 3u; i > 0; --i) {
        tail = (tail << 8) | bytes[4 * blocks + i - 1];
    }
    if ((n & 3u) != 0) {
        h ^= mix_in(tail);
    }
    // Finalisation: every input bit reaches every output bit.
    h ^= std::uint32_t(n);
    h ^= h >> 16;
    h *= 0x85ebca6bu;
    h ^= h >> 13;
    h *= 0xc2b2ae35u;
    h ^= h >> 16;
    return h;
}

float id_from_hash(std::uint32_t hash)
{
    const std::uint32_t exponent = (hash >> 23) & 0xffu;
    if (exponent == 0 || exponent == 255) {
        hash ^= 1u << 23;  // 0 -> 1, 255 -> 254: the exponent kept in 1..254
    }
    float f;
    std::memcpy(&f, &hash, sizeof(f));
    return f;
}

float id_of(std::string_view name) { return id_from_hash(murmur3_32(name)); }

std::string hex_of(float id)
{
    char s[9];
    std::snprintf(s, sizeof(s), "%08x", bits_of(id));
    return s;
}

}  // namespace posthaste::cryptomatte
