#include "exodaq/core/message_encoder.hpp"

#include <stdexcept>
#include <vector>

#include "exodaq/messages/raw_sample.hpp"

namespace exodaq::core {

MessageEncoder::MessageEncoder(const std::array<std::string, kJointCount>& joint_names,
                               std::int64_t run_id, bool publish_raw)
    : publish_raw_(publish_raw) {
  for (int i = 0; i < kJointCount; ++i) joint_.name[i] = joint_names[static_cast<std::size_t>(i)];
  joint_.run_id = palm_.run_id = raw_.run_id = run_id;
}

void MessageEncoder::warm_up() const {
  std::vector<std::uint8_t> scratch(kMaxMessageBytes);
  const int cap = static_cast<int>(scratch.size());
  if (joint_.encode(scratch.data(), 0, cap) < 0 || palm_.encode(scratch.data(), 0, cap) < 0 ||
      raw_.encode(scratch.data(), 0, cap) < 0) {
    throw std::runtime_error("message larger than a publisher slot");
  }
}

void MessageEncoder::publish(const CycleResult& r, const drivers::EncoderSample& sample,
                             Publisher& publisher) noexcept {
  joint_.utime = palm_.utime = raw_.utime = r.utime_us;
  joint_.mono_ns = palm_.mono_ns = raw_.mono_ns = r.mono_ns;
  joint_.seq = palm_.seq = raw_.seq = r.seq;
  palm_.valid = r.valid;
  palm_.invalid_reason = static_cast<std::int32_t>(r.invalid_reason);
  for (int k = 0; k < 3; ++k) {
    palm_.position[k] = r.pose.palm_position[k];
    palm_.elbow[k] = r.pose.elbow_position[k];
  }
  for (int k = 0; k < 4; ++k) palm_.orientation[k] = r.pose.palm_quaternion_wxyz[k];
  palm_.shoulder_manipulability = r.pose.shoulder_manipulability_normalised;
  palm_.shoulder_manipulability_raw = r.pose.shoulder_manipulability;
  palm_.near_singular = r.pose.near_singular;
  publish_encoded(publisher, msg::Kind::kPalmPose, palm_, r.utime_us);

  for (int i = 0; i < kJointCount; ++i) {
    const JointReading& j = r.joints[static_cast<std::size_t>(i)];
    joint_.position[i] = j.position_rad;
    joint_.velocity[i] = j.velocity_rad_s;
    joint_.raw_count[i] = j.count;
    joint_.homed[i] = j.homed;
    joint_.flags[i] = static_cast<std::int32_t>(j.flags);
  }
  joint_.sample_flags = static_cast<std::int32_t>(r.sample_flags);
  publish_encoded(publisher, msg::Kind::kJointState, joint_, r.utime_us);

  if (publish_raw_) {
    msg::to_encoder_raw(sample, raw_);
    publish_encoded(publisher, msg::Kind::kEncoderRaw, raw_, r.utime_us);
  }
  publisher.notify();
}

}  // namespace exodaq::core
