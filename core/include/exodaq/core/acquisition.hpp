#pragma once
// The acquisition loop: a dedicated thread that, wake after wake, waits for
// its time base, reads the encoder source, runs the pipeline, publishes the
// cycle's messages and, at the status rate, the status. A source that holds
// more samples (a free-running board while the loop was late: backlog()) is
// read on in the same wake, up to max_samples_per_wake, each sample its own
// published cycle; one published more than a period after its sample instant
// is flagged LATE. After start() a wake allocates nothing, blocks on nothing
// and logs nothing: events go through a ring to the main thread. Built by
// build_acquisition() (builder.hpp). docs/architecture.md, "One cycle".
#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "exodaq/core/clock.hpp"
#include "exodaq/core/config_handover.hpp"
#include "exodaq/core/health.hpp"
#include "exodaq/core/loop_events.hpp"
#include "exodaq/core/message_encoder.hpp"
#include "exodaq/core/pipeline.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/core/status_assembler.hpp"
#include "exodaq/core/time_base.hpp"
#include "exodaq/drivers/encoder_source.hpp"

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
  // A fixed run_id, so the same input gives byte-identical output (replay
  // passes the recording's). 0: random per start, as live.
  std::int64_t run_id = 0;
  ClockPolicy clock;
  std::array<std::string, kJointCount> joint_names;
  // Benchmarks: record every cycle's wake-up lateness (ns) into memory
  // reserved at start, for up to this many cycles (0: off).
  std::int64_t record_lateness_cycles = 0;
  // Catch-up bound: samples published in one wake at most (each is three
  // messages in the publisher's ring of 2048); a longer backlog is carried to
  // the next wakes (counted in backlog_wakes()).
  int max_samples_per_wake = 64;
};

class Acquisition {
 public:
  // `clock`: null for the system clocks; `loop_clock`: null for CLOCK_MONOTONIC.
  Acquisition(AcquisitionConfig config, std::unique_ptr<PipelineConfig> pipeline_config,
              std::unique_ptr<drivers::EncoderSource> source, std::unique_ptr<MessageSink> sink,
              const std::string& channel_prefix, std::unique_ptr<ClockSource> clock,
              std::unique_ptr<LoopClock> loop_clock = nullptr);
  ~Acquisition();
  Acquisition(const Acquisition&) = delete;
  Acquisition& operator=(const Acquisition&) = delete;

  // Starts the source, the publisher, the clock monitor and the loop thread.
  // Throws if the source cannot start.
  void start();
  // Stops the loop after its current cycle, publishes a final status with
  // state `stopping`, drains the publisher. Idempotent.
  void stop();

  // Main thread, at any time: the loop switches to `config` and `clock` at its
  // next cycle boundary. The previous configuration is freed off the loop thread.
  void stage_reload(std::unique_ptr<PipelineConfig> config, const ClockPolicy& clock);

  // Any thread (the daemon's listener on the status channel): another run is
  // heard on our channels (0: no longer). From the next cycle every sample is
  // flagged FOREIGN_RUN, status_t.foreign_run_id names it and the state is
  // degraded. One atomic store; the loop only loads it.
  void set_foreign_run_id(std::int64_t run_id) noexcept {
    foreign_run_id_.store(run_id, std::memory_order_relaxed);
  }
  std::int64_t foreign_run_id() const noexcept {
    return foreign_run_id_.load(std::memory_order_relaxed);
  }
  // The seq of the last status this loop assembled (-1: none yet), stored
  // before the status is sent: a status carrying this run id and a later seq
  // is not this loop's (the daemon's listener, instance_guard.hpp).
  std::int64_t last_status_seq() const noexcept {
    return last_status_seq_.load(std::memory_order_acquire);
  }
  // Any thread: log lines the daemon's output lost (since start); the status
  // message says so. One atomic store; the loop loads it once per status.
  void set_log_lines_dropped(std::int64_t lines) noexcept {
    log_lines_dropped_.store(lines, std::memory_order_relaxed);
  }

  bool pop_event(LogEvent& out) noexcept { return events_.pop(out); }
  // Events lost because the ring was full.
  std::int64_t events_dropped() const noexcept { return events_.dropped(); }

  // Observers (any thread).
  // Acquire: once cycles() > 0, what the loop thread wrote before its first
  // cycle (realtime_report()) is visible to the caller.
  std::int64_t cycles() const noexcept { return cycles_.load(std::memory_order_acquire); }
  ServiceState state() const noexcept { return state_.load(std::memory_order_relaxed); }
  // As of the last status window: why the state is what it is, and the
  // joints homed (systemd's STATUS=).
  StateReason state_reason() const noexcept {
    return state_reason_.load(std::memory_order_relaxed);
  }
  int homed_joints() const noexcept { return homed_joints_.load(std::memory_order_relaxed); }
  bool finished() const noexcept { return finished_.load(std::memory_order_acquire); }
  std::int64_t overruns() const noexcept { return overruns_.load(std::memory_order_relaxed); }
  // Samples flagged LATE; samples published after the first of their wake
  // (caught up); wakes that left a backlog for the next (the catch-up bound).
  std::int64_t late_samples() const noexcept { return late_.load(std::memory_order_relaxed); }
  std::int64_t caught_up_samples() const noexcept {
    return caught_up_.load(std::memory_order_relaxed);
  }
  std::int64_t backlog_wakes() const noexcept {
    return backlog_wakes_.load(std::memory_order_relaxed);
  }
  std::int64_t run_id() const noexcept { return run_id_; }
  const AcquisitionConfig& config() const noexcept { return config_; }
  const ClockShared& clock_shared() const noexcept { return clock_shared_; }
  Publisher& publisher() noexcept { return publisher_; }
  // The source's counters as of the last status window.
  struct SourceCounters {
    std::int64_t missing_samples = 0;
    std::int64_t seq_gaps = 0;
    std::int64_t bus_errors = 0;
    std::int64_t superseded_samples = 0;
    std::int64_t late_syncs = 0;
    drivers::BusState bus_state = drivers::BusState::kUnknown;
  };
  SourceCounters source_counters() const noexcept;
  // The source's own counters and state as of the last status window (what
  // source_status_t carried). Read it after stop(): the loop fills it.
  const drivers::SourceDiagnostics& source_diagnostics() const noexcept { return diagnostics_; }
  std::string_view source_name() const noexcept { return source_->name(); }
  // Whether the loop thread got the scheduling/locking it asked for.
  const std::string& realtime_report() const noexcept { return realtime_report_; }
  // Something asked for (SCHED_FIFO, CPU pinning, mlockall) was refused: the
  // daemon logs realtime_report() as a warning. Visible as realtime_report().
  bool realtime_refused() const noexcept { return realtime_refused_; }

  // The recorded wake-up lateness (ns) of each cycle, valid after stop().
  const std::vector<std::int32_t>& lateness_record() const noexcept { return lateness_record_; }

  // One wake, without the thread (replay, benchmarks, tests drive cycles
  // themselves): the sample for this deadline and any backlog, every sample
  // taken as published at `wake_ns`. `deadline_ns`/`wake_ns` on
  // CLOCK_MONOTONIC (or a simulated clock). Returns false at the end of the stream.
  bool run_cycle(std::int64_t deadline_ns, std::int64_t wake_ns) noexcept;
  // Prepares everything run_cycle() needs without starting threads.
  void prepare_for_manual_cycles();

 private:
  void thread_main() noexcept;
  // One wake: read, and read on while the source has a backlog. `clocked`:
  // each sample's publish time from the loop clock (else `wake_ns`).
  bool run_wake(std::int64_t deadline_ns, std::int64_t wake_ns, bool clocked) noexcept;
  void apply_staged_reload() noexcept;
  drivers::ReadStatus read_sample(const drivers::CycleTime& t) noexcept;
  // Stamps, tracks, encodes and counts the sample just read as one cycle.
  void publish_sample(std::int64_t deadline_ns, std::int64_t wake_ns, std::int64_t now_ns,
                      bool first_of_wake, std::int64_t work_start_ns) noexcept;
  void push_joint_events() noexcept;
  void record_lateness(std::int64_t lateness_ns) noexcept;
  void count_overrun(std::int64_t missed, std::int64_t lateness_ns, std::int64_t work_ns) noexcept;
  void finish_window(std::int64_t now_mono) noexcept;
  void push_event(LogEvent::Kind kind) noexcept;
  void push_segment_event(const std::array<double, kJointCount>& before) noexcept;

  AcquisitionConfig config_;
  ConfigHandover configs_;
  std::unique_ptr<drivers::EncoderSource> source_;
  std::unique_ptr<ClockSource> clock_;
  std::unique_ptr<LoopClock> loop_clock_;
  ClockShared clock_shared_;
  std::unique_ptr<ClockMonitor> clock_monitor_;
  Publisher publisher_;
  Pipeline pipeline_;
  std::unique_ptr<TimeBase> time_base_;
  std::int64_t run_id_ = 0;
  MessageEncoder encoder_;
  StatusAssembler status_;
  EventRing events_;

  // loop-thread state
  drivers::EncoderSample sample_;
  drivers::SourceDiagnostics diagnostics_;  // filled at each status window
  CycleResult result_;
  std::int64_t seq_ = 0;
  std::int64_t last_emitted_mono_ns_ = 0;
  std::int64_t last_present_mono_ns_ = 0;
  std::int64_t last_present_seq_ = 0;
  bool segment_pending_ = false;  // a reload taken: the next sample starts a new segment

  std::atomic<std::int64_t> cycles_{0};
  std::atomic<std::int64_t> overruns_{0};
  std::atomic<std::int64_t> foreign_run_id_{0};
  std::atomic<std::int64_t> last_status_seq_{-1};
  std::atomic<std::int64_t> log_lines_dropped_{0};
  std::atomic<std::int64_t> late_{0};
  std::atomic<std::int64_t> caught_up_{0};
  std::atomic<std::int64_t> backlog_wakes_{0};
  std::atomic<std::int64_t> published_missing_{0};
  std::atomic<std::int64_t> published_seq_gaps_{0};
  std::atomic<std::int64_t> published_bus_errors_{0};
  std::atomic<std::int64_t> published_superseded_{0};
  std::atomic<std::int64_t> published_late_syncs_{0};
  std::atomic<drivers::BusState> published_bus_state_{drivers::BusState::kUnknown};
  std::atomic<ServiceState> state_{ServiceState::kStarting};
  std::atomic<StateReason> state_reason_{StateReason::kNone};
  std::atomic<int> homed_joints_{0};
  std::atomic<bool> stop_requested_{false};
  std::atomic<bool> finished_{false};
  std::thread thread_;
  bool started_ = false;
  bool stopped_ = false;
  std::string realtime_report_;
  bool realtime_refused_ = false;
  std::int32_t reloads_ = 0;  // configurations taken from stage_reload()
  std::vector<std::int32_t> lateness_record_;
};

}  // namespace exodaq::core
