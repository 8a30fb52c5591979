#pragma once
// What every backend needs to know about the rig's encoders, from the
// encoders section, the model and the calibration (plain values; the chain
// for the sim's task planning).
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string_view>

#include "exodaq/drivers/encoder_sample.hpp"

namespace exodaq::kinematics {
class Chain;                 // kinematics/chain.hpp
struct RigKinematicsConfig;  // kinematics/rig_kinematics.hpp
}  // namespace exodaq::kinematics

namespace exodaq::drivers {

class FrameAssembler;  // frame_assembler.hpp

struct SourceJointContext {
  int channel = 0;
  int direction = 1;
  double gear_ratio = 1.0;
  double index_angle_rad = 0.0;  // joint angle at the index (calibration delta_theta0)
  double home_rad = 0.0;         // home posture: where the simulated rig powers up
  double lower_rad = -3.14159;
  double upper_rad = 3.14159;
  double max_speed_rad_s = 1.0;
};

struct SourceContext {
  std::int64_t period_ns = 1'000'000;
  std::int64_t counts_per_rev = 10000;
  std::array<SourceJointContext, kChannelCount> joints{};
  // The model (the sim plans task motion with it) and its elbow frame and
  // shoulder joints; shared, so that a backend that plans nothing needs no
  // kinematics headers. Null: none given (the defaults of kinematics::Chain and
  // kinematics::RigKinematicsConfig).
  std::shared_ptr<const kinematics::Chain> chain;
  std::shared_ptr<const kinematics::RigKinematicsConfig> rig;
  // The frame assembler of the CAN backend of that name, with the settings
  // of the configuration's section for it (the defaults when it has none);
  // null when the backend has no CAN frames or is unknown. Set by
  // make_source() (source_factory.hpp); empty: none known (protocol v1's
  // defaults are used).
  std::function<std::unique_ptr<FrameAssembler>(std::string_view backend)> frame_assembler;
};

}  // namespace exodaq::drivers
