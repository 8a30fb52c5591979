#pragma once
// The acquisition from a loaded service configuration: the one place that
// wires source, sink, pipeline and loop, for the daemon, replay, benchmarks
// and tests alike.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/pipeline.hpp"
#include "exodaq/settings/service_config.hpp"

namespace exodaq::core {

// What differs from the daemon's wiring; the defaults are the daemon's.
struct AcquisitionOptions {
  std::unique_ptr<drivers::EncoderSource> source;  // null: the configured backend
  std::unique_ptr<MessageSink> sink;               // null: LCM on lcm.url
  std::optional<std::string> channel_prefix;       // unset: lcm.prefix
  std::unique_ptr<ClockSource> clock;              // null: the system clocks
  std::unique_ptr<LoopClock> loop_clock;           // null: CLOCK_MONOTONIC (tests: simulated)
  std::int64_t run_id = 0;                         // 0: random per start
  bool realtime = true;  // false: no CPU pinning, SCHED_FIFO or mlockall (tools, tests)
  std::int64_t record_lateness_cycles = 0;  // AcquisitionConfig::record_lateness_cycles
};

// Throws what the source factory or the sink throws (unknown backend,
// missing file, LCM URL refused).
std::unique_ptr<Acquisition> build_acquisition(const settings::ServiceConfig& config,
                                               AcquisitionOptions options = {});

// The pipeline's configuration: trackers from encoders + model limits +
// calibration offsets, the chain with the calibration applied.
std::unique_ptr<PipelineConfig> make_pipeline_config(const settings::ServiceConfig& config);

// The loop's settings (rate, scheduling, status rate, joint names, clock policy).
AcquisitionConfig make_acquisition_config(const settings::ServiceConfig& config);

}  // namespace exodaq::core
