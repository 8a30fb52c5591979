#include "exodaq/messages/channels.hpp"

#include <cctype>
#include <cstring>

#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/homing_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::msg {

namespace {

struct KindInfo {
  Kind kind;
  std::string_view base;
  std::string_view type;
  std::string_view short_name;
};

constexpr std::array<KindInfo, kKindCount> kInfo = {{
    {Kind::kJointState, "EXO_JOINT_STATE", "joint_state_t", "joint_state"},
    {Kind::kPalmPose, "EXO_PALM_POSE", "palm_pose_t", "palm_pose"},
    {Kind::kEncoderRaw, "EXO_ENCODER_RAW", "encoder_raw_t", "encoder_raw"},
    {Kind::kStatus, "EXO_STATUS", "status_t", "status"},
    {Kind::kHoming, "EXO_HOMING", "homing_t", "homing"},
}};

const KindInfo& info(Kind k) noexcept {
  return kInfo[static_cast<std::size_t>(k)];
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (auto& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

template <typename T>
std::uint64_t fingerprint() noexcept {
  return static_cast<std::uint64_t>(T::getHash());
}

}  // namespace

std::string_view base_channel(Kind k) noexcept {
  return info(k).base;
}

std::string_view type_name(Kind k) noexcept {
  return info(k).type;
}

std::string channel_name(std::string_view prefix, Kind k) {
  return std::string(prefix) + std::string(base_channel(k));
}

std::optional<ChannelParts> split_channel(std::string_view channel) {
  for (const auto& i : kInfo) {
    if (channel.size() >= i.base.size() &&
        channel.substr(channel.size() - i.base.size()) == i.base) {
      return ChannelParts{std::string(channel.substr(0, channel.size() - i.base.size())), i.kind};
    }
  }
  return std::nullopt;
}

std::optional<Kind> parse_kind(std::string_view text) {
  const std::string u = upper(text);
  for (const auto& i : kInfo) {
    if (u == upper(i.base) || u == upper(i.type) || u == upper(i.short_name)) return i.kind;
  }
  if (u == "JOINT" || u == "JOINTS") return Kind::kJointState;
  if (u == "PALM" || u == "POSE") return Kind::kPalmPose;
  if (u == "RAW" || u == "ENCODER") return Kind::kEncoderRaw;
  return std::nullopt;
}

std::optional<Kind> kind_of_payload(const void* data, std::size_t size) noexcept {
  if (size < 8) return std::nullopt;
  const auto* b = static_cast<const unsigned char*>(data);
  std::uint64_t fp = 0;
  for (int i = 0; i < 8; ++i) fp = (fp << 8) | b[i];
  if (fp == fingerprint<joint_state_t>()) return Kind::kJointState;
  if (fp == fingerprint<palm_pose_t>()) return Kind::kPalmPose;
  if (fp == fingerprint<encoder_raw_t>()) return Kind::kEncoderRaw;
  if (fp == fingerprint<status_t>()) return Kind::kStatus;
  if (fp == fingerprint<homing_t>()) return Kind::kHoming;
  return std::nullopt;
}

std::string regex_escape(std::string_view literal) {
  std::string out;
  for (char c : literal) {
    if (std::strchr(".[]{}()\\*+?^$|", c) != nullptr) out += '\\';
    out += c;
  }
  return out;
}

}  // namespace exodaq::msg
