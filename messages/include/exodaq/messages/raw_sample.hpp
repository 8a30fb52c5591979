#pragma once
// A source's sample <-> encoder_raw_t (version 2), field for field: the raw
// channel is what a replay runs the pipeline on again. Recordings of version 1
// (lcmtypes/v1/encoder_raw_t.lcm, protocol v1's frame) are read as version 2.
// Allocation-free (loop thread).
#include <cstddef>
#include <cstdint>

#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/encoder_raw_t.hpp"

namespace exodaq_v1 {
class encoder_raw_t;
}  // namespace exodaq_v1

namespace exodaq::messages {

// The sample's content (presence, sequence, positions with their moduli,
// index latches, references, fresh channels, board state and errors, source
// flags, wall_ns). The header (utime, mono_ns, seq, run_id) is the caller's:
// it belongs to the cycle, not the sample.
void to_encoder_raw(const drivers::EncoderSample& sample, encoder_raw_t& out) noexcept;

// The recorded sample: mono_ns and the content as recorded, wall_ns =
// utime * 1000 (so utime maps back exactly).
void from_encoder_raw(const encoder_raw_t& raw, drivers::EncoderSample& out) noexcept;

// Version 1 as version 2: protocol v1's moduli (65536, sequence 256), index
// references, every channel fresh when present (version 1 does not say which
// half of a PARTIAL sample arrived).
void upgrade(const exodaq_v1::encoder_raw_t& v1, encoder_raw_t& out) noexcept;

// The most a position, a modulus or a sequence may be (2^53: exact as a
// double). A channel's position and index position lie in [0, modulus) when
// its modulus is not 0, in [-kMaxCount, kMaxCount] when it is; the source's
// sequence likewise, or -1.
inline constexpr std::int64_t kMaxCount = std::int64_t{1} << 53;
// false: values no source writes (a damaged recording).
bool positions_in_range(const encoder_raw_t& raw) noexcept;

enum class RawVersion { kNone, kV1, kV2 };
// Decodes one encoder_raw_t of either version into `out` (version 2);
// kNone when the bytes are exactly one message of neither.
RawVersion decode_encoder_raw(encoder_raw_t& out, const void* data, std::size_t size) noexcept;

}  // namespace exodaq::messages
