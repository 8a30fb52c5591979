#pragma once
// The service configuration file (config/sim.yaml, /etc/exodaq/exodaqd.yaml):
// rig, loop, source, encoders, model file, calibration file, kinematics, LCM,
// clock and logging. Strict: every error is "file:line: what" and unknown keys
// are errors. Model and calibration paths are relative to the config file.
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "exodaq/config/calibration_file.hpp"
#include "exodaq/config/model_file.hpp"
#include "exodaq/core/acquisition.hpp"
#include "exodaq/core/clock.hpp"
#include "exodaq/core/pipeline.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::core {

struct LoopSettings {
  double rate_hz = 1000.0;
  int cpu = -1;
  int priority = 0;
  bool lock_memory = false;
  std::int64_t fault_after_ms = 500;
  double status_rate_hz = 10.0;
};

struct EncoderJointSettings {
  int channel = 0;
  int direction = 1;
  double gear_ratio = 1.0;
  double max_speed_rad_s = 0.0;  // before the margin
};

struct EncoderSettings {
  int cycles_per_rev = 2500;  // CPR of the encoder disc
  int decoding = 4;           // quadrature decoding factor
  double stale_ms = 20.0;
  std::int64_t index_tolerance_counts = 2;
  double limit_margin_deg = 2.0;
  double speed_margin = 1.5;  // glitch bound = max_speed x margin
  int velocity_window = 21;
  double fault_hold_ms = 100.0;
  std::array<EncoderJointSettings, kJointCount> joints{};
  std::int64_t counts_per_rev() const noexcept {
    return static_cast<std::int64_t>(cycles_per_rev) * decoding;
  }
};

struct LcmSettings {
  std::string url = "udpm://239.255.76.67:7667?ttl=0";
  std::string prefix;
  bool publish_raw = true;
};

struct LoggingSettings {
  std::string level = "info";
  std::string sink = "auto";  // auto | stderr | journal
};

struct ServiceConfig {
  std::string file;
  std::string rig = "rig";
  LoopSettings loop;
  drivers::SourceOptions source;
  EncoderSettings encoders;
  std::string model_path;
  std::string calibration_path;
  config::KinematicModel model;
  config::Calibration calibration;
  double singularity_threshold = 0.05;
  LcmSettings lcm;
  ClockPolicy clock;
  LoggingSettings logging;
};

ServiceConfig load_service_config(const std::string& path);
ServiceConfig load_service_config_text(const std::string& text, const std::string& name);

// The pipeline's configuration from a loaded service config: trackers from
// encoders + model limits + calibration offsets, chain with the calibration.
std::unique_ptr<PipelineConfig> make_pipeline_config(const ServiceConfig& config);

// What the source backends need to know about the rig (encoders, model,
// calibration): the sim puts each index at the calibration's delta_theta0.
drivers::SourceContext make_source_context(const ServiceConfig& config);

// The loop's settings from a loaded service config (rate, scheduling, status
// rate, joint names, clock policy, replay pacing).
AcquisitionConfig make_acquisition_config(const ServiceConfig& config);

// A readable dump (YAML) of the effective configuration (--print-config).
std::string to_yaml(const ServiceConfig& config);

}  // namespace exodaq::core
