#pragma once
// One joint's path from encoder counts to a calibrated angle: unwrapping at the
// source's stated modulus, homing (seed 000 eq. 4: theta = delta_theta0 +
// theta_R) on an index or, for an absolute encoder, on its zero at the first
// sample, velocity
// estimate, and the per-joint faults (stale, glitch, out of range, lost
// counts). Integer counts end to end; angles are derived, never accumulated.
// Allocation-free after construction; runs on the loop thread.
#include <array>
#include <cstdint>

#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/settings/service_settings.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::core {

// joint_state_t's JOINT_* bits (defined in lcmtypes/exodaq/joint_state_t.lcm).
namespace joint_flag {
namespace w = wire::joint_state;
inline constexpr std::uint32_t kUnhomed = w::JOINT_UNHOMED;
inline constexpr std::uint32_t kStale = w::JOINT_STALE;
inline constexpr std::uint32_t kGlitch = w::JOINT_GLITCH;
inline constexpr std::uint32_t kOutOfRange = w::JOINT_OUT_OF_RANGE;
inline constexpr std::uint32_t kLostCounts = w::JOINT_LOST_COUNTS;
inline constexpr std::uint32_t kHomingRejected = w::JOINT_HOMING_REJECTED;
inline constexpr std::uint32_t kHeld = w::JOINT_HELD;
inline constexpr std::uint32_t kBoardError = w::JOINT_BOARD_ERROR;
// Flags that make a joint's angle untrustworthy (kHeld alone does not: the
// sample-level kMissing flag covers a held cycle).
inline constexpr std::uint32_t kFaults =
    kUnhomed | kStale | kGlitch | kOutOfRange | kLostCounts | kHomingRejected | kBoardError;
}  // namespace joint_flag

// status_t's HOMING_* codes.
enum class HomingState : std::int8_t {
  kUnhomed = wire::status::HOMING_UNHOMED,
  kHomed = wire::status::HOMING_HOMED,
  kRejected = wire::status::HOMING_REJECTED,
};

// No strings here: configs are copied on the loop thread at a reload.
struct JointTrackerConfig {
  int channel = 0;                      // the source's channel (0..kJointCount-1)
  int direction = 1;                    // +1 or -1: encoder count sign relative to the joint angle
  std::int64_t counts_per_rev = 10000;  // encoder counts per encoder revolution (CPR x 4)
  double gear_ratio = 1.0;              // encoder revolutions per joint revolution
  double offset_rad = 0.0;              // delta_theta0: the joint angle at the reference index
  double home_rad = 0.0;                // home posture angle: the reference before homing
  double lower_rad = -3.14159;          // mechanical limits (model)
  double upper_rad = 3.14159;
  double limit_margin_rad = 0.0349;  // out-of-range margin beyond the limits
  double max_speed_rad_s = 5.0;      // glitch bound (already including its margin)
  // The source's sample period (0: unknown). The glitch bound's interval is the
  // longer of the receive instants' and the source cycles' (docs/operations.md, GLITCH).
  std::int64_t board_period_ns = 0;
  std::int64_t index_tolerance_counts = 2;
  std::int64_t stale_ns = 20'000'000;
  std::int64_t fault_hold_ns = 100'000'000;  // how long kLostCounts stays after a correction
  int velocity_window = 21;  // samples in the velocity fit (odd, <= kMaxVelocityWindow)
};

using settings::kJointCount;
using settings::kMaxVelocityWindow;

// The velocity fit's exact sums (a GCC/Clang extension, hence __extension__).
__extension__ typedef __int128 FitSum;

struct JointCounters {
  std::int64_t glitches = 0;
  std::int64_t lost_count_events = 0;
  std::int64_t stale_events = 0;
  std::int64_t out_of_range_events = 0;
  std::int64_t homings = 0;
  std::int64_t rejected_homings = 0;
  std::int64_t last_index_drift_counts = 0;
};

// What the tracker reports after each cycle.
struct JointReading {
  double position_rad = 0.0;
  double velocity_rad_s = 0.0;
  std::int64_t count = 0;  // unwrapped encoder count since power-up
  bool homed = false;
  std::uint32_t flags = joint_flag::kUnhomed;
  HomingState homing = HomingState::kUnhomed;
};

// The tracker's homing reference (published as homing_t, docs/replay.md).
struct HomingReference {
  bool counted = false;  // a count has arrived since start
  std::int64_t count = 0;
  std::int64_t powerup_count = 0;
  HomingState homing = HomingState::kUnhomed;
  std::int64_t index_count = 0;  // unwrapped count at the accepted index
  std::int64_t index_turns = 0;  // k: the index angle is offset + k 2pi/gear
  double index_angle_rad = 0.0;  // under the current calibration

  // The same reference (the count and angle aside).
  bool same_reference(const HomingReference& o) const noexcept {
    return counted == o.counted && homing == o.homing && index_count == o.index_count &&
           index_turns == o.index_turns && powerup_count == o.powerup_count;
  }
};

// One joint's channel of one cycle's sample (encoder_sample.hpp says what
// each field means).
struct JointInput {
  std::int64_t mono_ns = 0;
  std::int64_t seq = -1;  // the source's cycle sequence, -1: none
  std::int64_t seq_modulus = 0;
  bool fresh = false;  // a new position arrived for this joint this cycle
  std::int64_t position = 0;
  std::int64_t modulus = 0;
  bool index_valid = false;  // index_position holds the position latched at an index edge
  std::int64_t index_position = 0;
  bool absolute = false;  // homed on the encoder's zero at the first position, no index
  bool board_error = false;
};

// Channel `channel` of `sample`.
JointInput joint_input(const drivers::EncoderSample& sample, int channel) noexcept;

// One event a tracker wants logged (off the loop thread).
enum class JointEvent : std::uint8_t {
  kNone,
  kHomed,
  kHomingRejected,
  kLostCounts,
  kGlitch,
  kStale,
  kOutOfRange,
  kUnwrapAmbiguous,
};

class JointTracker {
 public:
  JointTracker() = default;
  explicit JointTracker(const JointTrackerConfig& config);

  // Applies new calibration / limits at a cycle boundary, keeping the counts
  // and the homing (the reference index count stays; its angle is re-derived).
  void reconfigure(const JointTrackerConfig& config) noexcept;

  // One cycle. Returns the most important event of the cycle (kNone usually).
  JointEvent update(const JointInput& in) noexcept;

  // Continues a live run from a recording's first sample (replay): the first
  // count is unwrapped next to r.count, the homing reference is r's. Before
  // the first update() only.
  void resume(const drivers::JointResume& r) noexcept;
  HomingReference homing_reference() const noexcept;

  const JointReading& reading() const noexcept { return reading_; }
  const JointCounters& counters() const noexcept { return counters_; }
  const JointTrackerConfig& config() const noexcept { return config_; }

 private:
  void take_count(const JointInput& in, JointEvent& event) noexcept;
  // How long the joint had to move since its last fresh count.
  std::int64_t interval_since_fresh(const JointInput& in) const noexcept;
  void home_on_index(std::int64_t index_count, JointEvent& event) noexcept;
  // An absolute encoder: its zero (count 0) is the reference, taken at the
  // first count; the turn is the one that puts the joint nearest its home.
  void home_absolute(JointEvent& event) noexcept;
  // Homed: the index verifies the count, or re-homes when counts were lost.
  void check_index(std::int64_t t_ns, std::int64_t index_count, JointEvent& event) noexcept;
  void update_reading(std::int64_t t_ns, bool fresh, bool board_error, JointEvent& event) noexcept;
  double angle_of(std::int64_t count) const noexcept;
  void update_velocity(std::int64_t t_ns) noexcept;

  JointTrackerConfig config_;
  double rad_per_count_ = 0.0;

  bool have_count_ = false;
  std::int64_t count_ = 0;
  std::int64_t last_fresh_ns_ = 0;
  std::int64_t last_fresh_seq_ = -1;
  std::int64_t powerup_count_ = 0;
  bool resume_pending_ = false;  // resume(): the first count continues resume_count_
  std::int64_t resume_count_ = 0;

  HomingState homing_ = HomingState::kUnhomed;
  std::int64_t ref_count_ = 0;  // unwrapped count at the reference index
  std::int64_t ref_turns_ = 0;  // which index crossing (k in delta_theta0 + k 2pi/gear)
  bool suspect_ = false;        // a glitch or ambiguous unwrap: wrong until the next index
  bool stale_ = false;
  bool out_of_range_ = false;
  std::int64_t lost_counts_until_ns_ = 0;

  // velocity: the least-squares line through the last `velocity_window` fresh
  // samples, from exact integer sums updated as samples enter and leave
  // (times in ns and counts relative to an anchor sample).
  void add_to_fit(std::int64_t t_ns, std::int64_t count, int sign) noexcept;
  void rebuild_fit(std::int64_t anchor_t_ns, std::int64_t anchor_count) noexcept;
  std::array<std::int64_t, kMaxVelocityWindow> vel_t_{};
  std::array<std::int64_t, kMaxVelocityWindow> vel_c_{};
  int vel_n_ = 0;
  int vel_head_ = 0;  // the slot the next sample goes to: the oldest one once the window is full
  std::int64_t fit_t0_ = 0;  // the anchor
  std::int64_t fit_c0_ = 0;
  std::int64_t sum_t_ = 0;
  std::int64_t sum_c_ = 0;
  FitSum sum_tt_ = 0;
  FitSum sum_tc_ = 0;

  JointReading reading_;
  JointCounters counters_;
};

}  // namespace exodaq::core
