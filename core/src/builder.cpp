#include "exodaq/core/builder.hpp"

#include <algorithm>
#include <cmath>

namespace exodaq::core {

std::unique_ptr<PipelineConfig> make_pipeline_config(const config::ServiceConfig& c) {
  auto p = std::make_unique<PipelineConfig>();
  p->chain = config::apply_calibration(c.model.chain, c.calibration);
  p->rig = c.model.rig;
  const auto& joints = c.model.chain.joints();
  for (int i = 0; i < kJointCount; ++i) {
    const auto& e = c.encoders.joints[static_cast<std::size_t>(i)];
    JointTrackerConfig& t = p->joints[static_cast<std::size_t>(i)];
    t.channel = e.channel;
    t.direction = e.direction;
    t.counts_per_rev = c.encoders.counts_per_rev();
    t.gear_ratio = e.gear_ratio;
    t.offset_rad = c.calibration.encoder_offset_rad[static_cast<std::size_t>(i)];
    t.home_rad = c.model.home_posture.size() > i ? c.model.home_posture[i] : 0.0;
    t.lower_rad = joints[static_cast<std::size_t>(i)].limits.lower;
    t.upper_rad = joints[static_cast<std::size_t>(i)].limits.upper;
    t.limit_margin_rad = c.encoders.limit_margin_deg * config::kDegToRad;
    t.max_speed_rad_s = e.max_speed_rad_s * c.encoders.speed_margin;
    t.index_tolerance_counts = c.encoders.index_tolerance_counts;
    t.stale_ns = static_cast<std::int64_t>(c.encoders.stale_ms * 1e6);
    t.fault_hold_ns = static_cast<std::int64_t>(c.encoders.fault_hold_ms * 1e6);
    t.velocity_window = c.encoders.velocity_window;
  }
  return p;
}

AcquisitionConfig make_acquisition_config(const config::ServiceConfig& c) {
  AcquisitionConfig a;
  a.rig = c.rig;
  a.period_ns = config::period_ns(c);
  a.cpu = c.loop.cpu;
  a.priority = c.loop.priority;
  a.lock_memory = c.loop.lock_memory;
  a.fault_after_ms = c.loop.fault_after_ms;
  a.status_every_cycles =
      std::max(1, static_cast<int>(std::lround(c.loop.rate_hz / c.loop.status_rate_hz)));
  a.publish_raw = c.lcm.publish_raw;
  a.clock = c.clock;
  const auto& joints = c.model.chain.joints();
  for (int i = 0; i < kJointCount; ++i) {
    a.joint_names[static_cast<std::size_t>(i)] = joints[static_cast<std::size_t>(i)].name;
  }
  return a;
}

}  // namespace exodaq::core
