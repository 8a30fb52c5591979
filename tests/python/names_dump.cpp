// exodaq_names_dump: the C++ messages library's channel table and flag names,
// one line per value, for tests/python/check_names.py to compare with the
// Python package's (exodaq.names). Values: 0, every single bit, all bits, and
// a few mixtures for the flag families; every int8 for the state codes.
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "exodaq/messages/channels.hpp"
#include "exodaq/messages/flag_names.hpp"

namespace {

std::vector<std::int32_t> flag_values() {
  std::vector<std::int32_t> v = {0, -1, 3, 0x41, 0x5000, 0x7FF, 0x12345678};
  for (int b = 0; b < 32; ++b) v.push_back(static_cast<std::int32_t>(std::uint32_t{1} << b));
  return v;
}

}  // namespace

int main() {
  using namespace exodaq::messages;
  for (Kind k : kAllKinds) {
    std::printf("kind %s %s %s\n", std::string(type_name(k)).c_str(),
                std::string(base_channel(k)).c_str(), is_per_cycle(k) ? "per_cycle" : "-");
  }
  for (const char* text :
       {"joint_state", "JOINTS", "joint", "palm", "Pose", "palm_pose_t", "raw", "encoder",
        "EXO_ENCODER_RAW", "status", "exo_status", "status_t", "state", "", "EXO_JOINT"}) {
    const auto k = parse_kind(text);
    const std::string what = k ? std::string(type_name(*k)) : "-";
    std::printf("parse '%s' %s\n", text, what.c_str());
  }
  for (const char* channel : {"EXO_JOINT_STATE", "RIG2_EXO_PALM_POSE", "a.b_EXO_STATUS",
                              "EXO_ENCODER_RAW", "X_EXO_STATUS_", "BIG", ""}) {
    const auto parts = split_channel(channel);
    const std::string what =
        parts ? "'" + parts->prefix + "' " + std::string(type_name(parts->kind)) : "-";
    std::printf("split '%s' %s\n", channel, what.c_str());
  }
  for (std::int32_t v : flag_values()) {
    std::printf("joint %d %s\n", v, joint_flag_names(v).c_str());
    std::printf("sample %d %s\n", v, sample_flag_names(v).c_str());
    std::printf("invalid %d %s\n", v, invalid_reason_names(v).c_str());
  }
  for (int v = -128; v < 128; ++v) {
    const auto c = static_cast<std::int8_t>(v);
    std::printf("state %d %s\n", v, std::string(state_name(c)).c_str());
    std::printf("bus %d %s\n", v, std::string(bus_state_name(c)).c_str());
    std::printf("homing %d %s\n", v, std::string(homing_name(c)).c_str());
  }
  return 0;
}
