#include "exodaq/core/message_encoder.hpp"

#include <stdexcept>
#include <vector>

#include "exodaq/messages/raw_sample.hpp"

namespace exodaq::core {

MessageEncoder::MessageEncoder(const std::array<std::string, kJointCount>& joint_names,
                               std::int64_t run_id, bool publish_raw, std::int64_t period_ns)
    : publish_raw_(publish_raw),
      homing_every_(period_ns > 0 && period_ns < 1'000'000'000 ? 1'000'000'000 / period_ns : 1) {
  auto& joint = std::get<joint_state_t>(messages_);
  for (int i = 0; i < kJointCount; ++i) joint.name[i] = joint_names[static_cast<std::size_t>(i)];
  std::apply([run_id](auto&... m) { ((m.run_id = run_id), ...); }, messages_);
}

void MessageEncoder::warm_up() const {
  std::vector<std::uint8_t> scratch(kMaxMessageBytes);
  const int cap = static_cast<int>(scratch.size());
  const bool fit =
      std::apply([&](const auto&... m) { return ((m.encode(scratch.data(), 0, cap) >= 0) && ...); },
                 messages_);
  if (!fit) throw std::runtime_error("message larger than a publisher slot");
}

void MessageEncoder::publish(const CycleResult& r, const drivers::EncoderSample& sample,
                             Publisher& publisher) noexcept {
  auto& joint = std::get<joint_state_t>(messages_);
  auto& palm = std::get<palm_pose_t>(messages_);
  auto& raw = std::get<encoder_raw_t>(messages_);
  joint.utime = palm.utime = raw.utime = r.utime_us;
  joint.mono_ns = palm.mono_ns = raw.mono_ns = r.mono_ns;
  joint.seq = palm.seq = raw.seq = r.seq;
  palm.valid = r.valid;
  palm.invalid_reason = static_cast<std::int32_t>(r.invalid_reason);
  for (int k = 0; k < 3; ++k) {
    palm.position[k] = r.pose.palm_position[k];
    palm.elbow[k] = r.pose.elbow_position[k];
  }
  for (int k = 0; k < 4; ++k) palm.orientation[k] = r.pose.palm_quaternion_wxyz[k];
  palm.shoulder_manipulability = r.pose.shoulder_manipulability_normalised;
  palm.shoulder_manipulability_raw = r.pose.shoulder_manipulability;
  palm.near_singular = r.pose.near_singular;
  publish_encoded(publisher, palm, r.utime_us);

  for (int i = 0; i < kJointCount; ++i) {
    const JointReading& j = r.joints[static_cast<std::size_t>(i)];
    joint.position[i] = j.position_rad;
    joint.velocity[i] = j.velocity_rad_s;
    joint.raw_count[i] = j.count;
    joint.homed[i] = j.homed;
    joint.flags[i] = static_cast<std::int32_t>(j.flags);
  }
  joint.sample_flags = static_cast<std::int32_t>(r.sample_flags);
  publish_encoded(publisher, joint, r.utime_us);

  if (publish_raw_) {
    messages::to_encoder_raw(sample, raw);
    publish_encoded(publisher, raw, r.utime_us);
  }
  publisher.notify();
}

void MessageEncoder::publish_homing(const CycleResult& r, const Pipeline& pipeline,
                                    Publisher& publisher) noexcept {
  if (!publish_raw_) return;
  auto& homing = std::get<homing_t>(messages_);
  std::int32_t changed = 0;
  for (int i = 0; i < kJointCount; ++i) {
    const HomingReference h = pipeline.joint(i).homing_reference();
    auto& last = last_reference_[static_cast<std::size_t>(i)];
    if (!h.same_reference(last)) changed |= 1 << i;
    last = h;
    homing.counted[i] = h.counted;
    homing.count[i] = h.count;
    homing.powerup_count[i] = h.powerup_count;
    homing.homing[i] = static_cast<std::int8_t>(h.homing);
    homing.index_count[i] = h.index_count;
    homing.index_turns[i] = h.index_turns;
    homing.index_angle[i] = h.index_angle_rad;
  }
  if (changed == 0 && r.seq % homing_every_ != 0) return;
  homing.utime = r.utime_us;
  homing.mono_ns = r.mono_ns;
  homing.seq = r.seq;
  homing.changed = changed;
  publish_encoded(publisher, homing, r.utime_us);
}

}  // namespace exodaq::core
