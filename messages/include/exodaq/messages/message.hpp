#pragma once
// A decoded exodaq message of any type of the list (message_list.def),
// decoding by kind, and the header every message carries.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <variant>
#include <vector>

#include "exodaq/message_types.hpp"
#include "exodaq/messages/channels.hpp"

namespace exodaq::messages {

namespace detail {
template <typename First, typename... T>
struct VariantOfRest {
  using type = std::variant<T...>;
};
}  // namespace detail

// One alternative per kind, the alternative's index being the kind's value.
using Message = detail::VariantOfRest<void
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) , type
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
                                      >::type;

// The message type of a kind: MessageOf<Kind::kPalmPose> is palm_pose_t.
template <Kind K>
using MessageOf = std::variant_alternative_t<static_cast<std::size_t>(K), Message>;
static_assert(std::variant_size_v<Message> == kAllKinds.size());
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  static_assert(std::is_same_v<MessageOf<KindOf<type>::value>, type>);
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE

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
// The kind and header of encoded bytes without decoding them: every exodaq
// type starts, after its fingerprint, with utime, mono_ns, seq and run_id
// (big-endian int64). nullopt for a foreign fingerprint or fewer than 40
// bytes. For counting at wire speed (exodaq record); the message may still
// not decode.
struct KindStamp {
  Kind kind = Kind::kJointState;
  Stamp stamp;
};
std::optional<KindStamp> peek_stamp(const void* data, std::size_t size) noexcept;

// The run id as every tool, log line and CSV spells it: the 64 bits as 16
// lower-case hex digits ("1f3a09c2d4e5b6a7"; docs/messages.md).
std::string run_id_text(std::int64_t run_id);
// run_id_text() read back; nullopt unless exactly 16 hex digits.
std::optional<std::int64_t> parse_run_id(std::string_view text);

// A string from the network (a status's rig, a message text) made safe for a
// log line or a terminal: control characters (line breaks, ESC, DEL) and
// bytes that are not UTF-8 become \xNN (\n, \r, \t for those three);
// everything else, UTF-8 included, is kept. Applying it twice changes nothing.
std::string printable(std::string_view text);

// The daemon encodes every type once, all zero, before its first cycle (so
// lcm-gen's hashes are initialised off the loop); recordings hold them.
bool is_startup_message(const Stamp& s) noexcept;

// The counters a source_status_t holds: counter_count, within both arrays
// (a damaged or hand-made message may disagree with itself).
inline std::size_t counters_in(const source_status_t& m) noexcept {
  const auto n = static_cast<std::size_t>(m.counter_count < 0 ? 0 : m.counter_count);
  return std::min({n, m.counter_name.size(), m.counter_value.size()});
}

}  // namespace exodaq::messages
