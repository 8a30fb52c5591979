#pragma once
// The status window: each cycle's timing and facts are gathered; at the
// window's end the service state follows (ServiceStateMachine) and status_t is
// assembled from the window, the pipeline's joints, the source's counters and
// the clock. Loop thread; allocation-free after construction.
#include <array>
#include <cstdint>
#include <string>
#include <utility>

#include "exodaq/core/clock.hpp"
#include "exodaq/core/health.hpp"
#include "exodaq/core/pipeline.hpp"
#include "exodaq/core/publisher.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/drivers/source_diagnostics.hpp"
#include "exodaq/source_status_t.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::core {

struct StatusSettings {
  std::string rig;
  std::string source;  // the source's name
  std::array<std::string, kJointCount> joint_names;
  std::int64_t run_id = 0;
  ServiceStateMachine::Settings state;
};

// What the loop knows as a window closes.
struct WindowEnd {
  std::int64_t now_mono_ns = 0;  // the window closes on the cycle's own clock
  std::int64_t seq = 0;          // the window's last cycle
  std::int64_t utime_us = 0;     // ... and its utime
  std::int64_t overruns = 0;     // totals since start
  std::int64_t cycles = 0;
  std::int64_t publish_failures = 0;  // refused + ring drops, since start
  PublishHealth publish;              // the failure episode under way, or the last one
  drivers::SourceStats source;
  std::int64_t utime_correction_ns = 0;  // TimeBase
  std::int64_t clock_steps = 0;
  std::int64_t foreign_run_id = 0;     // another run heard on our status channel (0: none)
  std::int64_t log_lines_dropped = 0;  // the daemon's log output lost them (since start)
  // The source's own counters and state (nullptr: none; source_status_t then
  // carries the source's name only).
  const drivers::SourceDiagnostics* diagnostics = nullptr;
};

class StatusAssembler {
 public:
  // `pipeline` and `clock` are read when a window closes; both must outlive this.
  StatusAssembler(const StatusSettings& settings, const Pipeline& pipeline,
                  const ClockShared& clock);

  // Start-up: checks that the largest status_t fits a publisher slot (throws if not).
  void warm_up();

  // The files in effect (at start-up, and at each reload the loop takes) and
  // the reloads applied since start. Assigned within capacity reserved at
  // construction: `files` must keep ConfigFiles' limits.
  void use_files(const ConfigFiles& files, std::int32_t reloads) noexcept;

  // Every cycle. `clock_hold`: unsynchronised under require_sync: hold.
  // `new_wake`: false for a sample caught up in the same wake (its timing is
  // the wake's, counted once).
  void count_cycle(const CycleResult& result, bool present, bool clock_hold,
                   std::int64_t deadline_ns, std::int64_t wake_ns, bool new_wake = true) noexcept;
  void count_work(std::int64_t work_ns) noexcept { work_.add(work_ns); }

  // Closes the window: returns the next state and assembles message(); the
  // next window starts empty.
  ServiceState close_window(ServiceState current, const WindowEnd& end) noexcept;
  const exodaq::status_t& message() const noexcept { return status_; }
  // The same window's source_status_t (WindowEnd::diagnostics), assembled with it.
  const exodaq::source_status_t& source_message() const noexcept { return source_status_; }
  // Why the last window's state was chosen, and the joints homed at its end.
  const StateCause& cause() const noexcept { return cause_; }
  int homed() const noexcept { return homed_; }

 private:
  // The status_t strings naming the files in effect, each with its limit.
  std::array<std::pair<std::string*, std::size_t>, 5> file_fields() noexcept;
  void fill_timing(const WindowEnd& end) noexcept;
  void fill_counters(const WindowEnd& end) noexcept;
  void fill_joints_and_text(ServiceState state, const WindowEnd& end) noexcept;
  void fill_source(const WindowEnd& end) noexcept;
  int append_publish_text(char* text, int n, int cap, ServiceState state,
                          const WindowEnd& end) const noexcept;
  int append_service_text(char* text, int n, int cap, const WindowEnd& end) const noexcept;

  const Pipeline& pipeline_;
  const ClockShared& clock_;
  ServiceStateMachine state_machine_;
  exodaq::status_t status_{};
  // Its arrays hold SourceDiagnostics::kMaxCounters entries, each name with
  // room for kMaxNameBytes: counter_count says how many are in use.
  exodaq::source_status_t source_status_{};
  TimingWindow period_;
  TimingWindow lateness_;
  TimingWindow work_;
  WindowFacts facts_;
  std::int64_t last_wake_ns_ = 0;
  std::int64_t last_sample_wake_ns_ = 0;
  std::int64_t window_overruns_start_ = 0;
  std::int64_t window_publish_failures_start_ = 0;
  StateCause cause_;
  int homed_ = 0;
  std::int64_t window_start_ns_ = 0;  // the previous window's close (0: before the first cycle)
  std::int64_t segment_seq_ = -1;     // a new segment started at this seq in the window (-1: none)
  bool restart_pending_ = false;      // ConfigFiles::restart_pending of the files in effect
};

}  // namespace exodaq::core
