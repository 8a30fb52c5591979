#pragma once
// The simulated rig: a deterministic joint-space motion of the macaque arm
// (SimMotion), six incremental encoders watching it (SimEncoders), and the
// encoder interface board that turns each sampling cycle into protocol v1 CAN
// frames (SimBoard). SimRig ties them together per cycle; the `sim` backend
// (sim_source.hpp) and the board-simulator process both drive a SimRig, so
// both put exactly the same frames on their bus for the same options.
//
// Joint numbering is 0-based here (joint 0 = the paper's joint 1).
// Sources: seed 000 (Table 3 joint limits, Table 5 task ROM, home posture,
// eq. 4 θ = Δθ⁰ + θᴿ) and seed 001 (Table III joint speed bounds).
#include <array>
#include <cstdint>
#include <memory>
#include <numbers>
#include <span>
#include <string_view>
#include <vector>

#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/encoder_sample.hpp"

namespace exodaq::drivers::sim {

inline constexpr int kJoints = kChannelCount;
using Vec6 = std::array<double, kJoints>;

constexpr double deg(double d) noexcept {
  return d * std::numbers::pi / 180.0;
}

// Seed 000, Sec. 3.1: θ = [π/4, −π/2, π/2, 0, 0, 0].
inline constexpr Vec6 kHomeRad{deg(45), deg(-90), deg(90), 0.0, 0.0, 0.0};
// Seed 000, Table 3: mechanical joint limits.
inline constexpr Vec6 kLowerLimitRad{deg(-50.5), deg(-228.3), deg(-98.1),
                                     deg(-80),   deg(-88.7),  deg(-80)};
inline constexpr Vec6 kUpperLimitRad{deg(140.5), deg(48.3), deg(98.1), deg(80), deg(8.1), deg(80)};
// Seed 000, Table 5: range of motion measured in the reach-grasp-feed task.
inline constexpr Vec6 kTaskRomRad{deg(30.9), deg(5.1), deg(75.3), deg(39.9), deg(84.7), deg(54.9)};
// Speed bound per joint, seed 001 Table III read by anatomy: its rows are its
// own arm's shoulder ab/adduction (0.64 rad/s), flexion/extension (1.06),
// internal/external rotation (1.80) and elbow (5.38), i.e. this rig's joints
// 2, 3, 4 and 5. Joint 1 (azimuthal ab/adduction, seed 000 Table 2) takes the
// ab/adduction row; joint 6 (pronation/supination, not in the table) 3.0 rad/s,
// its whole 55 deg task ROM in ~0.3 s. The configs' max_speed_rad_s hold them.
inline constexpr Vec6 kSpeedBoundRadS{0.64, 0.64, 1.06, 1.80, 5.38, 3.0};
// The speed the hand-made curves may reach: 80 % of the bound.
inline constexpr Vec6 kMotionSpeedCapRadS{0.8 * 0.64, 0.8 * 0.64, 0.8 * 1.06,
                                          0.8 * 1.80, 0.8 * 5.38, 0.8 * 3.0};

// Default joint angle of each encoder's index (Δθ⁰ of seed 000 eq. 4): a few
// degrees from home, on the side that leaves room before the Table 3 limit.
inline constexpr Vec6 kDefaultIndexAngleRad{deg(45 + 4), deg(-90 - 3), deg(90 - 5),
                                            deg(6),      deg(-5),      deg(-4)};

// ---------------------------------------------------------------------------
// Motion
// ---------------------------------------------------------------------------

struct SimTask;      // sim_task.hpp
struct SimTaskPlan;  // sim_task.hpp

struct SimMotionOptions {
  std::uint64_t seed = 1;  // same seed → same trajectory
  Vec6 home_rad = kHomeRad;
  Vec6 lower_limit_rad = kLowerLimitRad;  // nothing ever leaves these
  Vec6 upper_limit_rad = kUpperLimitRad;
  // Window each joint's task motion stays in; width = Table 5 ROM by default,
  // placed around home for a reach in front of the animal. Must hold home.
  Vec6 task_lower_rad{deg(30.0), deg(-92.5), deg(19.7), deg(-20.0), deg(-84.7), deg(-27.45)};
  Vec6 task_upper_rad{deg(60.9), deg(-87.4), deg(95.0), deg(19.9), deg(0.0), deg(27.45)};
  Vec6 speed_cap_rad_s = kMotionSpeedCapRadS;  // peak speed of any segment
  double min_segment_s = 0.4;                  // shortest move
  double duration_slack = 0.3;                 // moves last up to 30 % longer than needed (random)
  double start_hold_s = 0.5;                   // at home before anything moves
  bool homing = true;                          // sweep every joint through its index first
  double homing_speed_rad_s = 0.3;             // peak speed of the homing sweeps
  double homing_overshoot_rad = deg(3.0);      // how far past the index a sweep goes
  double grasp_hold_s = 0.3;                   // pauses (each + up to 50 % random)
  double feed_hold_s = 0.5;
  double home_hold_s = 0.4;
  int round_trips = 16;  // distinct reach→grasp→feed→return trips; then they repeat
  // A task to run after homing instead of the hand-made round trips (the
  // fields above from task_lower_rad on are then unused). Null: the curves.
  std::shared_ptr<const SimTask> task;
};

struct JointTruth {
  Vec6 position{};      // rad
  Vec6 velocity{};      // rad/s
  Vec6 acceleration{};  // rad/s²
};

// The rig's joint motion: start hold, homing sweeps, then round trips
// repeated with period cycle_s() (docs/simulator.md, "Motion"). Rest-to-rest
// quintic segments; truth(t) is analytic for any t (t < 0: home at rest).
class SimMotion {
 public:
  struct Segment {
    double t0 = 0.0;        // start time, s
    double duration = 0.0;  // s
    Vec6 from{};
    Vec6 to{};      // equal to `from` for a hold
    int move = -1;  // >= 0: the task plan's joint trajectory `move`; else a quintic from -> to
  };

  // index_angle_rad: each joint's index angle; index_period_rad: 2π/gear, the
  // joint-space spacing of its index pulses. Throws std::invalid_argument
  // when the options are inconsistent (home or a waypoint window outside the
  // limits, an index sweep that would leave them, non-positive speeds).
  explicit SimMotion(const SimMotionOptions& options = {},
                     const Vec6& index_angle_rad = kDefaultIndexAngleRad,
                     const Vec6& index_period_rad = {2 * std::numbers::pi, 2 * std::numbers::pi,
                                                     2 * std::numbers::pi, 2 * std::numbers::pi,
                                                     2 * std::numbers::pi, 2 * std::numbers::pi});

  JointTruth truth(double t_s) const noexcept;
  Vec6 position(double t_s) const noexcept { return truth(t_s).position; }

  double homing_end_s() const noexcept { return homing_end_s_; }  // round trips start here
  double cycle_s() const noexcept { return cycle_s_; }            // round-trip pattern period
  // The homing sweep targets and the index angle each sweep crosses.
  const Vec6& homing_index_rad() const noexcept { return homing_index_; }
  const std::vector<Segment>& homing_segments() const noexcept { return homing_; }
  const std::vector<Segment>& trip_segments() const noexcept { return trips_; }  // t0 from 0
  const SimMotionOptions& options() const noexcept { return options_; }
  const SimTaskPlan* task_plan() const noexcept { return plan_.get(); }  // null: curves

 private:
  JointTruth eval(const Segment& s, double t) const noexcept;
  static const Segment* find(const std::vector<Segment>& segs, double t) noexcept;

  SimMotionOptions options_;
  std::shared_ptr<const SimTaskPlan> plan_;
  Vec6 homing_index_{};
  std::vector<Segment> homing_;  // absolute times
  std::vector<Segment> trips_;   // relative to homing_end_s_
  double homing_end_s_ = 0.0;
  double cycle_s_ = 0.0;
};

// ---------------------------------------------------------------------------
// Encoders
// ---------------------------------------------------------------------------

struct SimEncoderParams {
  int channel = 0;                       // board channel 0..5 (a permutation over joints)
  int direction = 1;                     // +1 or −1: count sign vs joint angle
  std::int64_t counts_per_rev = 10'000;  // per encoder revolution (2500 CPR × 4)
  double gear_ratio = 1.0;               // encoder revolutions per joint revolution (> 0)
  double index_angle_rad = 0.0;          // joint angle of an index pulse (Δθ⁰, seed 000 eq. 4)
  std::int64_t power_up_count = 0;       // counter value at t = 0, i.e. at home
};

// Six incremental encoders: counts by the floor of the encoder position,
// index latches where it crosses a whole revolution from the index angle
// (docs/simulator.md, "Encoders and board"). Only the last crossing of a
// cycle is latched.
class SimEncoders {
 public:
  SimEncoders(const std::array<SimEncoderParams, kJoints>& params, const Vec6& initial_rad);

  double encoder_position(int joint, double theta_rad) const noexcept;  // q(θ)
  std::int64_t count_at(int joint, double theta_rad) const noexcept;    // count(θ)
  std::int64_t count_at_index(int joint, std::int64_t n) const noexcept;
  std::int64_t offset(int joint) const noexcept { return offset_[idx(joint)]; }

  // Samples all joints at new angles: updates counts and this cycle's latches.
  void update(const Vec6& theta_rad) noexcept;
  std::int64_t count(int joint) const noexcept { return count_[idx(joint)]; }
  bool latched(int joint) const noexcept { return latched_[idx(joint)]; }
  std::int64_t latched_count(int joint) const noexcept { return latched_count_[idx(joint)]; }
  const SimEncoderParams& params(int joint) const noexcept { return params_[idx(joint)]; }

 private:
  static std::size_t idx(int j) noexcept { return static_cast<std::size_t>(j); }
  std::int64_t whole_counts(int joint, double theta_rad) const noexcept;  // f(θ)

  std::array<SimEncoderParams, kJoints> params_;
  std::array<std::int64_t, kJoints> offset_{};
  std::array<std::int64_t, kJoints> f_{};
  std::array<std::int64_t, kJoints> count_{};
  std::array<bool, kJoints> latched_{};
  std::array<std::int64_t, kJoints> latched_count_{};
};

// ---------------------------------------------------------------------------
// Board
// ---------------------------------------------------------------------------

struct SimBoardOptions {
  can::ProtocolIds ids{};
  int heartbeat_every = 100;  // cycles between heartbeats (100 at 1 kHz = 10 Hz)
  std::uint8_t first_seq = 0;
  std::uint8_t state = static_cast<std::uint8_t>(can::BoardState::kFreeRun);
  std::uint8_t errors = 0;  // board_error bits the heartbeat reports
  std::uint8_t channel_quadrature_errors = 0;
};

// What the board's counters hold at one sampling instant, by board channel.
struct BoardCycle {
  std::array<std::int64_t, kChannelCount> count{};
  std::uint32_t index_latched = 0;  // bit c: channel c latched this cycle
  std::array<std::int64_t, kChannelCount> index_count{};
};

// Frame order per cycle k: INDEX frames of channels that latched (ascending
// channel), COUNTS_A, COUNTS_B, then HEARTBEAT when k % heartbeat_every == 0.
// seq = first_seq + k (mod 256). Stamps are left 0 for the caller.
class SimBoard {
 public:
  // INDEX frames, COUNTS_A, COUNTS_B, HEARTBEAT, and room for the frames a
  // scripted fault adds (a duplicate, two held back from the previous cycle,
  // an error frame).
  static constexpr int kMaxFramesPerCycle = kChannelCount + 7;
  using Frames = std::array<can::CanFrame, kMaxFramesPerCycle>;

  explicit SimBoard(const SimBoardOptions& options = {}) noexcept : options_(options) {}
  int make_cycle(std::int64_t k, const BoardCycle& cycle, Frames& out) const noexcept;
  SimBoardOptions& options() noexcept { return options_; }  // fault injection
  const SimBoardOptions& options() const noexcept { return options_; }

 private:
  SimBoardOptions options_;
};

// ---------------------------------------------------------------------------
// The whole rig, per sampling cycle
// ---------------------------------------------------------------------------

inline std::array<SimEncoderParams, kJoints> default_encoders() noexcept {
  std::array<SimEncoderParams, kJoints> e{};
  // Power-up counts are arbitrary; these put joints 1 and 3 a few counts from
  // the 16-bit wrap on the side their homing sweep moves to (1 up, 3 down),
  // so the wrap is exercised within the first seconds.
  constexpr std::array<std::int64_t, kJoints> power_up{65500, 32760, 10, 0, -5, 100000};
  for (int j = 0; j < kJoints; ++j) {
    const auto i = static_cast<std::size_t>(j);
    e[i].channel = j;
    e[i].index_angle_rad = kDefaultIndexAngleRad[i];
    e[i].power_up_count = power_up[i];
  }
  return e;
}

// A scripted fault of the simulated board, its encoders or the bus, active
// from start_s for duration_s of simulated time (duration_s <= 0: until the
// end). What each kind does, its parameters and what the daemon makes of it:
// docs/simulator.md ("Fault kinds"), the one place the vocabulary is described.
struct SimFault {
  enum class Kind : std::uint8_t {
    kCountOffset,  // glitch:      the counter jumps by `counts` and keeps it
    kCountRamp,    // lost_counts: the counter gains `counts`, one count per cycle
    kExcursion,    // excursion:   the joint really moves `counts` away and back (triangle)
    kStuck,        // stuck:       the counter freezes; heartbeat reports `error_bits`
    kSilence,      // silence:     no frame reaches the bus
    kDrop,         // drop:        `percent` of cycles lose all their frames
    kPartial,      // partial:     COUNTS_B is lost
    kDuplicate,    // duplicate:   COUNTS_A is sent twice
    kBoardError,   // board_error: the heartbeat reports `error_bits`
    kReorder,      // reorder:     every other cycle's COUNTS_A/B follow the next cycle's
    kBadSeq,       // bad_seq:     COUNTS_A/B carry seq + 128
    kWrongDlc,     // wrong_dlc:   COUNTS_B is sent with DLC 6
    kDelay,        // delay:       the cycle's frames reach the bus `delay_us` late
    kErrorFrame,   // error_frame: the controller reports a protocol (bit) error frame
    kStall,        // stall:       the host stalls: the read reaching start_s blocks duration_s
  };
  Kind kind = Kind::kCountOffset;
  double start_s = 0.0;
  double duration_s = 0.0;
  int joint = 0;                // 0-based
  std::int64_t counts = 0;      // glitch, lost_counts, excursion
  double percent = 0.0;         // drop
  std::uint8_t error_bits = 0;  // board_error, stuck
  int every = 1;                // duplicate, bad_seq, wrong_dlc, error_frame: every Nth cycle
  double delay_us = 0.0;        // delay
};

// Which SimFault fields a kind reads (SimFaultName::params).
namespace fault_param {
inline constexpr std::uint32_t kJoint = 1U << 0;
inline constexpr std::uint32_t kCounts = 1U << 1;
inline constexpr std::uint32_t kPercent = 1U << 2;
inline constexpr std::uint32_t kErrorBits = 1U << 3;
inline constexpr std::uint32_t kEvery = 1U << 4;
inline constexpr std::uint32_t kDelay = 1U << 5;
}  // namespace fault_param

// The fault vocabulary, one table for every simulator: the name each kind has
// in a config (source.sim.faults[].kind) and for exodaq-board-sim --fault,
// and the parameters it takes.
struct SimFaultName {
  SimFault::Kind kind;
  std::string_view name;
  std::uint32_t params = 0;  // fault_param bits
};
std::span<const SimFaultName> sim_fault_names() noexcept;
std::string_view sim_fault_name(SimFault::Kind kind) noexcept;
const SimFaultName* find_sim_fault(std::string_view name) noexcept;  // nullptr: unknown

// Bits of SimCycle::applied: one per fault kind (its enum value), and the
// random loss of SimOptions::loss_percent / partial_percent.
constexpr std::uint32_t fault_bit(SimFault::Kind kind) noexcept {
  return 1U << static_cast<unsigned>(kind);
}
inline constexpr std::uint32_t kRandomLossBit = 1U << 30;
inline constexpr std::uint32_t kRandomPartialBit = 1U << 31;

// The board's sampling clock (docs/simulator.md, "Board clock").
struct SimBoardClock {
  // false: the board samples at the reader's deadlines, as a sync slave whose
  // SYNC leaves on time (the default). true: it samples on its own clock
  // whatever the reader does, and a reader that is late finds the cycles it
  // missed queued, as in a socket.
  bool free_running = false;
  double drift_ppm = 0.0;     // own period = period · (1 + drift_ppm · 1e-6); |drift| ≤ 1000
  std::int64_t phase_ns = 0;  // first sample this long after the start, [0, period)
};

struct SimOptions {
  std::uint64_t seed = 1;              // seeds motion, jitter, loss; same seed → same stream
  std::int64_t period_ns = 1'000'000;  // sampling period (1 kHz)
  // Sample k is taken at t_k = k · period_ns + jitter_k, jitter_k uniform in
  // [−jitter_ns, +jitter_ns] from (seed, k); clamped below period_ns / 2.
  // A free-running board: t_k = phase + k · period_ns · (1 + drift) + jitter_k.
  std::int64_t jitter_ns = 0;
  SimBoardClock board_clock{};
  double loss_percent = 0.0;     // cycles whose frames are all lost on the bus (from (seed, k))
  double partial_percent = 0.0;  // cycles whose COUNTS_B is lost (only A arrives)
  std::array<SimEncoderParams, kJoints> encoders = default_encoders();
  SimMotionOptions motion{};  // motion.seed is replaced by `seed`
  SimBoardOptions board{};
  // Sample stamps: mono_ns = start_mono_ns + t_k, wall_ns = mono_ns + wall_offset_ns.
  // 0 = taken from CLOCK_MONOTONIC / CLOCK_REALTIME − CLOCK_MONOTONIC at start().
  std::int64_t start_mono_ns = 0;
  std::int64_t wall_offset_ns = 0;
  std::vector<SimFault> faults;  // scripted faults (sim_rig.hpp SimFault)
};

// What one simulated cycle was, before the faults touched the frames.
struct SimCycle {
  std::int64_t k = -1;
  double t_s = 0.0;                                 // sampling instant
  Vec6 position{};                                  // true joint angles (motion + excursions)
  std::array<std::int64_t, kChannelCount> count{};  // true counts by board channel
  std::uint32_t applied = 0;  // fault_bit() of each fault that changed this cycle
};

// The rig, one sampling cycle per step(). Throws std::invalid_argument on
// inconsistent options (see SimMotion and SimEncoders; loss/partial outside
// [0, 100], invalid protocol IDs, a fault with a bad joint, window, percent,
// `every` < 1 or a delay of 4 periods or more).
class SimRig {
 public:
  static constexpr int kMaxDelayPeriods = 4;

  explicit SimRig(const SimOptions& options);

  // Simulates cycle k (k = 0, 1, 2, … in order): samples the motion at t_k,
  // updates the encoders and writes the frames the board puts on the bus for
  // it to `out`, stamped with the instant each reaches the bus on the given
  // time base (t_k, plus any scripted delay). Returns how many (0: lost).
  int step(std::int64_t k, SimBoard::Frames& out, std::int64_t start_mono_ns,
           std::int64_t wall_offset_ns) noexcept;
  // The same, sampled at t_ns (from the time base's start) instead of t_k: a
  // board that latches its counts when a SYNC reaches it (exodaq-board-sim).
  int step_at(std::int64_t k, std::int64_t t_ns, SimBoard::Frames& out, std::int64_t start_mono_ns,
              std::int64_t wall_offset_ns) noexcept;
  const SimCycle& last_cycle() const noexcept { return cycle_; }
  // How many cycles had each bit of SimCycle::applied set so far (by bit number).
  const std::array<std::int64_t, 32>& applied_counts() const noexcept { return applied_; }

  std::int64_t sample_offset_ns(std::int64_t k) const noexcept;  // t_k in ns
  double sample_time_s(std::int64_t k) const noexcept {
    return static_cast<double>(sample_offset_ns(k)) * 1e-9;
  }
  bool cycle_lost(std::int64_t k) const noexcept;
  bool cycle_partial(std::int64_t k) const noexcept;
  // The counts the scripted faults add to joint j's counter at time t.
  std::int64_t fault_count_offset(int j, double t_s, std::int64_t k) const noexcept;
  // The real joint motion scripted excursions add to joint j at time t (rad).
  double fault_excursion_rad(int j, double t_s) const noexcept;

  const SimMotion& motion() const noexcept { return motion_; }
  const SimEncoders& encoders() const noexcept { return encoders_; }
  SimBoard& board() noexcept { return board_; }
  const SimOptions& options() const noexcept { return options_; }

 private:
  struct CycleFaults;  // what the active faults do to one cycle (sim_rig.cpp)

  CycleFaults active_faults(std::int64_t k, double t_s) const noexcept;
  BoardCycle sample_board(double t_s) noexcept;
  void apply_counter_faults(std::int64_t k, double t_s, CycleFaults& f, BoardCycle& c) noexcept;
  int apply_bus_faults(std::int64_t k, CycleFaults& f, SimBoard::Frames& out, int n) noexcept;
  int reorder(bool hold, SimBoard::Frames& out, int n) noexcept;
  std::int64_t start_cycle(const SimFault& f) const noexcept;

  SimOptions options_;
  SimMotion motion_;
  SimEncoders encoders_;
  SimBoard board_;
  SimCycle cycle_{};
  std::array<std::int64_t, 32> applied_{};
  std::array<std::int64_t, kJoints> stuck_count_{};
  std::array<bool, kJoints> stuck_{};
  std::uint8_t base_errors_ = 0;
  // kReorder: count frames held back to be sent after the next cycle's.
  std::array<can::CanFrame, 2> held_{};
  int held_n_ = 0;
};

// Deterministic hash → uniform [0, 1) (splitmix64), for the sim's randomness.
double unit_random(std::uint64_t seed, std::uint64_t stream, std::uint64_t k) noexcept;

}  // namespace exodaq::drivers::sim
