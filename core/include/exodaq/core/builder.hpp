#pragma once
// The acquisition's parts from a loaded service configuration.
#include <memory>

#include "exodaq/config/service_config.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/pipeline.hpp"

namespace exodaq::core {

// The pipeline's configuration: trackers from encoders + model limits +
// calibration offsets, the chain with the calibration applied.
std::unique_ptr<PipelineConfig> make_pipeline_config(const config::ServiceConfig& config);

// The loop's settings (rate, scheduling, status rate, joint names, clock
// policy, replay pacing).
AcquisitionConfig make_acquisition_config(const config::ServiceConfig& config);

}  // namespace exodaq::core
