#pragma once
// Wrapping counter arithmetic, the one definition: every sample carries the
// low 16 bits of each joint's count (count16) and an 8-bit board sequence.
#include <cstdint>

namespace exodaq {

// Signed distance from reading `from` to reading `to` of a 16-bit counter, in
// [−32768, 32767] (the smallest one modulo 65536).
constexpr int count_delta16(std::uint16_t from, std::uint16_t to) noexcept {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(to - from));
}

// Unwraps a 16-bit counter reading against the previous unwrapped value by the
// smallest signed difference: result ≡ raw (mod 65536) and result − previous
// ∈ [−32768, 32767]. Correct while fewer than 32768 counts pass between two
// readings.
constexpr std::int64_t unwrap16(std::int64_t previous, std::uint16_t raw) noexcept {
  return previous + count_delta16(static_cast<std::uint16_t>(previous & 0xFFFF), raw);
}

// Signed distance from `from` to `to` in the uint8 board-sequence space, in
// [−128, 127]: 1 = next cycle, 0 = same, negative = older.
constexpr int seq_delta(std::uint8_t from, std::uint8_t to) noexcept {
  return static_cast<std::int8_t>(static_cast<std::uint8_t>(to - from));
}

}  // namespace exodaq
