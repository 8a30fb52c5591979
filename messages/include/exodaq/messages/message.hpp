#pragma once
// A decoded exodaq message of any of the five types, decoding by kind, and
// the header every message carries.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/homing_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/messages/channels.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::msg {

using Message = std::variant<joint_state_t, palm_pose_t, encoder_raw_t, status_t, homing_t>;

Kind kind_of(const Message& m) noexcept;

// Decodes `data` as `k`: nullopt when the bytes are not exactly one complete
// message of that type (wrong fingerprint, truncated, trailing bytes, or a
// damaged string length, which LCM 1.3.1's decoders throw for).
std::optional<Message> decode(Kind k, const void* data, std::size_t size);

// Decodes into an existing message (no new strings once their capacity
// suffices); false when the bytes are not exactly one message of type T.
template <typename T>
bool decode_into(T& msg, const void* data, std::size_t size) noexcept {
  if (size > 0x7FFFFFFF) return false;
  try {
    return msg.decode(data, 0, static_cast<int>(size)) == static_cast<int>(size);
  } catch (...) {
    return false;
  }
}

// One message's encoded bytes (tools and tests; the loop encodes into its
// pre-allocated slots instead).
template <typename T>
std::vector<std::uint8_t> encode(const T& msg) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  return bytes;
}

// Common header of every message.
struct Stamp {
  std::int64_t utime = 0;
  std::int64_t mono_ns = 0;
  std::int64_t seq = 0;
  std::int64_t run_id = 0;
};
Stamp stamp_of(const Message& m) noexcept;

// The run id as every tool, log line and CSV spells it: the 64 bits as 16
// lower-case hex digits ("1f3a09c2d4e5b6a7"; docs/messages.md).
std::string run_id_text(std::int64_t run_id);
// run_id_text() read back; nullopt unless exactly 16 hex digits.
std::optional<std::int64_t> parse_run_id(std::string_view text);

// The daemon encodes every type once, all zero, before its first cycle (so
// lcm-gen's hashes are initialised off the loop); recordings hold them.
bool is_startup_message(const Stamp& s) noexcept;

}  // namespace exodaq::msg
