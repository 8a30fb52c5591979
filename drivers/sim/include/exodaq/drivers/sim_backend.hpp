#pragma once
// The `sim` backend: the simulated rig as the configuration describes it.
// Shared by the backend and the board-simulator process (tools/board-sim), so
// both put the same frames on their bus for the same config: encoders on the
// configured channels with the configured direction and gearing, each index
// at the calibration's delta_theta0, powering up at the model's home posture.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "exodaq/drivers/backend.hpp"
#include "exodaq/drivers/sim_rig.hpp"

namespace exodaq::drivers {

namespace sim {
struct SimTaskFile;  // sim_task.hpp
}  // namespace sim

// source.sim
struct SimSourceSettings final : BackendSettings {
  std::uint64_t seed = 1;                // motion and fault randomness; same seed, same stream
  double loss_percent = 0.0;             // samples dropped at random (deterministic for a seed)
  double jitter_us = 0.0;                // sample-instant jitter (uniform, +/-)
  std::uint16_t powerup_count = 0x1234;  // counter value at power-up on every channel
  std::vector<sim::SimFault> faults;     // scripted faults (sim_rig.hpp)
  // source.sim.board_clock: {free_running, drift_ppm, phase} (phase in periods, [0, 1))
  bool free_running = false;
  double drift_ppm = 0.0;
  double phase = 0.0;
  std::string motion = "curves";                 // "curves" (hand-made) or "task" (the task file)
  std::string task_path;                         // source.sim.task, relative to the config
  std::shared_ptr<const sim::SimTaskFile> task;  // parsed when task_path is given
  std::string describe() const override;
};

const Backend& sim_backend();

sim::SimOptions sim_options_from(const SimSourceSettings& settings, const SourceContext& context);
// The config's sim section (defaults when it has none).
sim::SimOptions sim_options_from(const SourceOptions& options, const SourceContext& context);

// One scripted fault from its YAML mapping (source.sim.faults[i], or
// exodaq-board-sim --fault). Throws exodaq::ConfigError.
sim::SimFault parse_sim_fault(exodaq::MapReader& m);

}  // namespace exodaq::drivers
