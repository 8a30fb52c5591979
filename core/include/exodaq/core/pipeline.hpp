#pragma once
// One cycle's data path after the source: counts -> joint angles (per-joint
// trackers) -> palm pose and shoulder manipulability -> validity. No I/O, no
// allocation after construction; runs on the loop thread.
#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "exodaq/core/clock.hpp"
#include "exodaq/core/joint_tracker.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/kinematics/chain.hpp"
#include "exodaq/kinematics/rig_kinematics.hpp"

namespace exodaq::core {

// palm_pose_t's INVALID_* bits.
namespace invalid_reason {
inline constexpr std::uint32_t kUnhomed = wire::palm_pose::INVALID_UNHOMED;
inline constexpr std::uint32_t kJointFault = wire::palm_pose::INVALID_JOINT_FAULT;
inline constexpr std::uint32_t kSample = wire::palm_pose::INVALID_SAMPLE;
inline constexpr std::uint32_t kSource = wire::palm_pose::INVALID_SOURCE;
inline constexpr std::uint32_t kClock = wire::palm_pose::INVALID_CLOCK;
}  // namespace invalid_reason

// The configuration and calibration files in effect, as status_t carries
// them: paths at most kMaxPathBytes (a longer one keeps its end after
// "..."), content hashes of 64 hex digits, provenance at most
// kMaxProvenanceBytes. make_pipeline_config() cuts them.
struct ConfigFiles {
  static constexpr std::size_t kMaxPathBytes = 112;
  static constexpr std::size_t kMaxHashBytes = 64;
  static constexpr std::size_t kMaxProvenanceBytes = 80;
  std::string config_path;
  std::string config_sha256;
  std::string calibration_path;
  std::string calibration_sha256;
  std::string calibration_provenance;
  // A reload left restart-only settings of config_path unapplied: no file
  // describes the configuration in effect, and config_sha256 is empty.
  bool restart_pending = false;
};

struct PipelineConfig {
  std::array<JointTrackerConfig, kJointCount> joints;
  kinematics::Chain chain;  // with the calibration's DH deviations and palm offset applied
  kinematics::RigKinematicsConfig rig;
  // Set by a reload (Acquisition::stage_reload): the loop's new clock policy,
  // handed over with the rest of the configuration.
  std::optional<ClockPolicy> clock;
  // The files it came from, for status_t (cut to its field limits).
  ConfigFiles files;
  // Set by a reload that changes how counts become angles or angles the palm
  // pose (settings::starts_new_segment()): the first sample the loop
  // publishes with it carries SAMPLE_NEW_SEGMENT.
  bool new_segment = false;
};

// Everything one cycle publishes.
struct CycleResult {
  std::int64_t seq = 0;
  std::int64_t mono_ns = 0;
  std::int64_t utime_us = 0;
  std::uint32_t sample_flags = 0;  // drivers::sample_flag bits (incl. clock and late bits)
  std::array<JointReading, kJointCount> joints{};
  std::array<JointEvent, kJointCount> events{};
  kinematics::RigPose pose;
  bool valid = false;
  std::uint32_t invalid_reason = 0;
};

// Sample flags that make the cycle's palm pose invalid.
inline constexpr std::uint32_t kInvalidatingSampleFlags =
    drivers::sample_flag::kMissing | drivers::sample_flag::kPartial;
inline constexpr std::uint32_t kInvalidatingSourceFlags =
    drivers::sample_flag::kBoardError | drivers::sample_flag::kBusError;

class Pipeline {
 public:
  // `config` must outlive the pipeline (or the next use()).
  explicit Pipeline(const PipelineConfig& config);

  // Switches to another configuration at a cycle boundary (SIGHUP reload):
  // keeps counts and homing, copies no strings, allocates nothing.
  void use(const PipelineConfig& config) noexcept;

  // Processes one sample. `clock_invalid`: the clock policy marks this sample
  // unusable (step being absorbed, or unsynchronised under require_sync: hold).
  void process(const drivers::EncoderSample& sample, std::uint32_t extra_sample_flags,
               bool clock_invalid, CycleResult& out) noexcept;

  // Replay of a recording that starts mid-run: each tracker continues the
  // live run's count and homing (JointTracker::resume).
  void resume(const drivers::JointResumeSet& joints) noexcept;

  const JointTracker& joint(int i) const noexcept { return trackers_[static_cast<std::size_t>(i)]; }
  const PipelineConfig& config() const noexcept { return *config_; }

 private:
  const PipelineConfig* config_;
  std::array<JointTracker, kJointCount> trackers_;
  kinematics::JointVector q_;
};

}  // namespace exodaq::core
