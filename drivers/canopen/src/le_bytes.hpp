#pragma once
// Little-endian field access on a classic CAN payload (library-internal).
#include <array>
#include <cstddef>
#include <cstdint>

namespace exodaq::drivers::canopen {

using Payload = std::array<std::uint8_t, 8>;

inline std::uint16_t get_u16(const Payload& d, std::size_t at) noexcept {
  return static_cast<std::uint16_t>(d[at] | (d[at + 1] << 8));
}

inline std::uint32_t get_u32(const Payload& d, std::size_t at) noexcept {
  return static_cast<std::uint32_t>(d[at]) | (static_cast<std::uint32_t>(d[at + 1]) << 8) |
         (static_cast<std::uint32_t>(d[at + 2]) << 16) |
         (static_cast<std::uint32_t>(d[at + 3]) << 24);
}

inline void put_u16(Payload& d, std::size_t at, std::uint16_t v) noexcept {
  d[at] = static_cast<std::uint8_t>(v & 0xFF);
  d[at + 1] = static_cast<std::uint8_t>(v >> 8);
}

inline void put_u32(Payload& d, std::size_t at, std::uint32_t v) noexcept {
  for (std::size_t i = 0; i < 4; ++i) d[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// The low `bytes` (0..4) bytes of a 32-bit value.
constexpr std::uint32_t size_mask(std::uint8_t bytes) noexcept {
  return bytes >= 4 ? 0xFFFFFFFFU : (std::uint32_t{1} << (8 * bytes)) - 1;
}

}  // namespace exodaq::drivers::canopen
