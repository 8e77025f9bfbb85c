/// @file
/// FNV-1a 64 (Fowler-Noll-Vo), fed as a stream: the one implementation of the hash behind the
/// bake cache's file names and recipes (bake/bake_cache.h), a tile file's distile:hash
/// (sampler/tile_io.h) and the UUID of the .vdb files distile writes. Those values are stored
/// in files, so the hash of given bytes must never change. It detects changed content; it is
/// not cryptographic.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace distile {

/// FNV-1a 64 of the bytes fed so far. The value depends only on the bytes and their order, not
/// on how they were split between calls.
class Fnv1a64 {
  public:
    /// The offset basis and prime that FNV-1a 64 publishes.
    static constexpr std::uint64_t kOffsetBasis = 0xcbf29ce484222325ull;
    static constexpr std::uint64_t kPrime = 0x100000001b3ull;

    /// The hash of no bytes. Another `offsetBasis` gives a second, different hash of the same
    /// bytes (no longer the published FNV-1a 64).
    constexpr explicit Fnv1a64(std::uint64_t offsetBasis = kOffsetBasis) : value_(offsetBasis) {}

    /// Feeds one byte.
    constexpr void update(std::byte byte) {
        value_ = (value_ ^ std::to_integer<std::uint64_t>(byte)) * kPrime;
    }

    /// Feeds `bytes`, first to last.
    constexpr void update(std::span<const std::byte> bytes) {
        for (const std::byte byte : bytes) update(byte);
    }

    /// Feeds `value` as 4 little-endian bytes, whatever the host's byte order.
    constexpr void updateU32LittleEndian(std::uint32_t value) {
        for (int byte = 0; byte < 4; ++byte) update(std::byte(value >> (8 * byte)));
    }

    /// The hash of the bytes fed so far; feeding may continue.
    constexpr std::uint64_t value() const { return value_; }

  private:
    std::uint64_t value_;
};

/// `value` as 16 lowercase hex digits, leading zeros kept: how distile writes a 64-bit hash.
inline std::string hexDigits(std::uint64_t value) {
    constexpr char kDigits[] = "0123456789abcdef";
    std::string text(16, '0');
    for (auto digit = text.rbegin(); digit != text.rend(); ++digit, value >>= 4)
        *digit = kDigits[value & 0xf];
    return text;
}

}  // namespace distile
