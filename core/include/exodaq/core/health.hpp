#pragma once
// Loop health: per-cycle timing over a status window, the window's facts and
// the service state machine. Loop thread; allocation-free.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "exodaq/core/joint_tracker.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/wire_constants.hpp"

namespace exodaq::core {

// status_t's STATE_* codes.
enum class ServiceState : std::int8_t {
  kStarting = wire::status::STATE_STARTING,
  kHoming = wire::status::STATE_HOMING,
  kRunning = wire::status::STATE_RUNNING,
  kDegraded = wire::status::STATE_DEGRADED,
  kFault = wire::status::STATE_FAULT,
  kStopping = wire::status::STATE_STOPPING,
};
const char* state_name(ServiceState s) noexcept;

struct Percentiles {
  double p50_us = 0.0;
  double p99_us = 0.0;
  double max_us = 0.0;
};

// Up to kCapacity samples per window; older ones are dropped if a window runs long.
class TimingWindow {
 public:
  static constexpr int kCapacity = 8192;
  void add(std::int64_t value_ns) noexcept {
    if (n_ < kCapacity) values_[static_cast<std::size_t>(n_++)] = value_ns;
  }
  int size() const noexcept { return n_; }
  Percentiles percentiles() noexcept;  // reorders the values
  void clear() noexcept { n_ = 0; }

 private:
  std::array<std::int64_t, kCapacity> values_{};
  int n_ = 0;
};

// Aggregated facts of one status window, from which the state follows.
struct WindowFacts {
  int cycles = 0;
  int samples_present = 0;
  int valid_poses = 0;
  std::uint32_t sample_flags_or = 0;
  std::array<std::uint32_t, kJointCount> joint_flags_or{};
  bool all_homed = false;   // at the end of the window
  bool clock_hold = false;  // require_sync: hold and unsynchronised
  drivers::BusState bus_state = drivers::BusState::kUnknown;
  std::int64_t overruns = 0;
  std::int64_t publish_failures = 0;  // messages the publish path refused or dropped
};

// Why the state machine chose a degraded or fault state (docs/operations.md,
// "Service state"); kNone for the others (homing: the homed count says it).
// In the order they are told: a skipped deadline also makes a board seq gap
// (SEQ_GAP) or a stale joint, so the overrun, the cause, comes first.
enum class StateReason : std::uint8_t {
  kNone,
  kNoSamples,        // fault: no sample for `value` ms (`threshold`: fault_after_ms)
  kBusDown,          // fault: bus off, interface down or gone (`value`: the BusState)
  kForeignRun,       // another run on these channels (any status heard from it)
  kOverruns,         // `value` deadlines skipped in the window (`threshold`: more than this)
  kJointFault,       // fault `flags` of `joint` in the window (`value`: joints with faults)
  kSampleFlags,      // samples flagged `flags` in the window
  kPublishFailures,  // `value` messages not published in the window (`threshold`: as above)
  kClockHold,        // clock unsynchronised under clock.require_sync: hold
  kRecovering,       // held degraded: `value` clean windows in a row of the `threshold` needed
};
// "OVERRUNS", "JOINT_FAULT", ...: the reason's one name (journal EXODAQ_REASON).
std::string_view reason_name(StateReason r) noexcept;

// The reason a state was chosen, and what crossed which threshold.
struct StateCause {
  StateReason reason = StateReason::kNone;
  std::int64_t value = 0;
  std::int64_t threshold = 0;
  std::uint32_t flags = 0;
  int joint = -1;
  std::uint32_t also = 0;                // other reasons of the window: bit 1 << StateReason
  StateReason was = StateReason::kNone;  // kRecovering: the reason it recovers from
  std::int64_t window_ns = 0;            // the window's length (the status assembler's)
};

// The cause for people, without allocating ("3 overruns in the last 0.1 s
// window (threshold: more than 0)"); `joint_name`: the name of `c.joint`.
// Writes at most `cap` bytes with the NUL; returns the length written.
std::size_t describe_cause(const StateCause& c, std::string_view joint_name, char* out,
                           std::size_t cap) noexcept;

struct Verdict {
  ServiceState state = ServiceState::kStarting;
  StateCause cause;
};

// One step of the service state machine (docs/operations.md, "Service state")
// at the end of a window: starting, homing, running, degraded or fault from
// the window's facts, with the reason; stopping stays.
Verdict judge(ServiceState current, const WindowFacts& facts, std::int64_t ms_since_last_sample,
              std::int64_t fault_after_ms) noexcept;
inline ServiceState next_state(ServiceState current, const WindowFacts& facts,
                               std::int64_t ms_since_last_sample,
                               std::int64_t fault_after_ms) noexcept {
  return judge(current, facts, ms_since_last_sample, fault_after_ms).state;
}

// next_state() with hysteresis: back from degraded to running only after
// `clean_windows_to_recover` clean windows in a row. With
// `hold_fault_while_samples` (a recording's time), a window that had samples
// never enters fault.
class ServiceStateMachine {
 public:
  struct Settings {
    std::int64_t fault_after_ms = 500;
    int clean_windows_to_recover = 10;
    bool hold_fault_while_samples = false;
  };
  explicit ServiceStateMachine(const Settings& settings) : settings_(settings) {}

  ServiceState next(ServiceState current, const WindowFacts& facts,
                    std::int64_t ms_since_last_sample) noexcept;
  // Why next() chose its last state.
  const StateCause& cause() const noexcept { return cause_; }

 private:
  Settings settings_;
  int clean_windows_ = 0;
  StateCause cause_;
  StateReason last_reason_ = StateReason::kNone;  // of the last degraded window
};

}  // namespace exodaq::core
