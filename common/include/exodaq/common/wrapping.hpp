#pragma once
// Wrapping counter arithmetic, the one definition. A source states each
// position's modulus and its sequence's modulus (0: the value does not wrap);
// protocol v1 sends the low 16 bits of each count (kCount16Modulus) and an
// 8-bit board sequence (seq_delta(), the 256 case for its uint8 fields).
#include <cstdint>

namespace exodaq {

// Signed distance from reading `from` to reading `to` of a counter that wraps
// at `modulus`, in [−modulus/2, modulus/2): the smallest one modulo
// `modulus`. Readings lie in [0, modulus). modulus 0: to − from.
constexpr std::int64_t wrapped_delta(std::int64_t from, std::int64_t to,
                                     std::int64_t modulus) noexcept {
  if (modulus <= 0) return to - from;
  std::int64_t d = 0;
  if ((modulus & (modulus - 1)) == 0) {
    d = (to - from) & (modulus - 1);  // a power of two (every CAN encoder's): no division
  } else {
    d = (to - from) % modulus;
    if (d < 0) d += modulus;
  }
  return d >= modulus - modulus / 2 ? d - modulus : d;
}

// Unwraps a reading of a counter that wraps at `modulus` against the previous
// unwrapped value by the smallest signed difference: result ≡ raw (mod
// modulus) and result − previous ∈ [−modulus/2, modulus/2). Correct while
// fewer than modulus/2 counts pass between two readings. modulus 0: raw.
constexpr std::int64_t unwrap(std::int64_t previous, std::int64_t raw,
                              std::int64_t modulus) noexcept {
  return modulus <= 0 ? raw : previous + wrapped_delta(previous, raw, modulus);
}

// A value reduced into [0, modulus) (unchanged for modulus 0).
constexpr std::int64_t wrap(std::int64_t value, std::int64_t modulus) noexcept {
  if (modulus <= 0) return value;
  const std::int64_t r = value % modulus;
  return r < 0 ? r + modulus : r;
}

// Protocol v1: 16-bit counts, 8-bit board sequence.
inline constexpr std::int64_t kCount16Modulus = 65536;
inline constexpr std::int64_t kSeq8Modulus = 256;

// Signed distance from `from` to `to` in the uint8 board-sequence space, in
// [−128, 127]: 1 = next cycle, 0 = same, negative = older.
constexpr int seq_delta(std::uint8_t from, std::uint8_t to) noexcept {
  return static_cast<std::int8_t>(static_cast<std::uint8_t>(to - from));
}

static_assert(wrapped_delta(65535, 0, kCount16Modulus) == 1);
static_assert(wrapped_delta(0, 32768, kCount16Modulus) == -32768);
static_assert(unwrap(-1, 65535, kCount16Modulus) == -1);
static_assert(unwrap(70000, 4463, kCount16Modulus) == 69999);
static_assert(unwrap(5, 1000, 0) == 1000);
static_assert(wrapped_delta(250, 3, kSeq8Modulus) == seq_delta(250, 3));
static_assert(wrapped_delta(3, 250, 240) == 7 && wrapped_delta(0, 120, 240) == -120);
static_assert(wrapped_delta(239, 1, 240) == 2 && wrapped_delta(1, 239, 240) == -2);
static_assert(unwrap(-240, 5, 240) == -235 && unwrap(-1, 0, 10000) == 0);

}  // namespace exodaq
