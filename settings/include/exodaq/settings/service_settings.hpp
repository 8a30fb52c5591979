#pragma once
// The plain settings of the service configuration (service_config.hpp loads
// them): loop, encoders, LCM, clock policy and logging, and the joint count.
// Values only: no YAML, no kinematics, so the acquisition core's headers can
// use them without the loaders. The fields and their defaults come from the
// declarations in setting_list.hpp.
#include <array>
#include <cstdint>
#include <string>

#include "exodaq/settings/setting_list.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::settings {

// The service publishes exactly the joints of joint_state_t's arrays.
inline constexpr int kJointCount = wire::kJointCount;

// How sample time treats the wall clock (docs/time.md).
struct ClockPolicy {
  EXODAQ_CLOCK_SETTINGS(EXODAQ_SETTING_FIELD)
};

struct LoopSettings {
  EXODAQ_LOOP_SETTINGS(EXODAQ_SETTING_FIELD)
};

struct EncoderJointSettings {
  EXODAQ_JOINT_SETTINGS(EXODAQ_SETTING_FIELD)
};

struct EncoderSettings {
  EXODAQ_ENCODER_SETTINGS(EXODAQ_SETTING_FIELD)
  std::array<EncoderJointSettings, kJointCount> joints{};
  std::int64_t counts_per_rev() const noexcept {
    return static_cast<std::int64_t>(cycles_per_rev) * decoding;
  }
};

struct LcmSettings {
  EXODAQ_LCM_SETTINGS(EXODAQ_SETTING_FIELD)
};

struct LoggingSettings {
  EXODAQ_LOGGING_SETTINGS(EXODAQ_SETTING_FIELD)
};

}  // namespace exodaq::settings
