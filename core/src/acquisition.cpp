#include "exodaq/core/acquisition.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/mman.h>
#include <time.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdio>
#include <cstring>
#include <random>
#include <stdexcept>
#include <vector>

#include "exodaq/common/clock_now.hpp"
#include "exodaq/messages/raw_sample.hpp"

namespace exodaq::core {

namespace {
void sleep_until(std::int64_t deadline_ns) noexcept {
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(deadline_ns / 1'000'000'000);
  ts.tv_nsec = static_cast<long>(deadline_ns % 1'000'000'000);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

std::int64_t new_run_id() {
  std::random_device rd;
  const std::uint64_t hi = rd();
  const std::uint64_t lo = rd();
  return static_cast<std::int64_t>(((hi << 32) | lo) & 0x7FFF'FFFF'FFFF'FFFFULL);
}

std::int8_t bus_state_code(drivers::BusState s) noexcept {
  return static_cast<std::int8_t>(s);
}
}  // namespace

Acquisition::Acquisition(AcquisitionConfig config, std::unique_ptr<PipelineConfig> pipeline_config,
                         std::unique_ptr<drivers::EncoderSource> source,
                         std::unique_ptr<MessageSink> sink, const std::string& channel_prefix,
                         std::unique_ptr<ClockSource> clock)
    : config_(std::move(config)),
      active_config_(std::move(pipeline_config)),
      source_(std::move(source)),
      clock_(clock ? std::move(clock) : make_system_clock()),
      publisher_(std::move(sink), channel_prefix),
      pipeline_(*active_config_),
      run_id_(config_.run_id != 0 ? config_.run_id : new_run_id()) {
  time_mapper_.set_policy(config_.clock);
  if (config_.status_every_cycles < 1) config_.status_every_cycles = 1;
  if (const auto speed = source_->recording_speed()) {
    replay_ = true;
    replay_speed_ = *speed;
  }

  // Every string the loop will ever encode is set here, once; the message
  // buffer is reserved so per-window text never reallocates.
  for (int i = 0; i < kJointCount; ++i) {
    const auto& name = config_.joint_names[static_cast<std::size_t>(i)];
    joint_msg_.name[i] = name;
    status_msg_.joint_name[i] = name;
  }
  joint_msg_.run_id = palm_msg_.run_id = raw_msg_.run_id = status_msg_.run_id = run_id_;
  status_msg_.rig = config_.rig;
  status_msg_.source = std::string(source_->name());
  status_msg_.message.reserve(256);
  status_msg_.message.assign(255, ' ');
  status_msg_.message.clear();
}

Acquisition::~Acquisition() {
  stop();
  delete staged_config_.exchange(nullptr);
  delete retired_config_.exchange(nullptr);
}

void Acquisition::prepare_for_manual_cycles() {
  if (!started_) {
    source_->start();
    clock_monitor_ = std::make_unique<ClockMonitor>(*clock_, config_.clock, clock_shared_);
    // Run every encoder once into scratch memory before the loop starts:
    // lcm-gen's hashes are function-local statics initialised on first use.
    // Also checks that the largest status message fits a slot.
    std::vector<std::uint8_t> scratch(kMaxMessageBytes);
    const int cap = static_cast<int>(scratch.size());
    if (joint_msg_.encode(scratch.data(), 0, cap) < 0 ||
        palm_msg_.encode(scratch.data(), 0, cap) < 0 ||
        raw_msg_.encode(scratch.data(), 0, cap) < 0) {
      throw std::runtime_error("message larger than a publisher slot");
    }
    status_msg_.message.assign(255, 'x');
    const bool status_fits = status_msg_.encode(scratch.data(), 0, cap) >= 0;
    status_msg_.message.clear();
    if (config_.record_lateness_cycles > 0) {
      lateness_record_.reserve(static_cast<std::size_t>(config_.record_lateness_cycles));
    }
    if (!status_fits) throw std::runtime_error("status message larger than a publisher slot");
    started_ = true;
  }
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
    finish_window(mono_now_ns());
    publisher_.stop();
    if (clock_monitor_) clock_monitor_->stop();
    source_->stop();
  }
}

void Acquisition::wait_until_finished() {
  while (!finished_.load(std::memory_order_acquire) && !stop_requested_.load()) {
    struct timespec ts {
      0, 2'000'000
    };
    nanosleep(&ts, nullptr);
  }
}

void Acquisition::stage_reload(std::unique_ptr<PipelineConfig> config, const ClockPolicy& clock) {
  // Free what the loop retired after the previous reload.
  delete retired_config_.exchange(nullptr);
  // The clock policy travels with the configuration, so the loop takes both
  // through the one pointer exchange (nothing else is shared).
  config->clock = clock;
  if (clock_monitor_) clock_monitor_->set_policy(clock);
  delete staged_config_.exchange(config.release(), std::memory_order_acq_rel);
}

bool Acquisition::pop_event(LogEvent& out) noexcept {
  const std::uint64_t tail = event_tail_.load(std::memory_order_relaxed);
  if (tail == event_head_.load(std::memory_order_acquire)) return false;
  out = events_[tail % kEventCapacity];
  event_tail_.store(tail + 1, std::memory_order_release);
  return true;
}

void Acquisition::push_event(const LogEvent& e) noexcept {
  const std::uint64_t head = event_head_.load(std::memory_order_relaxed);
  if (head - event_tail_.load(std::memory_order_acquire) >= kEventCapacity) {
    events_dropped_.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  events_[head % kEventCapacity] = e;
  event_head_.store(head + 1, std::memory_order_release);
}

void Acquisition::setup_realtime() {
  std::string report;
  if (config_.lock_memory) {
    if (mlockall(MCL_CURRENT | MCL_FUTURE) != 0) {
      report += std::string("mlockall refused (") + strerrordesc_np(errno) + "); ";
    } else {
      report += "memory locked; ";
    }
  }
  if (config_.cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(config_.cpu, &set);
    const int rc = pthread_setaffinity_np(pthread_self(), sizeof(set), &set);
    report += rc == 0 ? "pinned to CPU " + std::to_string(config_.cpu) + "; "
                      : "CPU affinity refused (" + std::string(strerrordesc_np(rc)) + "); ";
  }
  if (config_.priority > 0) {
    sched_param param{};
    param.sched_priority = config_.priority;
    const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &param);
    report += rc == 0 ? "SCHED_FIFO priority " + std::to_string(config_.priority)
                      : "SCHED_FIFO refused (" + std::string(strerrordesc_np(rc)) +
                            "), running SCHED_OTHER";
  } else {
    report += "SCHED_OTHER";
  }
  realtime_report_ = report;
}

template <typename Msg>
void Acquisition::encode(msg::Kind channel, const Msg& msg, std::int64_t utime_us) noexcept {
  OutgoingMessage* slot = publisher_.acquire();
  if (slot == nullptr) return;  // ring full: counted by the publisher
  const int n = msg.encode(slot->bytes.data(), 0, static_cast<int>(slot->bytes.size()));
  if (n < 0) return;  // cannot happen with checked sizes; the slot is simply not committed
  slot->channel = channel;
  slot->size = static_cast<std::uint32_t>(n);
  slot->utime_us = utime_us;
  publisher_.commit();
}

void Acquisition::thread_main() noexcept {
  try {
    setup_realtime();
  } catch (...) {
    realtime_report_ = "real-time setup failed";
  }
  pthread_setname_np(pthread_self(), "exodaq-loop");
  const std::int64_t period = config_.period_ns;
  std::int64_t deadline = mono_now_ns() + period;
  while (!stop_requested_.load(std::memory_order_relaxed)) {
    if (stall_.load(std::memory_order_relaxed)) {
      sleep_until(mono_now_ns() + 10'000'000);
      deadline = mono_now_ns() + period;
      continue;
    }
    const std::int64_t recorded_next = source_->next_sample_mono_ns();
    if (replay_ && recorded_next >= 0) {
      // Paced by the recording (or not at all at --speed max).
      if (first_recorded_mono_ns_ < 0) {
        first_recorded_mono_ns_ = recorded_next;
        replay_start_mono_ns_ = mono_now_ns();
      }
      if (replay_speed_ > 0.0) {
        deadline =
            replay_start_mono_ns_ +
            static_cast<std::int64_t>(static_cast<double>(recorded_next - first_recorded_mono_ns_) /
                                      replay_speed_);
        sleep_until(deadline);
      } else {
        deadline = mono_now_ns();
      }
    } else {
      sleep_until(deadline);
    }
    const std::int64_t wake = mono_now_ns();
    if (!run_cycle(deadline, wake)) break;
    const std::int64_t end = mono_now_ns();
    deadline += period;
    if (!replay_ && end > deadline) {
      // Overrun: count it and skip to the next deadline still ahead instead of
      // bursting through the missed ones. The skipped cycles' seq numbers are
      // not published; the status counts them.
      const std::int64_t missed = (end - deadline) / period + 1;
      deadline += missed * period;
      seq_ += missed;
      overruns_.fetch_add(missed, std::memory_order_relaxed);
      previous_overran_ = true;
      LogEvent e;
      e.kind = LogEvent::Kind::kOverrun;
      e.seq = seq_;
      e.count = missed;
      e.value = static_cast<double>(end - wake) / 1000.0;
      push_event(e);
    }
  }
  finished_.store(true, std::memory_order_release);
}

bool Acquisition::run_cycle(std::int64_t deadline_ns, std::int64_t wake_ns) noexcept {
  // Reload at the cycle boundary: swap pointers only.
  if (PipelineConfig* staged = staged_config_.exchange(nullptr, std::memory_order_acq_rel)) {
    pipeline_.use(*staged);
    if (staged->clock) {
      config_.clock = *staged->clock;
      time_mapper_.set_policy(config_.clock);
    }
    PipelineConfig* old = active_config_.release();
    active_config_.reset(staged);
    // The main thread frees it; if it has not collected the last one yet, keep
    // the older one alive rather than free on this thread.
    PipelineConfig* expected = nullptr;
    if (!retired_config_.compare_exchange_strong(expected, old)) {
      // Unreachable in practice (stage_reload collects first); leak rather than free here.
    }
    LogEvent e;
    e.kind = LogEvent::Kind::kReloadApplied;
    e.seq = seq_;
    push_event(e);
  }

  drivers::CycleTime t;
  t.deadline_mono_ns = deadline_ns;
  t.now_mono_ns = wake_ns;
  t.period_ns = config_.period_ns;
  t.cycle = seq_;
  const drivers::ReadStatus status = source_->read(t, sample_);
  if (status == drivers::ReadStatus::kEndOfStream) {
    LogEvent e;
    e.kind = LogEvent::Kind::kEndOfStream;
    e.seq = seq_;
    push_event(e);
    finished_.store(true, std::memory_order_release);
    return false;
  }
  if (replay_) {
    // The recording's cycle numbers, gaps from the live run's overruns included.
    const std::int64_t recorded = source_->recorded_seq();
    if (recorded >= 0) seq_ = recorded;
  }
  if (!sample_.present) {
    // The instant the sample was due: the source's own stamp for the lost
    // cycle when it has one (the sim does); else extrapolated from the last
    // real sample by whole periods, which stays before the next real sample's
    // stamp, so the never-backwards rule never has to push a real sample's
    // utime later than its receive time.
    if (sample_.mono_ns <= last_emitted_mono_ns_) {
      sample_.mono_ns = last_present_mono_ns_ > 0
                            ? last_present_mono_ns_ + (seq_ - last_present_seq_) * config_.period_ns
                            : deadline_ns;
    }
  } else {
    last_sample_mono_ns_ = wake_ns;
    last_present_mono_ns_ = sample_.mono_ns;
    last_present_seq_ = seq_;
  }

  // Time: recorded on replay; otherwise the sample's monotonic instant mapped
  // to wall time (never backwards; steps slewed and flagged).
  std::uint32_t extra = 0;
  bool clock_invalid = false;
  std::int64_t utime_us = 0;
  if (replay_) {
    utime_us = sample_.wall_ns / 1000;
    extra |= drivers::sample_flag::kReplay;
    // The live run's clock verdict, carried in the recorded flags.
    clock_invalid = (sample_.flags & drivers::sample_flag::kClockStep) != 0 ||
                    ((sample_.flags & drivers::sample_flag::kClockUnsync) != 0 &&
                     config_.clock.require_sync == RequireSync::kHold);
  } else {
    const auto mapped =
        time_mapper_.map(sample_.mono_ns, clock_shared_.offset_ns.load(std::memory_order_relaxed),
                         clock_shared_.offset_generation.load(std::memory_order_acquire));
    utime_us = mapped.utime_us;
    if (mapped.stepping) {
      extra |= drivers::sample_flag::kClockStep;
      clock_invalid = true;
    }
    if (mapped.new_step) {
      LogEvent e;
      e.kind = LogEvent::Kind::kClockStep;
      e.seq = seq_;
      e.count = time_mapper_.steps();
      e.value = static_cast<double>(time_mapper_.pending_correction_ns()) / 1e6;
      push_event(e);
    }
    const bool unsync = !clock_shared_.synchronised.load(std::memory_order_relaxed);
    if (unsync && config_.clock.require_sync != RequireSync::kIgnore) {
      extra |= drivers::sample_flag::kClockUnsync;
      if (config_.clock.require_sync == RequireSync::kHold) clock_invalid = true;
    }
    facts_.clock_hold =
        facts_.clock_hold || (unsync && config_.clock.require_sync == RequireSync::kHold);
  }
  if (previous_overran_) {
    extra |= drivers::sample_flag::kLate;
    previous_overran_ = false;
  }

  pipeline_.process(sample_, extra, clock_invalid, result_);
  result_.seq = seq_;
  result_.mono_ns = sample_.mono_ns;
  last_emitted_mono_ns_ = sample_.mono_ns;
  result_.utime_us = utime_us;
  encode_cycle(sample_);

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
    push_event(e);
  }

  // Window bookkeeping.
  ++facts_.cycles;
  if (sample_.present) ++facts_.samples_present;
  if (result_.valid) ++facts_.valid_poses;
  facts_.sample_flags_or |= result_.sample_flags;
  for (int i = 0; i < kJointCount; ++i) {
    facts_.joint_flags_or[static_cast<std::size_t>(i)] |=
        result_.joints[static_cast<std::size_t>(i)].flags;
  }
  if (last_wake_ns_ != 0) period_window_.add(wake_ns - last_wake_ns_);
  last_wake_ns_ = wake_ns;
  lateness_window_.add(wake_ns - deadline_ns);
  if (lateness_record_.size() < lateness_record_.capacity()) {
    // Within the capacity reserved at start: no allocation.
    lateness_record_.push_back(
        static_cast<std::int32_t>(std::min<std::int64_t>(wake_ns - deadline_ns, INT32_MAX)));
  }

  ++seq_;
  cycles_.fetch_add(1, std::memory_order_release);  // publishes realtime_report_ (cycles())
  const std::int64_t end = mono_now_ns();
  work_window_.add(end - wake_ns);
  // The window closes on the cycle's own clock (the simulated one when tests
  // drive cycles by hand), so state decisions are reproducible.
  if (seq_ % config_.status_every_cycles == 0) finish_window(wake_ns);
  return true;
}

void Acquisition::encode_cycle(const drivers::EncoderSample& sample) noexcept {
  const CycleResult& r = result_;
  joint_msg_.utime = palm_msg_.utime = raw_msg_.utime = r.utime_us;
  joint_msg_.mono_ns = palm_msg_.mono_ns = raw_msg_.mono_ns = r.mono_ns;
  joint_msg_.seq = palm_msg_.seq = raw_msg_.seq = r.seq;
  // The palm pose first: it is what a BMI decoder waits for.
  palm_msg_.valid = r.valid;
  palm_msg_.invalid_reason = static_cast<std::int32_t>(r.invalid_reason);
  for (int k = 0; k < 3; ++k) {
    palm_msg_.position[k] = r.pose.palm_position[k];
    palm_msg_.elbow[k] = r.pose.elbow_position[k];
  }
  for (int k = 0; k < 4; ++k) palm_msg_.orientation[k] = r.pose.palm_quaternion_wxyz[k];
  palm_msg_.shoulder_manipulability = r.pose.shoulder_manipulability_normalised;
  palm_msg_.shoulder_manipulability_raw = r.pose.shoulder_manipulability;
  palm_msg_.near_singular = r.pose.near_singular;
  encode(msg::Kind::kPalmPose, palm_msg_, r.utime_us);

  for (int i = 0; i < kJointCount; ++i) {
    const JointReading& j = r.joints[static_cast<std::size_t>(i)];
    joint_msg_.position[i] = j.position_rad;
    joint_msg_.velocity[i] = j.velocity_rad_s;
    joint_msg_.raw_count[i] = j.count;
    joint_msg_.homed[i] = j.homed;
    joint_msg_.flags[i] = static_cast<std::int32_t>(j.flags);
  }
  joint_msg_.sample_flags = static_cast<std::int32_t>(r.sample_flags);
  encode(msg::Kind::kJointState, joint_msg_, r.utime_us);

  if (config_.publish_raw) {
    msg::to_encoder_raw(sample, raw_msg_);
    encode(msg::Kind::kEncoderRaw, raw_msg_, r.utime_us);
  }
  publisher_.notify();
}

void Acquisition::finish_window(std::int64_t now_mono) noexcept {
  const drivers::SourceStats stats = source_->stats();
  published_missing_.store(stats.missing_samples, std::memory_order_relaxed);
  published_seq_gaps_.store(stats.seq_gaps, std::memory_order_relaxed);
  published_bus_errors_.store(stats.bus_errors, std::memory_order_relaxed);
  published_bus_state_.store(stats.bus_state, std::memory_order_relaxed);
  const std::int64_t overruns = overruns_.load(std::memory_order_relaxed);
  facts_.overruns = overruns - window_overruns_start_;
  window_overruns_start_ = overruns;
  facts_.bus_state = stats.bus_state;
  bool all_homed = true;
  for (int i = 0; i < kJointCount; ++i) all_homed = all_homed && pipeline_.joint(i).reading().homed;
  facts_.all_homed = all_homed;

  const ServiceState previous = state_.load(std::memory_order_relaxed);
  ServiceState next = previous;
  if (previous != ServiceState::kStopping) {
    const std::int64_t since_sample_ms =
        last_sample_mono_ns_ == 0 ? 0 : (now_mono - last_sample_mono_ns_) / 1'000'000;
    next = next_state(previous, facts_, since_sample_ms, config_.fault_after_ms);
    if (replay_ && facts_.samples_present > 0 && next == ServiceState::kFault) {
      next = previous;
    }
    // Hysteresis: back to running only after a run of clean windows, so a
    // marginal fault does not flap the state (and the log) every window.
    clean_windows_ = next == ServiceState::kRunning ? clean_windows_ + 1 : 0;
    if (next == ServiceState::kRunning && previous == ServiceState::kDegraded &&
        clean_windows_ < config_.clean_windows_to_recover) {
      next = previous;
    }
  }
  if (next != previous) {
    state_.store(next, std::memory_order_relaxed);
    LogEvent e;
    e.kind = LogEvent::Kind::kStateChange;
    e.seq = seq_;
    e.state = next;
    push_event(e);
  }

  status_t& s = status_msg_;
  s.utime = result_.utime_us;
  s.mono_ns = now_mono;
  s.seq = seq_ - 1;
  s.state = static_cast<std::int8_t>(next);
  s.window_cycles = facts_.cycles;
  const Percentiles period = period_window_.percentiles();
  const Percentiles late = lateness_window_.percentiles();
  const Percentiles work = work_window_.percentiles();
  s.period_p50_us = period.p50_us;
  s.period_p99_us = period.p99_us;
  s.period_max_us = period.max_us;
  s.lateness_p50_us = late.p50_us;
  s.lateness_p99_us = late.p99_us;
  s.lateness_max_us = late.max_us;
  s.work_p50_us = work.p50_us;
  s.work_p99_us = work.p99_us;
  s.work_max_us = work.max_us;
  s.overruns = overruns;
  s.cycles = cycles_.load(std::memory_order_relaxed);
  s.publish_failures = publisher_.failures() + publisher_.ring_drops();
  s.frames = stats.frames;
  s.bad_frames = stats.bad_frames;
  s.missing_samples = stats.missing_samples;
  s.seq_gaps = stats.seq_gaps;
  s.duplicates = stats.duplicates;
  s.out_of_order = stats.out_of_order;
  s.bus_errors = stats.bus_errors;
  s.rx_overflows = stats.rx_overflows;
  s.bus_state = bus_state_code(stats.bus_state);
  s.board_errors = static_cast<std::int32_t>(stats.board_errors);
  s.clock_synchronised = clock_shared_.synchronised.load(std::memory_order_relaxed);
  s.clock_est_error_us = clock_shared_.est_error_us.load(std::memory_order_relaxed);
  s.clock_max_error_us = clock_shared_.max_error_us.load(std::memory_order_relaxed);
  s.clock_offset_us = clock_shared_.ntp_offset_us.load(std::memory_order_relaxed);
  s.utime_correction_us = static_cast<double>(time_mapper_.pending_correction_ns()) / 1000.0;
  s.clock_steps = time_mapper_.steps();
  int homed = 0;
  int worst_joint = -1;
  for (int i = 0; i < kJointCount; ++i) {
    const JointTracker& j = pipeline_.joint(i);
    s.homing[i] = static_cast<std::int8_t>(j.reading().homing);
    s.joint_flags[i] =
        static_cast<std::int32_t>(facts_.joint_flags_or[static_cast<std::size_t>(i)]);
    s.glitches[i] = j.counters().glitches;
    s.lost_count_events[i] = j.counters().lost_count_events;
    s.stale_events[i] = j.counters().stale_events;
    s.out_of_range_events[i] = j.counters().out_of_range_events;
    if (j.reading().homed) ++homed;
    const std::uint32_t faults = facts_.joint_flags_or[static_cast<std::size_t>(i)] &
                                 joint_flag::kFaults & ~joint_flag::kUnhomed;
    if (faults != 0 && worst_joint < 0) worst_joint = i;
  }
  // A one-line summary for people; snprintf into a stack buffer, then assign
  // within the reserved capacity (no allocation).
  char text[200];
  const double valid_pct =
      facts_.cycles > 0 ? 100.0 * facts_.valid_poses / static_cast<double>(facts_.cycles) : 0.0;
  int n = std::snprintf(text, sizeof(text), "%s: %d/%d homed, %.1f%% valid, %lld overruns",
                        state_name(next), homed, kJointCount, valid_pct,
                        static_cast<long long>(overruns));
  if (worst_joint >= 0 && n > 0 && n < static_cast<int>(sizeof(text))) {
    n +=
        std::snprintf(text + n, sizeof(text) - static_cast<std::size_t>(n), "; joint %s flags 0x%x",
                      config_.joint_names[static_cast<std::size_t>(worst_joint)].c_str(),
                      facts_.joint_flags_or[static_cast<std::size_t>(worst_joint)]);
  }
  if ((facts_.sample_flags_or & drivers::sample_flag::kClockUnsync) != 0 && n > 0 &&
      n < static_cast<int>(sizeof(text))) {
    std::snprintf(text + n, sizeof(text) - static_cast<std::size_t>(n), "; clock unsynchronised");
  }
  s.message.assign(text);
  encode(msg::Kind::kStatus, s, s.utime);
  publisher_.notify();

  period_window_.clear();
  lateness_window_.clear();
  work_window_.clear();
  facts_ = WindowFacts{};
}

}  // namespace exodaq::core
