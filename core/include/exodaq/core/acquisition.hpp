#pragma once
// The acquisition loop: a dedicated thread that wakes on absolute
// CLOCK_MONOTONIC deadlines, reads the encoder source, runs the pipeline,
// encodes the cycle's messages into pre-allocated slots and, at the status
// rate, assembles status_t. After start() the cycle allocates nothing, blocks
// on nothing and logs nothing: events go through a ring to the main thread.
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "exodaq/core/clock.hpp"
#include "exodaq/core/health.hpp"
#include "exodaq/core/pipeline.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/encoder_raw_t.hpp"
#include "exodaq/joint_state_t.hpp"
#include "exodaq/palm_pose_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::core {

struct AcquisitionConfig {
  std::string rig = "rig";
  std::int64_t period_ns = 1'000'000;
  int cpu = -1;              // pin the loop thread to this CPU (-1: no pinning)
  int priority = 0;          // SCHED_FIFO priority for the loop thread (0: SCHED_OTHER)
  bool lock_memory = false;  // mlockall(MCL_CURRENT | MCL_FUTURE)
  std::int64_t fault_after_ms = 500;
  int status_every_cycles = 100;      // 10 Hz at 1 kHz
  int clean_windows_to_recover = 10;  // degraded -> running after this many clean windows
  bool publish_raw = true;
  // Replay: a fixed run_id so the same input gives byte-identical output
  // (exodaq replay passes the recording's). 0: random per start, as live.
  std::int64_t run_id = 0;
  ClockPolicy clock;
  std::array<std::string, kJointCount> joint_names;
  // Benchmarks: record every cycle's wake-up lateness (ns) into memory
  // reserved at start, for up to this many cycles (0: off). See timing_record().
  std::int64_t record_lateness_cycles = 0;
};

// Something the loop wants logged; drained and logged by another thread.
struct LogEvent {
  enum class Kind : std::uint8_t {
    kJoint,
    kOverrun,
    kClockStep,
    kStateChange,
    kReloadApplied,
    kEndOfStream,
  };
  Kind kind = Kind::kJoint;
  std::int64_t seq = 0;
  int joint = -1;
  JointEvent joint_event = JointEvent::kNone;
  double value = 0.0;      // angle, drift, lateness... by kind
  std::int64_t count = 0;  // counter value after the event
  ServiceState state = ServiceState::kStarting;
};

class Acquisition {
 public:
  Acquisition(AcquisitionConfig config, std::unique_ptr<PipelineConfig> pipeline_config,
              std::unique_ptr<drivers::EncoderSource> source, std::unique_ptr<MessageSink> sink,
              const std::string& channel_prefix, std::unique_ptr<ClockSource> clock);
  ~Acquisition();
  Acquisition(const Acquisition&) = delete;
  Acquisition& operator=(const Acquisition&) = delete;

  // Starts the source, the publisher, the clock monitor and the loop thread.
  // Throws if the source cannot start.
  void start();
  // Stops the loop after its current cycle, publishes a final status with
  // state `stopping`, drains the publisher. Idempotent.
  void stop();
  // For replay: blocks until the source ends (or stop()).
  void wait_until_finished();

  // Main thread, at any time: the loop switches to `config` at its next cycle
  // boundary. The previous configuration is freed off the loop thread.
  void stage_reload(std::unique_ptr<PipelineConfig> config, const ClockPolicy& clock);

  bool pop_event(LogEvent& out) noexcept;

  // Observers (any thread).
  // Acquire: once cycles() > 0, what the loop thread wrote before its first
  // cycle (realtime_report()) is visible to the caller.
  std::int64_t cycles() const noexcept { return cycles_.load(std::memory_order_acquire); }
  ServiceState state() const noexcept { return state_.load(std::memory_order_relaxed); }
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }
  std::int64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }
  std::int64_t run_id() const noexcept { return run_id_; }
  const ClockShared& clock_shared() const noexcept { return clock_shared_; }
  Publisher& publisher() noexcept { return publisher_; }
  const drivers::EncoderSource& source() const noexcept { return *source_; }
  // The source's counters as of the last status window, safe to read from any
  // thread (the source itself is the loop thread's alone).
  struct SourceCounters {
    std::int64_t missing_samples = 0;
    std::int64_t seq_gaps = 0;
    std::int64_t bus_errors = 0;
    drivers::BusState bus_state = drivers::BusState::kUnknown;
  };
  SourceCounters source_counters() const noexcept {
    SourceCounters c;
    c.missing_samples = published_missing_.load(std::memory_order_relaxed);
    c.seq_gaps = published_seq_gaps_.load(std::memory_order_relaxed);
    c.bus_errors = published_bus_errors_.load(std::memory_order_relaxed);
    c.bus_state = published_bus_state_.load(std::memory_order_relaxed);
    return c;
  }
  // Whether the loop thread got the scheduling/locking it asked for.
  const std::string& realtime_report() const noexcept { return realtime_report_; }

  // The recorded wake-up lateness (ns) of each cycle, valid after stop().
  const std::vector<std::int32_t>& lateness_record() const noexcept { return lateness_record_; }

  // Test hook: while set, the loop thread sleeps instead of cycling (a stalled
  // loop, so tests can see the watchdog stop).
  void set_stall_for_test(bool stall) noexcept { stall_.store(stall); }

  // One cycle, exposed so tests can drive the loop deterministically without
  // the thread. `deadline_ns`/`wake_ns` on CLOCK_MONOTONIC.
  bool run_cycle(std::int64_t deadline_ns, std::int64_t wake_ns) noexcept;
  // Prepares everything run_cycle() needs without starting threads (tests).
  void prepare_for_manual_cycles();

 private:
  void thread_main() noexcept;
  void setup_realtime();
  void push_event(const LogEvent& e) noexcept;
  void encode_cycle(const drivers::EncoderSample& sample) noexcept;
  void finish_window(std::int64_t now_mono) noexcept;
  template <typename Msg>
  void encode(msg::Kind channel, const Msg& msg, std::int64_t utime_us) noexcept;

  AcquisitionConfig config_;
  // Replay: timestamps come from the recording, the loop is paced by it
  // (speed > 0: that many times real time) or runs flat out (speed <= 0).
  bool replay_ = false;
  double replay_speed_ = 1.0;
  std::unique_ptr<PipelineConfig> active_config_;
  std::atomic<PipelineConfig*> staged_config_{nullptr};
  std::atomic<PipelineConfig*> retired_config_{nullptr};
  std::unique_ptr<drivers::EncoderSource> source_;
  std::unique_ptr<ClockSource> clock_;
  ClockShared clock_shared_;
  std::unique_ptr<ClockMonitor> clock_monitor_;
  Publisher publisher_;
  Pipeline pipeline_;
  WallTimeMapper time_mapper_;
  std::int64_t run_id_ = 0;

  // loop-thread state
  drivers::EncoderSample sample_;
  CycleResult result_;
  exodaq::joint_state_t joint_msg_{};
  exodaq::palm_pose_t palm_msg_{};
  exodaq::encoder_raw_t raw_msg_{};
  exodaq::status_t status_msg_{};
  std::int64_t seq_ = 0;
  std::int64_t last_wake_ns_ = 0;
  std::int64_t last_sample_mono_ns_ = 0;
  std::int64_t last_emitted_mono_ns_ = 0;
  std::int64_t last_present_mono_ns_ = 0;
  std::int64_t last_present_seq_ = 0;
  bool previous_overran_ = false;
  TimingWindow period_window_;
  TimingWindow lateness_window_;
  TimingWindow work_window_;
  WindowFacts facts_;
  int clean_windows_ = 0;
  std::int64_t window_overruns_start_ = 0;
  std::int64_t first_recorded_mono_ns_ = -1;
  std::int64_t replay_start_mono_ns_ = 0;

  // event ring (loop -> main thread)
  static constexpr std::size_t kEventCapacity = 1024;
  std::array<LogEvent, kEventCapacity> events_{};
  alignas(64) std::atomic<std::uint64_t> event_head_{0};
  alignas(64) std::atomic<std::uint64_t> event_tail_{0};
  std::atomic<std::int64_t> events_dropped_{0};

  std::atomic<std::int64_t> cycles_{0};
  std::atomic<std::int64_t> overruns_{0};
  std::atomic<std::int64_t> published_missing_{0};
  std::atomic<std::int64_t> published_seq_gaps_{0};
  std::atomic<std::int64_t> published_bus_errors_{0};
  std::atomic<drivers::BusState> published_bus_state_{drivers::BusState::kUnknown};
  std::atomic<ServiceState> state_{ServiceState::kStarting};
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> finished_{false};
  std::atomic<bool> stall_{false};
  std::thread thread_;
  bool started_ = false;
  bool stopped_ = false;
  std::string realtime_report_;
  std::vector<std::int32_t> lateness_record_;
};

}  // namespace exodaq::core
