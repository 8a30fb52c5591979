#include "exodaq/messages/flag_names.hpp"

#include <cstdio>
#include <cstring>

#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::messages {

namespace {

struct BitName {
  std::int32_t bit;
  std::string_view name;
};

constexpr BitName kJointFlags[] = {{joint_state_t::JOINT_UNHOMED, "UNHOMED"},
                                   {joint_state_t::JOINT_STALE, "STALE"},
                                   {joint_state_t::JOINT_GLITCH, "GLITCH"},
                                   {joint_state_t::JOINT_OUT_OF_RANGE, "OUT_OF_RANGE"},
                                   {joint_state_t::JOINT_LOST_COUNTS, "LOST_COUNTS"},
                                   {joint_state_t::JOINT_HOMING_REJECTED, "HOMING_REJECTED"},
                                   {joint_state_t::JOINT_HELD, "HELD"},
                                   {joint_state_t::JOINT_BOARD_ERROR, "BOARD_ERROR"}};

constexpr BitName kSampleFlags[] = {{joint_state_t::SAMPLE_MISSING, "MISSING"},
                                    {joint_state_t::SAMPLE_SEQ_GAP, "SEQ_GAP"},
                                    {joint_state_t::SAMPLE_DUPLICATE, "DUPLICATE"},
                                    {joint_state_t::SAMPLE_OUT_OF_ORDER, "OUT_OF_ORDER"},
                                    {joint_state_t::SAMPLE_BOARD_ERROR, "BOARD_ERROR"},
                                    {joint_state_t::SAMPLE_BUS_ERROR, "BUS_ERROR"},
                                    {joint_state_t::SAMPLE_CLOCK_STEP, "CLOCK_STEP"},
                                    {joint_state_t::SAMPLE_CLOCK_UNSYNC, "CLOCK_UNSYNC"},
                                    {joint_state_t::SAMPLE_LATE, "LATE"},
                                    {joint_state_t::SAMPLE_PARTIAL, "PARTIAL"},
                                    {joint_state_t::SAMPLE_REPLAY, "REPLAY"},
                                    {joint_state_t::SAMPLE_FOREIGN_RUN, "FOREIGN_RUN"},
                                    {joint_state_t::SAMPLE_NEW_SEGMENT, "NEW_SEGMENT"}};

constexpr BitName kInvalidReasons[] = {{palm_pose_t::INVALID_UNHOMED, "UNHOMED"},
                                       {palm_pose_t::INVALID_JOINT_FAULT, "JOINT_FAULT"},
                                       {palm_pose_t::INVALID_SAMPLE, "SAMPLE"},
                                       {palm_pose_t::INVALID_SOURCE, "SOURCE"},
                                       {palm_pose_t::INVALID_CLOCK, "CLOCK"}};

// Every name the tables hold, joined, and an unknown rest: well within this.
constexpr std::size_t kMaxText = 256;

// Calls `each` with the name of every set bit, then with the unknown rest
// ("0x1000") if any.
template <std::size_t N, typename F>
void each_bit(std::int32_t flags, const BitName (&names)[N], F each) {
  auto rest = static_cast<std::uint32_t>(flags);
  for (const auto& n : names) {
    if (rest & static_cast<std::uint32_t>(n.bit)) {
      each(n.name);
      rest &= ~static_cast<std::uint32_t>(n.bit);
    }
  }
  if (rest != 0) {
    char buf[16];
    const int len = std::snprintf(buf, sizeof buf, "0x%x", rest);
    each(std::string_view(buf, static_cast<std::size_t>(len)));
  }
}

template <std::size_t N>
std::size_t write_bits(std::int32_t flags, const BitName (&names)[N], char* out,
                       std::size_t cap) noexcept {
  if (cap == 0) return 0;
  std::size_t n = 0;
  const auto put = [&](std::string_view text) {
    const std::size_t room = cap - 1 - n;
    const std::size_t len = text.size() < room ? text.size() : room;
    std::memcpy(out + n, text.data(), len);
    n += len;
  };
  if (flags == 0) {
    put("-");
  } else {
    each_bit(flags, names, [&](std::string_view name) {
      if (n > 0) put("|");
      put(name);
    });
  }
  out[n] = '\0';
  return n;
}

template <std::size_t N>
std::string bit_names(std::int32_t flags, const BitName (&names)[N]) {
  char text[kMaxText];
  return {text, write_bits(flags, names, text, sizeof text)};
}

}  // namespace

std::size_t write_joint_flag_names(std::int32_t flags, char* out, std::size_t cap) noexcept {
  return write_bits(flags, kJointFlags, out, cap);
}

std::size_t write_sample_flag_names(std::int32_t flags, char* out, std::size_t cap) noexcept {
  return write_bits(flags, kSampleFlags, out, cap);
}

std::vector<std::string> joint_flag_list(std::int32_t flags) {
  std::vector<std::string> out;
  each_bit(flags, kJointFlags, [&](std::string_view name) { out.emplace_back(name); });
  return out;
}

std::string joint_flag_names(std::int32_t flags) {
  return bit_names(flags, kJointFlags);
}

std::string sample_flag_names(std::int32_t flags) {
  return bit_names(flags, kSampleFlags);
}

std::string invalid_reason_names(std::int32_t reasons) {
  return bit_names(reasons, kInvalidReasons);
}

std::string_view state_name(std::int8_t state) {
  switch (state) {
    case status_t::STATE_STARTING:
      return "STARTING";
    case status_t::STATE_HOMING:
      return "HOMING";
    case status_t::STATE_RUNNING:
      return "RUNNING";
    case status_t::STATE_DEGRADED:
      return "DEGRADED";
    case status_t::STATE_FAULT:
      return "FAULT";
    case status_t::STATE_STOPPING:
      return "STOPPING";
    default:
      return "UNKNOWN_STATE";
  }
}

std::string_view bus_state_name(std::int8_t bus) {
  switch (bus) {
    case status_t::BUS_UNKNOWN:
      return "UNKNOWN";
    case status_t::BUS_ACTIVE:
      return "ACTIVE";
    case status_t::BUS_WARNING:
      return "WARNING";
    case status_t::BUS_PASSIVE:
      return "PASSIVE";
    case status_t::BUS_OFF:
      return "OFF";
    case status_t::BUS_DOWN:
      return "DOWN";
    default:
      return "?";
  }
}

std::string_view homing_name(std::int8_t homing) {
  switch (homing) {
    case status_t::HOMING_UNHOMED:
      return "UNHOMED";
    case status_t::HOMING_HOMED:
      return "HOMED";
    case status_t::HOMING_REJECTED:
      return "REJECTED";
    default:
      return "?";
  }
}

}  // namespace exodaq::messages
