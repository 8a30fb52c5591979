#include "exodaq/messages/message.hpp"

#include <cstdio>
#include <type_traits>

namespace exodaq::msg {

Kind kind_of(const Message& m) noexcept {
  return std::visit(
      [](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, joint_state_t>) return Kind::kJointState;
        if constexpr (std::is_same_v<T, palm_pose_t>) return Kind::kPalmPose;
        if constexpr (std::is_same_v<T, encoder_raw_t>) return Kind::kEncoderRaw;
        if constexpr (std::is_same_v<T, status_t>) return Kind::kStatus;
        if constexpr (std::is_same_v<T, homing_t>) return Kind::kHoming;
      },
      m);
}

namespace {
template <typename T>
std::optional<Message> decode_as(const void* data, std::size_t size) {
  T msg;
  if (!decode_into(msg, data, size)) return std::nullopt;
  return Message{std::move(msg)};
}
}  // namespace

std::optional<Message> decode(Kind k, const void* data, std::size_t size) {
  switch (k) {
    case Kind::kJointState:
      return decode_as<joint_state_t>(data, size);
    case Kind::kPalmPose:
      return decode_as<palm_pose_t>(data, size);
    case Kind::kEncoderRaw:
      return decode_as<encoder_raw_t>(data, size);
    case Kind::kStatus:
      return decode_as<status_t>(data, size);
    case Kind::kHoming:
      return decode_as<homing_t>(data, size);
  }
  return std::nullopt;
}

Stamp stamp_of(const Message& m) noexcept {
  return std::visit([](const auto& v) { return Stamp{v.utime, v.mono_ns, v.seq, v.run_id}; }, m);
}

std::string run_id_text(std::int64_t run_id) {
  char buf[24];
  std::snprintf(buf, sizeof buf, "%016llx",
                static_cast<unsigned long long>(static_cast<std::uint64_t>(run_id)));
  return buf;
}

std::optional<std::int64_t> parse_run_id(std::string_view text) {
  if (text.size() != 16) return std::nullopt;
  std::uint64_t v = 0;
  for (const char c : text) {
    int d = -1;
    if (c >= '0' && c <= '9') d = c - '0';
    if (c >= 'a' && c <= 'f') d = c - 'a' + 10;
    if (c >= 'A' && c <= 'F') d = c - 'A' + 10;
    if (d < 0) return std::nullopt;
    v = (v << 4) | static_cast<std::uint64_t>(d);
  }
  return static_cast<std::int64_t>(v);
}

bool is_startup_message(const Stamp& s) noexcept {
  return s.utime == 0 && s.mono_ns == 0 && s.seq == 0;
}

}  // namespace exodaq::msg
