#include "exodaq/core/acquisition.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <random>

#include "exodaq/common/clock_now.hpp"

namespace exodaq::core {

namespace {
std::int64_t new_run_id() {
  std::random_device rd;
  const std::uint64_t hi = rd();
  const std::uint64_t lo = rd();
  return static_cast<std::int64_t>(((hi << 32) | lo) & 0x7FFF'FFFF'FFFF'FFFFULL);
}

StatusSettings status_settings(const AcquisitionConfig& c, const drivers::EncoderSource& source,
                               const TimeBase& time_base, std::int64_t run_id) {
  StatusSettings s;
  s.rig = c.rig;
  s.source = std::string(source.name());
  s.joint_names = c.joint_names;
  s.run_id = run_id;
  s.state.fault_after_ms = c.fault_after_ms;
  s.state.clean_windows_to_recover = c.clean_windows_to_recover;
  s.state.hold_fault_while_samples = time_base.recorded();
  return s;
}

// The loop thread's CPU, SCHED_FIFO priority and memory locking as asked;
// returns what was granted, for the log.
std::string setup_realtime(const AcquisitionConfig& c) {
  std::string report;
  if (c.lock_memory) {
    report += mlockall(MCL_CURRENT | MCL_FUTURE) != 0
                  ? std::string("mlockall refused (") + strerrordesc_np(errno) + "); "
                  : std::string("memory locked; ");
  }
  if (c.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(c.cpu, &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    report += rc == 0 ? "pinned to CPU " + std::to_string(c.cpu) + "; "
                      : "CPU affinity refused (" + std::string(strerrordesc_np(rc)) + "); ";
  }
  if (c.priority > 0) {
    sched_param param{};
    param.sched_priority = c.priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    report += rc == 0 ? "SCHED_FIFO priority " + std::to_string(c.priority)
                      : "SCHED_FIFO refused (" + std::string(strerrordesc_np(rc)) +
                            "), running SCHED_OTHER";
  } else {
    report += "SCHED_OTHER";
  }
  return report;
}
}  // namespace

Acquisition::Acquisition(AcquisitionConfig config, std::unique_ptr<PipelineConfig> pipeline_config,
                         std::unique_ptr<drivers::EncoderSource> source,
                         std::unique_ptr<MessageSink> sink, const std::string& channel_prefix,
                         std::unique_ptr<ClockSource> clock, std::unique_ptr<LoopClock> loop_clock)
    : config_(std::move(config)),
      configs_(std::move(pipeline_config)),
      source_(std::move(source)),
      clock_(clock ? std::move(clock) : make_system_clock()),
      loop_clock_(loop_clock ? std::move(loop_clock) : make_monotonic_loop_clock()),
      publisher_(std::move(sink), channel_prefix),
      pipeline_(configs_.active()),
      time_base_(
          make_time_base(*source_, clock_shared_, config_.clock, config_.period_ns, *loop_clock_)),
      run_id_(config_.run_id != 0 ? config_.run_id : new_run_id()),
      encoder_(config_.joint_names, run_id_, config_.publish_raw, config_.period_ns),
      status_(status_settings(config_, *source_, *time_base_, run_id_), pipeline_, clock_shared_) {
  if (config_.status_every_cycles < 1) config_.status_every_cycles = 1;
  if (config_.max_samples_per_wake < 1) config_.max_samples_per_wake = 1;
}

Acquisition::~Acquisition() {
  stop();
}

void Acquisition::prepare_for_manual_cycles() {
  if (started_) return;
  source_->start();
  if (const drivers::JointResumeSet* resume = source_->resume_state()) pipeline_.resume(*resume);
  clock_monitor_ = std::make_unique<ClockMonitor>(*clock_, config_.clock, clock_shared_);
  encoder_.warm_up();
  status_.warm_up();
  if (config_.record_lateness_cycles > 0) {
    lateness_record_.reserve(static_cast<std::size_t>(config_.record_lateness_cycles));
  }
  started_ = true;
}

void Acquisition::start() {
  if (started_) return;
  prepare_for_manual_cycles();
  publisher_.start();
  clock_monitor_->start();
  thread_ = std::thread([this] { thread_main(); });
}

void Acquisition::stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_requested_.store(true);
  if (thread_.joinable()) thread_.join();
  if (started_) {
    // The final status: subscribers see the service stop on purpose.
    state_.store(ServiceState::kStopping);
    finish_window(time_base_->now());
    publisher_.stop();
    if (clock_monitor_) clock_monitor_->stop();
    source_->stop();
  }
}

void Acquisition::stage_reload(std::unique_ptr<PipelineConfig> config, const ClockPolicy& clock) {
  // The clock policy travels with the configuration: the loop takes both
  // through the one pointer exchange.
  config->clock = clock;
  if (clock_monitor_) clock_monitor_->set_policy(clock);
  configs_.stage(std::move(config));
}

Acquisition::SourceCounters Acquisition::source_counters() const noexcept {
  SourceCounters c;
  c.missing_samples = published_missing_.load(std::memory_order_relaxed);
  c.seq_gaps = published_seq_gaps_.load(std::memory_order_relaxed);
  c.bus_errors = published_bus_errors_.load(std::memory_order_relaxed);
  c.superseded_samples = published_superseded_.load(std::memory_order_relaxed);
  c.late_syncs = published_late_syncs_.load(std::memory_order_relaxed);
  c.bus_state = published_bus_state_.load(std::memory_order_relaxed);
  return c;
}

// The joint that moved most from the sample before the new segment to its first.
void Acquisition::push_segment_event(const std::array<double, kJointCount>& before) noexcept {
  LogEvent e;
  e.kind = LogEvent::Kind::kNewSegment;
  e.seq = seq_;
  for (std::size_t i = 0; i < before.size(); ++i) {
    const double jump = result_.joints[i].position_rad - before[i];
    if (e.joint < 0 || std::fabs(jump) > std::fabs(e.value)) {
      e.joint = static_cast<int>(i);
      e.value = jump;
    }
  }
  events_.push(e);
}

void Acquisition::push_event(LogEvent::Kind kind) noexcept {
  LogEvent e;
  e.kind = kind;
  e.seq = seq_;
  events_.push(e);
}

void Acquisition::thread_main() noexcept {
  try {
    realtime_report_ = setup_realtime(config_);
    realtime_refused_ = realtime_report_.find("refused") != std::string::npos;
  } catch (...) {
    realtime_report_ = "real-time setup failed";
    realtime_refused_ = true;
  }
  pthread_setname_np(pthread_self(), "exodaq-loop");
  const std::int64_t period = config_.period_ns;
  std::int64_t deadline = time_base_->now() + period;
  while (!stop_requested_.load(std::memory_order_relaxed)) {
    deadline = time_base_->wait(deadline);
    const std::int64_t wake = time_base_->now();
    if (!run_wake(deadline, wake, true)) break;
    const std::int64_t end = time_base_->now();
    const std::int64_t lateness = wake - deadline;
    deadline += period;
    // Overrun: skip to the next deadline still ahead instead of bursting
    // through the missed ones. Sync master: their seq numbers are counted, not
    // published (no sample was taken). Free-running board: the samples taken
    // meanwhile wait in the source and come with the next wakes' backlog.
    if (const std::int64_t missed = time_base_->overrun(end, deadline); missed > 0) {
      deadline += missed * period;
      count_overrun(missed, lateness, end - wake);
    }
  }
  finished_.store(true, std::memory_order_release);
}

// The wake's lateness and the cycle's work travel apart: a late wake, not a
// long cycle, is the usual cause (docs/operations.md, "Overruns").
void Acquisition::count_overrun(std::int64_t missed, std::int64_t lateness_ns,
                                std::int64_t work_ns) noexcept {
  if (!source_->free_running()) seq_ += missed;
  overruns_.fetch_add(missed, std::memory_order_relaxed);
  LogEvent e;
  e.kind = LogEvent::Kind::kOverrun;
  e.seq = seq_;
  e.count = missed;
  e.value = static_cast<double>(lateness_ns) / 1000.0;
  e.work_us = static_cast<double>(work_ns) / 1000.0;
  events_.push(e);
}

bool Acquisition::run_cycle(std::int64_t deadline_ns, std::int64_t wake_ns) noexcept {
  return run_wake(deadline_ns, wake_ns, false);
}

bool Acquisition::run_wake(std::int64_t deadline_ns, std::int64_t wake_ns, bool clocked) noexcept {
  apply_staged_reload();
  drivers::CycleTime t;
  t.deadline_mono_ns = deadline_ns;
  t.now_mono_ns = wake_ns;
  t.period_ns = config_.period_ns;
  for (int n = 1;; ++n) {
    const std::int64_t work_start = mono_now_ns();
    t.cycle = seq_;
    const drivers::ReadStatus r = read_sample(t);
    if (r == drivers::ReadStatus::kEndOfStream) return false;
    if (r == drivers::ReadStatus::kNothingDue) return true;
    const std::int64_t now = clocked ? time_base_->now() : wake_ns;
    publish_sample(deadline_ns, wake_ns, now, !t.catch_up, work_start);
    if (source_->backlog() <= 0) return true;
    if (n >= config_.max_samples_per_wake) {
      // Bounded: the rest stays queued in the source for the next wakes.
      backlog_wakes_.fetch_add(1, std::memory_order_relaxed);
      return true;
    }
    t.catch_up = true;
    t.now_mono_ns = now;
  }
}

void Acquisition::publish_sample(std::int64_t deadline_ns, std::int64_t wake_ns,
                                 std::int64_t now_ns, bool first_of_wake,
                                 std::int64_t work_start_ns) noexcept {
  const SampleTime time = time_base_->stamp(sample_);
  if (time.new_step) {
    LogEvent e;
    e.kind = LogEvent::Kind::kClockStep;
    e.seq = seq_;
    e.count = time_base_->clock_steps();
    e.value = static_cast<double>(time_base_->utime_correction_ns()) / 1e6;
    events_.push(e);
  }
  std::uint32_t flags = time.flags;
  // LATE: published more than one period after its sample instant (a
  // recording's samples are published when replayed, never late).
  if (!time_base_->recorded() && now_ns - sample_.mono_ns > config_.period_ns) {
    flags |= drivers::sample_flag::kLate;
    late_.fetch_add(1, std::memory_order_relaxed);
  }
  if (foreign_run_id_.load(std::memory_order_relaxed) != 0)
    flags |= drivers::sample_flag::kForeignRun;
  const bool new_segment = segment_pending_;
  std::array<double, kJointCount> before{};
  if (new_segment) {
    flags |= drivers::sample_flag::kNewSegment;
    segment_pending_ = false;
    for (std::size_t i = 0; i < before.size(); ++i) before[i] = result_.joints[i].position_rad;
  }

  pipeline_.process(sample_, flags, time.clock_invalid, result_);
  result_.seq = seq_;
  if (new_segment) push_segment_event(before);
  result_.mono_ns = sample_.mono_ns;
  last_emitted_mono_ns_ = sample_.mono_ns;
  result_.utime_us = time.utime_us;
  encoder_.publish_homing(result_, pipeline_, publisher_);
  encoder_.publish(result_, sample_, publisher_);
  push_joint_events();

  // The wake's timing counts once; every sample counts as a cycle.
  status_.count_cycle(result_, sample_.present, time.clock_hold, deadline_ns, wake_ns,
                      first_of_wake);
  if (first_of_wake) {
    record_lateness(wake_ns - deadline_ns);
  } else {
    caught_up_.fetch_add(1, std::memory_order_relaxed);
  }
  ++seq_;
  cycles_.fetch_add(1, std::memory_order_release);  // publishes realtime_report_ (cycles())
  status_.count_work(mono_now_ns() - work_start_ns);
  // The window closes on the cycle's own clock (the simulated one when tests
  // drive cycles by hand), so state decisions are reproducible.
  if (seq_ % config_.status_every_cycles == 0) finish_window(now_ns);
}

void Acquisition::apply_staged_reload() noexcept {
  const PipelineConfig* staged = configs_.take_staged();
  if (staged == nullptr) return;
  pipeline_.use(*staged);
  ++reloads_;
  status_.use_files(staged->files, reloads_);
  if (staged->clock) time_base_->set_policy(*staged->clock);
  segment_pending_ = segment_pending_ || staged->new_segment;
  push_event(LogEvent::Kind::kReloadApplied);
}

// Reads the next sample and settles its seq and, for a missing sample, the
// instant it was due.
drivers::ReadStatus Acquisition::read_sample(const drivers::CycleTime& t) noexcept {
  const drivers::ReadStatus r = source_->read(t, sample_);
  if (r == drivers::ReadStatus::kEndOfStream) {
    push_event(LogEvent::Kind::kEndOfStream);
    finished_.store(true, std::memory_order_release);
    return r;
  }
  if (r == drivers::ReadStatus::kNothingDue) return r;
  seq_ = time_base_->seq(seq_);
  if (sample_.present) {
    last_present_mono_ns_ = sample_.mono_ns;
    last_present_seq_ = seq_;
  } else if (sample_.mono_ns <= last_emitted_mono_ns_) {
    // No stamp of its own: extrapolated from the last real sample by whole
    // periods, which stays before the next real sample's stamp, so utime
    // never has to be pushed later than a real sample's receive time.
    sample_.mono_ns = last_present_mono_ns_ > 0
                          ? last_present_mono_ns_ + (seq_ - last_present_seq_) * config_.period_ns
                          : t.deadline_mono_ns;
  }
  return r;
}

void Acquisition::push_joint_events() noexcept {
  for (int i = 0; i < kJointCount; ++i) {
    const JointEvent je = result_.events[static_cast<std::size_t>(i)];
    if (je == JointEvent::kNone) continue;
    const auto& tracker = pipeline_.joint(i);
    LogEvent e;
    e.kind = LogEvent::Kind::kJoint;
    e.seq = seq_;
    e.joint = i;
    e.joint_event = je;
    e.value = tracker.reading().position_rad;
    e.count = tracker.counters().last_index_drift_counts;
    events_.push(e);
  }
}

void Acquisition::record_lateness(std::int64_t lateness_ns) noexcept {
  // Within the capacity reserved at start: no allocation.
  if (lateness_record_.size() < lateness_record_.capacity()) {
    lateness_record_.push_back(
        static_cast<std::int32_t>(std::min<std::int64_t>(lateness_ns, INT32_MAX)));
  }
}

void Acquisition::finish_window(std::int64_t now_mono) noexcept {
  WindowEnd end;
  end.source = source_->stats();
  published_missing_.store(end.source.missing_samples, std::memory_order_relaxed);
  published_seq_gaps_.store(end.source.seq_gaps, std::memory_order_relaxed);
  published_bus_errors_.store(end.source.bus_errors, std::memory_order_relaxed);
  published_superseded_.store(end.source.superseded_samples, std::memory_order_relaxed);
  published_late_syncs_.store(end.source.late_syncs, std::memory_order_relaxed);
  published_bus_state_.store(end.source.bus_state, std::memory_order_relaxed);
  end.now_mono_ns = now_mono;
  end.seq = seq_ - 1;
  end.utime_us = result_.utime_us;
  end.overruns = overruns_.load(std::memory_order_relaxed);
  end.cycles = cycles_.load(std::memory_order_relaxed);
  end.publish = publisher_.health();
  end.publish_failures = end.publish.failures + end.publish.ring_drops;
  end.utime_correction_ns = time_base_->utime_correction_ns();
  end.clock_steps = time_base_->clock_steps();
  end.foreign_run_id = foreign_run_id_.load(std::memory_order_relaxed);
  end.log_lines_dropped = log_lines_dropped_.load(std::memory_order_relaxed);
  diagnostics_.clear();
  source_->diagnose(diagnostics_);
  end.diagnostics = &diagnostics_;

  const ServiceState previous = state_.load(std::memory_order_relaxed);
  const ServiceState next = status_.close_window(previous, end);
  state_reason_.store(status_.cause().reason, std::memory_order_relaxed);
  homed_joints_.store(status_.homed(), std::memory_order_relaxed);
  if (next != previous) {
    state_.store(next, std::memory_order_relaxed);
    LogEvent e;
    e.kind = LogEvent::Kind::kStateChange;
    e.seq = seq_;
    e.state = next;
    e.cause = status_.cause();
    events_.push(e);
  }
  last_status_seq_.store(end.seq, std::memory_order_release);
  publish_encoded(publisher_, status_.message(), status_.message().utime);
  publish_encoded(publisher_, status_.source_message(), status_.source_message().utime);
  publisher_.notify();
}

}  // namespace exodaq::core
