#pragma once
// Cryptomatte IDs (Psyop's specification): a name's MurmurHash3_x86_32 (seed 0), its float
// exponent kept in 1..254, stored as a float32. In the core: the renderer writes them and the
// reader and the cryptomatte node read them (io/cryptomatte.h has the header's declarations).

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace posthaste::cryptomatte {

/// MurmurHash3_x86_32 of `data` (Austin Appleby's public-domain hash).
std::uint32_t murmur3_32(std::string_view data, std::uint32_t seed = 0);
/// The specification's uint32_to_float32: the hash's bits with the exponent kept in 1..254.
float id_from_hash(std::uint32_t hash);
/// The ID of a name: id_from_hash(murmur3_32(name)).
float id_of(std::string_view name);
/// The bits of an ID (what the manifest writes as 8 hex digits).
inline std::uint32_t bits_of(float id)
{
    std::uint32_t b;
    std::memcpy(&b, &id, sizeof(b));
    return b;
}
/// "13851a76" for an ID.
std::string hex_of(float id);

}  // namespace posthaste::cryptomatte
