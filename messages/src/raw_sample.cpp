#include "exodaq/messages/raw_sample.hpp"

#include <cstddef>

namespace exodaq::messages {

void to_encoder_raw(const drivers::EncoderSample& s, encoder_raw_t& out) noexcept {
  out.present = s.present;
  out.board_seq = s.board_seq;
  for (std::size_t c = 0; c < static_cast<std::size_t>(drivers::kChannelCount); ++c) {
    out.count16[c] = static_cast<std::int16_t>(s.count16[c]);
    out.index_count16[c] = static_cast<std::int16_t>(s.index_count16[c]);
  }
  out.index_latched = static_cast<std::int32_t>(s.index_latched);
  out.index_count_valid = static_cast<std::int32_t>(s.index_count_valid);
  out.board_state = static_cast<std::int32_t>(s.board_state);
  out.board_errors = static_cast<std::int32_t>(s.board_errors);
  out.source_flags = static_cast<std::int32_t>(s.flags);
  out.wall_ns = s.wall_ns;
}

void from_encoder_raw(const encoder_raw_t& raw, drivers::EncoderSample& s) noexcept {
  s.mono_ns = raw.mono_ns;
  s.wall_ns = raw.utime * 1000;
  s.present = raw.present != 0;
  s.board_seq = raw.board_seq;
  for (std::size_t c = 0; c < static_cast<std::size_t>(drivers::kChannelCount); ++c) {
    s.count16[c] = static_cast<std::uint16_t>(raw.count16[c]);
    s.index_count16[c] = static_cast<std::uint16_t>(raw.index_count16[c]);
  }
  s.index_latched = static_cast<std::uint32_t>(raw.index_latched);
  s.index_count_valid = static_cast<std::uint32_t>(raw.index_count_valid);
  s.board_state = static_cast<std::uint32_t>(raw.board_state);
  s.board_errors = static_cast<std::uint32_t>(raw.board_errors);
  s.flags = static_cast<std::uint32_t>(raw.source_flags);
  s.channel_fresh = s.present ? 0x3FU : 0U;
}

}  // namespace exodaq::messages
