#pragma once
// Plausible messages for tests and corpus makers: one place that says what a
// daemon-written encoder_raw_t of cycle `seq` looks like.
#include <cstdint>

#include "exodaq/encoder_raw_t.hpp"

namespace exodaq::test {

// Cycle `seq` of run `run_id` at 1 kHz, as protocol v1 delivers it: present,
// board sequence seq mod 256, channel c's count 100 c + seq mod 65536, every
// channel fresh, board state 1, no index, no flags.
inline encoder_raw_t raw_message(std::int64_t seq, std::int64_t run_id = 0x5eed) {
  encoder_raw_t m{};
  m.utime = 1'700'000'000'000'000 + seq * 1000;
  m.mono_ns = 5'000'000'000 + seq * 1'000'000;
  m.seq = seq;
  m.run_id = run_id;
  m.present = 1;
  m.source_seq = seq & 0xFF;
  m.source_seq_modulus = 256;
  for (int c = 0; c < 6; ++c) {
    m.position[c] = (100 * c + seq) & 0xFFFF;
    m.modulus[c] = 65536;
  }
  m.channel_fresh = 0x3F;
  m.board_state = 1;
  m.wall_ns = m.utime * 1000;
  return m;
}

}  // namespace exodaq::test
