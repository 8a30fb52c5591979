#include "exodaq/messages/flag_names.hpp"

#include <cstdio>
#include <initializer_list>

#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::msg {

namespace {

struct BitName {
  std::int32_t bit;
  std::string_view name;
};

std::string bit_names(std::int32_t flags, std::initializer_list<BitName> names) {
  if (flags == 0) return "-";
  std::string out;
  auto rest = static_cast<std::uint32_t>(flags);
  for (const auto& n : names) {
    if (rest & static_cast<std::uint32_t>(n.bit)) {
      if (!out.empty()) out += '|';
      out += n.name;
      rest &= ~static_cast<std::uint32_t>(n.bit);
    }
  }
  if (rest != 0) {
    char buf[16];
    std::snprintf(buf, sizeof buf, "0x%x", rest);
    if (!out.empty()) out += '|';
    out += buf;
  }
  return out;
}

}  // namespace

std::string joint_flag_names(std::int32_t flags) {
  return bit_names(flags, {{joint_state_t::JOINT_UNHOMED, "UNHOMED"},
                           {joint_state_t::JOINT_STALE, "STALE"},
                           {joint_state_t::JOINT_GLITCH, "GLITCH"},
                           {joint_state_t::JOINT_OUT_OF_RANGE, "OUT_OF_RANGE"},
                           {joint_state_t::JOINT_LOST_COUNTS, "LOST_COUNTS"},
                           {joint_state_t::JOINT_HOMING_REJECTED, "HOMING_REJECTED"},
                           {joint_state_t::JOINT_HELD, "HELD"},
                           {joint_state_t::JOINT_BOARD_ERROR, "BOARD_ERROR"}});
}

std::string sample_flag_names(std::int32_t flags) {
  return bit_names(flags, {{joint_state_t::SAMPLE_MISSING, "MISSING"},
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
                           {joint_state_t::SAMPLE_FOREIGN_RUN, "FOREIGN_RUN"}});
}

std::string invalid_reason_names(std::int32_t reasons) {
  return bit_names(reasons, {{palm_pose_t::INVALID_UNHOMED, "UNHOMED"},
                             {palm_pose_t::INVALID_JOINT_FAULT, "JOINT_FAULT"},
                             {palm_pose_t::INVALID_SAMPLE, "SAMPLE"},
                             {palm_pose_t::INVALID_SOURCE, "SOURCE"},
                             {palm_pose_t::INVALID_CLOCK, "CLOCK"}});
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

}  // namespace exodaq::msg
