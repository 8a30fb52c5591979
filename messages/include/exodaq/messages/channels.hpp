#pragma once
// The five exodaq messages and their channels: the one table of channel names,
// type names and fingerprints. A channel is `<prefix><base>`, e.g.
// "RIG2_" + "EXO_JOINT_STATE" (docs/messages.md).
#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace exodaq::msg {

enum class Kind : std::uint8_t { kJointState = 0, kPalmPose, kEncoderRaw, kStatus, kHoming };
inline constexpr int kKindCount = 5;
inline constexpr std::array<Kind, kKindCount> kAllKinds = {
    Kind::kJointState, Kind::kPalmPose, Kind::kEncoderRaw, Kind::kStatus, Kind::kHoming};

// "EXO_JOINT_STATE" etc., without prefix.
std::string_view base_channel(Kind k) noexcept;
// "joint_state_t" etc.
std::string_view type_name(Kind k) noexcept;
// prefix + base channel.
std::string channel_name(std::string_view prefix, Kind k);

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

}  // namespace exodaq::msg
