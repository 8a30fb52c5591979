#include "exodaq/drivers/sim_options.hpp"

namespace exodaq::drivers {

sim::SimOptions sim_options_from(const SourceOptions& options, const SourceContext& ctx) {
  sim::SimOptions o;
  o.seed = options.sim.seed;
  o.period_ns = ctx.period_ns;
  o.jitter_ns = static_cast<std::int64_t>(options.sim.jitter_us * 1000.0);
  o.loss_percent = options.sim.loss_percent;
  o.faults = options.sim.faults;
  // The simulated rig is the configured one: its encoders sit on the
  // configured channels with the configured direction and gearing, and each
  // index at the calibration's delta_theta0, so a homed joint reads the truth.
  for (std::size_t j = 0; j < ctx.joints.size(); ++j) {
    const SourceJointContext& c = ctx.joints[j];
    auto& e = o.encoders[j];
    e.channel = c.channel;
    e.direction = c.direction;
    e.counts_per_rev = ctx.counts_per_rev;
    e.gear_ratio = c.gear_ratio;
    e.index_angle_rad = c.index_angle_rad;
    e.power_up_count = options.sim.powerup_count;
    o.motion.home_rad[j] = c.home_rad;
    o.motion.lower_limit_rad[j] = c.lower_rad;
    o.motion.upper_limit_rad[j] = c.upper_rad;
  }
  return o;
}

}  // namespace exodaq::drivers
