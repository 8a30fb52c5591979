#pragma once
// The exodaq messages and their channels, all derived from the one list
// (message_list.def): their kinds, channel names, type names and fingerprints.
// A channel is `<prefix><base>`, e.g. "RIG2_" + "EXO_JOINT_STATE"
// (docs/messages.md).
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace exodaq {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) class type;
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
}  // namespace exodaq

namespace exodaq::messages {

// One kind per line of the list, numbered in its order from 0.
enum class Kind : std::uint8_t {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) kind,
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
};
inline constexpr std::array kAllKinds = {
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) Kind::kind,
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE
};
inline constexpr int kKindCount = static_cast<int>(kAllKinds.size());

// The kind of a message type: KindOf<palm_pose_t>::value == Kind::kPalmPose;
// a type the list does not name does not compile.
template <typename T>
struct KindOf;
#define EXODAQ_MESSAGE(kind, type, channel, per_cycle, aliases) \
  template <>                                                   \
  struct KindOf<::exodaq::type> {                               \
    static constexpr Kind value = Kind::kind;                   \
  };
#include "exodaq/messages/message_list.def"
#undef EXODAQ_MESSAGE

// "EXO_JOINT_STATE" etc., without prefix.
std::string_view base_channel(Kind k) noexcept;
// "joint_state_t" etc.
std::string_view type_name(Kind k) noexcept;
// prefix + base channel.
std::string channel_name(std::string_view prefix, Kind k);
// Whether the daemon sends one message of kind k every cycle, with the
// cycle's seq (joint_state_t, palm_pose_t, encoder_raw_t).
bool is_per_cycle(Kind k) noexcept;

// A channel name split into its prefix and kind: "RIG2_EXO_PALM_POSE" ->
// {"RIG2_", kPalmPose}; nullopt when it ends in no base name.
struct ChannelParts {
  std::string prefix;
  Kind kind = Kind::kJointState;
};
std::optional<ChannelParts> split_channel(std::string_view channel);

// What a user typed for a channel: a short name ("joint_state", "palm",
// "raw", "status"), a base name (case-insensitive) or a type name.
std::optional<Kind> parse_kind(std::string_view text);

// The type of an encoded message from its 8-byte fingerprint; nullopt for a
// foreign type or a buffer shorter than 8 bytes.
std::optional<Kind> kind_of_payload(const void* data, std::size_t size) noexcept;

// LCM subscribes by POSIX extended regular expression: a literal channel name
// escaped so that a prefix like "rig.2" matches only itself.
std::string regex_escape(std::string_view literal);

}  // namespace exodaq::messages
