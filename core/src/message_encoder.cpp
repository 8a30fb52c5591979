#include "exodaq/core/message_encoder.hpp"

#include <stdexcept>
#include <vector>

#include "exodaq/messages/raw_sample.hpp"

namespace exodaq::core {

MessageEncoder::MessageEncoder(const std::array<std::string, kJointCount>& joint_names,
                               std::int64_t run_id, bool publish_raw, std::int64_t period_ns)
    : publish_raw_(publish_raw),
      homing_every_(period_ns > 0 && period_ns < 1'000'000'000 ? 1'000'000'000 / period_ns : 1) {
  for (int i = 0; i < kJointCount; ++i) joint_.name[i] = joint_names[static_cast<std::size_t>(i)];
  joint_.run_id = palm_.run_id = raw_.run_id = homing_.run_id = run_id;
}

void MessageEncoder::warm_up() const {
  std::vector<std::uint8_t> scratch(kMaxMessageBytes);
  const int cap = static_cast<int>(scratch.size());
  if (joint_.encode(scratch.data(), 0, cap) < 0 || palm_.encode(scratch.data(), 0, cap) < 0 ||
      raw_.encode(scratch.data(), 0, cap) < 0 || homing_.encode(scratch.data(), 0, cap) < 0) {
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

void MessageEncoder::publish_homing(const CycleResult& r, const Pipeline& pipeline,
                                    Publisher& publisher) noexcept {
  if (!publish_raw_) return;
  std::int32_t changed = 0;
  for (int i = 0; i < kJointCount; ++i) {
    const HomingReference h = pipeline.joint(i).homing_reference();
    auto& last = last_reference_[static_cast<std::size_t>(i)];
    if (!h.same_reference(last)) changed |= 1 << i;
    last = h;
    homing_.counted[i] = h.counted;
    homing_.count[i] = h.count;
    homing_.powerup_count[i] = h.powerup_count;
    homing_.homing[i] = static_cast<std::int8_t>(h.homing);
    homing_.index_count[i] = h.index_count;
    homing_.index_turns[i] = h.index_turns;
    homing_.index_angle[i] = h.index_angle_rad;
  }
  if (changed == 0 && r.seq % homing_every_ != 0) return;
  homing_.utime = r.utime_us;
  homing_.mono_ns = r.mono_ns;
  homing_.seq = r.seq;
  homing_.changed = changed;
  publish_encoded(publisher, msg::Kind::kHoming, homing_, r.utime_us);
}

}  // namespace exodaq::core
