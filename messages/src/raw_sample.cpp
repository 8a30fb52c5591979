#include "exodaq/messages/raw_sample.hpp"

#include <cstddef>

#include "exodaq/common/wrapping.hpp"
#include "exodaq/messages/message.hpp"
#include "exodaq_v1/encoder_raw_t.hpp"

namespace exodaq::messages {

namespace {
constexpr auto kChannels = static_cast<std::size_t>(drivers::kChannelCount);
}  // namespace

void to_encoder_raw(const drivers::EncoderSample& s, encoder_raw_t& out) noexcept {
  out.present = s.present;
  out.source_seq = s.seq;
  out.source_seq_modulus = s.seq_modulus;
  for (std::size_t c = 0; c < kChannels; ++c) {
    out.position[c] = s.position[c];
    out.modulus[c] = s.modulus[c];
    out.index_position[c] = s.index_position[c];
  }
  out.index_latched = static_cast<std::int32_t>(s.index_latched);
  out.index_count_valid = static_cast<std::int32_t>(s.index_count_valid);
  out.absolute = static_cast<std::int32_t>(s.absolute);
  out.channel_fresh = static_cast<std::int32_t>(s.channel_fresh);
  out.board_state = static_cast<std::int32_t>(s.board_state);
  out.board_errors = static_cast<std::int32_t>(s.board_errors);
  out.source_flags = static_cast<std::int32_t>(s.flags);
  out.wall_ns = s.wall_ns;
}

void from_encoder_raw(const encoder_raw_t& raw, drivers::EncoderSample& s) noexcept {
  s.mono_ns = raw.mono_ns;
  s.wall_ns = raw.utime * 1000;
  s.present = raw.present != 0;
  s.seq = raw.source_seq;
  s.seq_modulus = raw.source_seq_modulus;
  for (std::size_t c = 0; c < kChannels; ++c) {
    s.position[c] = raw.position[c];
    s.modulus[c] = raw.modulus[c];
    s.index_position[c] = raw.index_position[c];
  }
  s.index_latched = static_cast<std::uint32_t>(raw.index_latched);
  s.index_count_valid = static_cast<std::uint32_t>(raw.index_count_valid);
  s.absolute = static_cast<std::uint32_t>(raw.absolute);
  s.channel_fresh = static_cast<std::uint32_t>(raw.channel_fresh) & drivers::kAllChannels;
  s.board_state = static_cast<std::uint32_t>(raw.board_state);
  s.board_errors = static_cast<std::uint32_t>(raw.board_errors);
  s.flags = static_cast<std::uint32_t>(raw.source_flags);
}

void upgrade(const exodaq_v1::encoder_raw_t& v1, encoder_raw_t& out) noexcept {
  out.utime = v1.utime;
  out.mono_ns = v1.mono_ns;
  out.seq = v1.seq;
  out.run_id = v1.run_id;
  out.present = v1.present;
  out.source_seq = v1.board_seq;
  out.source_seq_modulus = kSeq8Modulus;
  for (std::size_t c = 0; c < kChannels; ++c) {
    out.position[c] = static_cast<std::uint16_t>(v1.count16[c]);
    out.modulus[c] = kCount16Modulus;
    out.index_position[c] = static_cast<std::uint16_t>(v1.index_count16[c]);
  }
  out.index_latched = v1.index_latched;
  out.index_count_valid = v1.index_count_valid;
  out.absolute = 0;
  out.channel_fresh = v1.present ? static_cast<std::int32_t>(drivers::kAllChannels) : 0;
  out.board_state = v1.board_state;
  out.board_errors = v1.board_errors;
  out.source_flags = v1.source_flags;
  out.wall_ns = v1.wall_ns;
}

namespace {
bool in_range(std::int64_t value, std::int64_t modulus) noexcept {
  if (modulus < 0 || modulus > kMaxCount) return false;
  return modulus > 0 ? value >= 0 && value < modulus : value >= -kMaxCount && value <= kMaxCount;
}
}  // namespace

bool positions_in_range(const encoder_raw_t& raw) noexcept {
  if (raw.source_seq != -1 && !in_range(raw.source_seq, raw.source_seq_modulus)) return false;
  if (raw.source_seq_modulus < 0 || raw.source_seq_modulus > kMaxCount) return false;
  for (std::size_t c = 0; c < kChannels; ++c) {
    if (!in_range(raw.position[c], raw.modulus[c]) ||
        !in_range(raw.index_position[c], raw.modulus[c])) {
      return false;
    }
  }
  return true;
}

RawVersion decode_encoder_raw(encoder_raw_t& out, const void* data, std::size_t size) noexcept {
  if (decode_into(out, data, size)) return RawVersion::kV2;
  exodaq_v1::encoder_raw_t v1;
  if (!decode_into(v1, data, size)) return RawVersion::kNone;
  upgrade(v1, out);
  return RawVersion::kV1;
}

}  // namespace exodaq::messages
