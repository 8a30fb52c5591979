#pragma once
// Runs the whole pipeline in-process over the simulated rig, cycle by cycle
// on the simulated clock (no threads, no sleeping), and keeps every message
// decoded, with the simulator's truth at hand.
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "exodaq/core/acquisition.hpp"
#include "exodaq/drivers/sim_source.hpp"
#include "exodaq/drivers/source_factory.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/settings/service_config.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::test {

struct Cycle {
  exodaq::joint_state_t joint;
  exodaq::palm_pose_t palm;
};

struct ScenarioResult {
  std::vector<Cycle> cycles;  // index = seq
  std::vector<exodaq::status_t> statuses;
  const drivers::SimSource* sim = nullptr;
  std::unique_ptr<core::Acquisition> acquisition;  // keeps the sim alive
  settings::ServiceConfig config;
  double rad_per_count(int j) const {
    return 2.0 * M_PI /
           (static_cast<double>(config.encoders.counts_per_rev()) *
            config.encoders.joints[static_cast<std::size_t>(j)].gear_ratio);
  }
  // First seq at which `pred(cycle)` holds, or -1.
  template <typename Pred>
  std::int64_t first(Pred pred, std::int64_t from = 0) const {
    for (std::size_t i = static_cast<std::size_t>(from); i < cycles.size(); ++i) {
      if (pred(cycles[i])) return static_cast<std::int64_t>(i);
    }
    return -1;
  }
  const exodaq::status_t& last_status() const { return statuses.back(); }
};

settings::ServiceConfig sim_config();
// `rig` configures the simulated rig (encoders, index angles from its
// calibration, faults); `daemon` the pipeline. Usually the same.
ScenarioResult run_scenario(const settings::ServiceConfig& daemon, double seconds,
                            const settings::ServiceConfig* rig = nullptr);

// Seconds into the run when the simulated operator has homed every joint.
inline constexpr double kHomedBy = 11.0;

}  // namespace exodaq::test
