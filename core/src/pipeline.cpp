#include "exodaq/core/pipeline.hpp"

namespace exodaq::core {

Pipeline::Pipeline(const PipelineConfig& config) : config_(&config) {
  for (int i = 0; i < kJointCount; ++i) {
    trackers_[static_cast<std::size_t>(i)] =
        JointTracker(config.joints[static_cast<std::size_t>(i)]);
  }
  q_.resize(kJointCount);
}

void Pipeline::use(const PipelineConfig& config) noexcept {
  config_ = &config;
  for (int i = 0; i < kJointCount; ++i) {
    trackers_[static_cast<std::size_t>(i)].reconfigure(config.joints[static_cast<std::size_t>(i)]);
  }
}

void Pipeline::resume(const drivers::JointResumeSet& joints) noexcept {
  for (int i = 0; i < kJointCount; ++i) {
    trackers_[static_cast<std::size_t>(i)].resume(joints[static_cast<std::size_t>(i)]);
  }
}

void Pipeline::process(const drivers::EncoderSample& sample, std::uint32_t extra_sample_flags,
                       bool clock_invalid, CycleResult& out) noexcept {
  out.sample_flags = sample.flags | extra_sample_flags;
  if (!sample.present) out.sample_flags |= drivers::sample_flag::kMissing;
  std::uint32_t any_fault = 0;
  bool all_homed = true;
  for (int i = 0; i < kJointCount; ++i) {
    auto& tracker = trackers_[static_cast<std::size_t>(i)];
    out.events[static_cast<std::size_t>(i)] =
        tracker.update(joint_input(sample, tracker.config().channel));
    const JointReading& r = tracker.reading();
    out.joints[static_cast<std::size_t>(i)] = r;
    q_[i] = r.position_rad;
    all_homed = all_homed && r.homed;
    any_fault |= r.flags & (joint_flag::kFaults & ~joint_flag::kUnhomed);
  }
  kinematics::evaluate_rig(config_->chain, config_->rig, q_, out.pose);

  std::uint32_t reason = 0;
  if (!all_homed) reason |= invalid_reason::kUnhomed;
  if (any_fault != 0) reason |= invalid_reason::kJointFault;
  if ((out.sample_flags & kInvalidatingSampleFlags) != 0) reason |= invalid_reason::kSample;
  if ((out.sample_flags & kInvalidatingSourceFlags) != 0) reason |= invalid_reason::kSource;
  if (clock_invalid) reason |= invalid_reason::kClock;
  out.invalid_reason = reason;
  out.valid = reason == 0;
}

}  // namespace exodaq::core
