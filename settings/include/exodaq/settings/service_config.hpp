#pragma once
// The service configuration file (config/sim.yaml, /etc/exodaq/exodaqd.yaml):
// rig, loop, source, encoders, model file, calibration file, kinematics, LCM,
// clock and logging. Strict: every error is "file:line: what" and unknown keys
// are errors. Model and calibration paths are relative to the config file.
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "exodaq/drivers/backend.hpp"
#include "exodaq/drivers/source_options.hpp"
#include "exodaq/settings/calibration_file.hpp"
#include "exodaq/settings/model_file.hpp"
#include "exodaq/settings/service_settings.hpp"

namespace exodaq::settings {

struct ServiceConfig {
  std::string file;
  // sha256_hex() of the bytes each file was parsed from (content_hash.hpp).
  std::string config_sha256;
  std::string model_sha256;
  std::string calibration_sha256;
  EXODAQ_TOP_SETTINGS(EXODAQ_SETTING_FIELD)
  LoopSettings loop;
  drivers::SourceOptions source;
  EncoderSettings encoders;
  std::string model_path;
  std::string calibration_path;
  KinematicModel model;
  Calibration calibration;
  EXODAQ_KINEMATICS_SETTINGS(EXODAQ_SETTING_FIELD)
  LcmSettings lcm;
  ClockPolicy clock;
  LoggingSettings logging;
};

ServiceConfig load_service_config(const std::string& path);
ServiceConfig load_service_config_text(const std::string& text, const std::string& name);

// What the source backends need to know about the rig (encoders, model,
// calibration): the sim puts each index at the calibration's delta_theta0.
drivers::SourceContext make_source_context(const ServiceConfig& config);

// The loop period of a configuration, ns.
std::int64_t period_ns(const ServiceConfig& config);

// A readable dump (YAML) of the effective configuration (--print-config):
// every setting once, under the key settings_of() (setting_classes.hpp) gives
// it, in the declarations' order (setting_list.hpp).
std::string to_yaml(const ServiceConfig& config);

// The calibration's provenance in one line: "created_by, date, rms before ->
// after mm, N samples" (the parts the file has).
std::string provenance_text(const CalibrationProvenance& p);

}  // namespace exodaq::settings
