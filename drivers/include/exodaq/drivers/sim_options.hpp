#pragma once
// The simulated rig as the configuration describes it. Shared by the `sim`
// backend (source_factory.cpp) and the board-simulator process
// (tools/board-sim), so both put the same frames on their bus for the same
// config: encoders on the configured channels with the configured direction
// and gearing, each index at the calibration's delta_theta0, powering up at
// the model's home posture.
#include "exodaq/drivers/sim_rig.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::drivers {

sim::SimOptions sim_options_from(const SourceOptions& options, const SourceContext& context);

}  // namespace exodaq::drivers
