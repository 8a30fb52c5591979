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
#include "exodaq/drivers/backend.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::config {

// The service publishes exactly six joints (the arrays of joint_state_t).
inline constexpr int kJointCount = 6;
// The longest velocity fit a joint tracker holds (encoders.velocity_window).
inline constexpr int kMaxVelocityWindow = 64;

enum class RequireSync : std::uint8_t {
  kIgnore,  // clock health reported only
  kMark,    // samples carry SAMPLE_CLOCK_UNSYNC while unsynchronised
  kHold,    // as kMark, and the service stays degraded (palm invalid) until synchronised
};

// How sample time treats the wall clock (docs/time.md).
struct ClockPolicy {
  RequireSync require_sync = RequireSync::kMark;
  double max_est_error_us = 5'000.0;           // synchronised needs esterror at most this
  double max_max_error_us = 100'000.0;         // ... and maxerror at most this
  std::int64_t step_threshold_ns = 2'000'000;  // an offset change larger than this is a step
  double slew_ppm = 1'000.0;                   // ordinary tracking rate (NTP slews at most 500 ppm)
  double step_slew_ppm = 100'000.0;            // how fast a step is absorbed: 10 % (1 s in 10 s)
};

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
  // sha256_hex() of the bytes each file was parsed from (content_hash.hpp).
  std::string config_sha256;
  std::string model_sha256;
  std::string calibration_sha256;
  std::string rig = "rig";
  LoopSettings loop;
  drivers::SourceOptions source;
  EncoderSettings encoders;
  std::string model_path;
  std::string calibration_path;
  KinematicModel model;
  Calibration calibration;
  double singularity_threshold = 0.05;
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
// every setting once, under the key settings_of() (setting_classes.hpp) gives it.
std::string to_yaml(const ServiceConfig& config);

// The calibration's provenance in one line: "created_by, date, rms before ->
// after mm, N samples" (the parts the file has).
std::string provenance_text(const CalibrationProvenance& p);

}  // namespace exodaq::config
