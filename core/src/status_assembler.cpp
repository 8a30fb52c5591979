#include "exodaq/core/status_assembler.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <vector>

#include "exodaq/core/publisher.hpp"
#include "exodaq/messages/flag_names.hpp"

namespace exodaq::core {

StatusAssembler::StatusAssembler(const StatusSettings& settings, const Pipeline& pipeline,
                                 const ClockShared& clock)
    : pipeline_(pipeline), clock_(clock), state_machine_(settings.state) {
  for (int i = 0; i < kJointCount; ++i)
    status_.joint_name[i] = settings.joint_names[static_cast<std::size_t>(i)];
  status_.run_id = settings.run_id;
  status_.rig = settings.rig;
  status_.source = settings.source;
  // The summary text is assigned within this capacity: it never reallocates.
  status_.message.reserve(256);
  status_.message.assign(255, ' ');
  status_.message.clear();
  for (auto [text, bytes] : file_fields()) text->reserve(bytes);
  use_files(pipeline.config().files, 0);
  status_.foreign_run_id = 0;
  source_status_.run_id = settings.run_id;
  source_status_.source = settings.source;
  source_status_.state.reserve(drivers::SourceDiagnostics::kMaxStateBytes);
  constexpr auto kCounters = static_cast<std::size_t>(drivers::SourceDiagnostics::kMaxCounters);
  source_status_.counter_name.resize(kCounters);
  source_status_.counter_value.resize(kCounters);
  for (std::string& name : source_status_.counter_name)
    name.reserve(drivers::SourceDiagnostics::kMaxNameBytes);
  source_status_.counter_count = 0;
}

std::array<std::pair<std::string*, std::size_t>, 5> StatusAssembler::file_fields() noexcept {
  return {{{&status_.config_path, ConfigFiles::kMaxPathBytes},
           {&status_.config_sha256, ConfigFiles::kMaxHashBytes},
           {&status_.calibration_path, ConfigFiles::kMaxPathBytes},
           {&status_.calibration_sha256, ConfigFiles::kMaxHashBytes},
           {&status_.calibration_provenance, ConfigFiles::kMaxProvenanceBytes}}};
}

void StatusAssembler::use_files(const ConfigFiles& files, std::int32_t reloads) noexcept {
  const std::array<const std::string*, 5> from = {
      &files.config_path, &files.config_sha256, &files.calibration_path, &files.calibration_sha256,
      &files.calibration_provenance};
  const auto to = file_fields();
  for (std::size_t i = 0; i < to.size(); ++i) {
    // Within the reserved capacity (a longer one is cut, never reallocated).
    to[i].first->assign(*from[i], 0, to[i].second);
  }
  restart_pending_ = files.restart_pending;
  status_.reloads = reloads;
}

void StatusAssembler::warm_up() {
  std::vector<std::uint8_t> scratch(kMaxMessageBytes);
  const ConfigFiles kept = {status_.config_path, status_.config_sha256, status_.calibration_path,
                            status_.calibration_sha256, status_.calibration_provenance};
  status_.message.assign(255, 'x');
  for (auto [text, bytes] : file_fields()) text->assign(bytes, 'x');
  const bool fits = status_.encode(scratch.data(), 0, static_cast<int>(scratch.size())) >= 0;
  status_.message.clear();
  use_files(kept, status_.reloads);
  if (!fits) throw std::runtime_error("status message larger than a publisher slot");
  // The largest source_status_t: every counter, every name and the state at their limits.
  source_status_t& m = source_status_;
  m.state.assign(drivers::SourceDiagnostics::kMaxStateBytes - 1, 'x');
  for (std::string& name : m.counter_name)
    name.assign(drivers::SourceDiagnostics::kMaxNameBytes, 'x');
  m.counter_count = static_cast<std::int16_t>(m.counter_name.size());
  const bool source_fits = m.encode(scratch.data(), 0, static_cast<int>(scratch.size())) >= 0;
  m.state.clear();
  for (std::string& name : m.counter_name) name.clear();
  m.counter_count = 0;
  if (!source_fits) throw std::runtime_error("source status message larger than a publisher slot");
}

void StatusAssembler::count_cycle(const CycleResult& result, bool present, bool clock_hold,
                                  std::int64_t deadline_ns, std::int64_t wake_ns,
                                  bool new_wake) noexcept {
  ++facts_.cycles;
  if (present) {
    ++facts_.samples_present;
    last_sample_wake_ns_ = wake_ns;
  }
  if (window_start_ns_ == 0) window_start_ns_ = wake_ns;
  if (result.valid) ++facts_.valid_poses;
  facts_.clock_hold = facts_.clock_hold || clock_hold;
  facts_.sample_flags_or |= result.sample_flags;
  if ((result.sample_flags & drivers::sample_flag::kNewSegment) != 0) segment_seq_ = result.seq;
  for (int i = 0; i < kJointCount; ++i) {
    facts_.joint_flags_or[static_cast<std::size_t>(i)] |=
        result.joints[static_cast<std::size_t>(i)].flags;
  }
  if (!new_wake) return;
  if (last_wake_ns_ != 0) period_.add(wake_ns - last_wake_ns_);
  last_wake_ns_ = wake_ns;
  lateness_.add(wake_ns - deadline_ns);
}

ServiceState StatusAssembler::close_window(ServiceState current, const WindowEnd& end) noexcept {
  facts_.overruns = end.overruns - window_overruns_start_;
  window_overruns_start_ = end.overruns;
  facts_.publish_failures = end.publish_failures - window_publish_failures_start_;
  window_publish_failures_start_ = end.publish_failures;
  facts_.bus_state = end.source.bus_state;
  bool all_homed = true;
  for (int i = 0; i < kJointCount; ++i) all_homed = all_homed && pipeline_.joint(i).reading().homed;
  facts_.all_homed = all_homed;
  const std::int64_t since_sample_ms =
      last_sample_wake_ns_ == 0 ? 0 : (end.now_mono_ns - last_sample_wake_ns_) / 1'000'000;
  const ServiceState next = state_machine_.next(current, facts_, since_sample_ms);
  cause_ = state_machine_.cause();
  cause_.window_ns = window_start_ns_ != 0 ? end.now_mono_ns - window_start_ns_ : 0;
  window_start_ns_ = end.now_mono_ns;

  status_.utime = end.utime_us;
  status_.mono_ns = end.now_mono_ns;
  status_.seq = end.seq;
  status_.state = static_cast<std::int8_t>(next);
  status_.window_cycles = facts_.cycles;
  status_.foreign_run_id = end.foreign_run_id;
  fill_timing(end);
  fill_counters(end);
  fill_joints_and_text(next, end);
  fill_source(end);

  period_.clear();
  lateness_.clear();
  work_.clear();
  facts_ = WindowFacts{};
  segment_seq_ = -1;
  return next;
}

void StatusAssembler::fill_timing(const WindowEnd& end) noexcept {
  status_t& s = status_;
  const Percentiles period = period_.percentiles();
  const Percentiles late = lateness_.percentiles();
  const Percentiles work = work_.percentiles();
  s.period_p50_us = period.p50_us;
  s.period_p99_us = period.p99_us;
  s.period_max_us = period.max_us;
  s.lateness_p50_us = late.p50_us;
  s.lateness_p99_us = late.p99_us;
  s.lateness_max_us = late.max_us;
  s.work_p50_us = work.p50_us;
  s.work_p99_us = work.p99_us;
  s.work_max_us = work.max_us;
  s.overruns = end.overruns;
  s.cycles = end.cycles;
  s.publish_failures = end.publish_failures;
}

void StatusAssembler::fill_counters(const WindowEnd& end) noexcept {
  status_t& s = status_;
  const drivers::SourceStats& stats = end.source;
  s.frames = stats.frames;
  s.bad_frames = stats.bad_frames;
  s.missing_samples = stats.missing_samples;
  s.seq_gaps = stats.seq_gaps;
  s.duplicates = stats.duplicates;
  s.out_of_order = stats.out_of_order;
  s.bus_errors = stats.bus_errors;
  s.rx_overflows = stats.rx_overflows;
  s.bus_state = static_cast<std::int8_t>(stats.bus_state);
  s.board_errors = static_cast<std::int32_t>(stats.board_errors);
  s.clock_synchronised = clock_.synchronised.load(std::memory_order_relaxed);
  s.clock_est_error_us = clock_.est_error_us.load(std::memory_order_relaxed);
  s.clock_max_error_us = clock_.max_error_us.load(std::memory_order_relaxed);
  s.clock_offset_us = clock_.ntp_offset_us.load(std::memory_order_relaxed);
  s.utime_correction_us = static_cast<double>(end.utime_correction_ns) / 1000.0;
  s.clock_steps = end.clock_steps;
}

void StatusAssembler::fill_joints_and_text(ServiceState state, const WindowEnd& end) noexcept {
  status_t& s = status_;
  int homed = 0;
  int worst_joint = -1;
  for (int i = 0; i < kJointCount; ++i) {
    const JointTracker& j = pipeline_.joint(i);
    const std::uint32_t flags = facts_.joint_flags_or[static_cast<std::size_t>(i)];
    s.homing[i] = static_cast<std::int8_t>(j.reading().homing);
    s.joint_flags[i] = static_cast<std::int32_t>(flags);
    s.glitches[i] = j.counters().glitches;
    s.lost_count_events[i] = j.counters().lost_count_events;
    s.stale_events[i] = j.counters().stale_events;
    s.out_of_range_events[i] = j.counters().out_of_range_events;
    if (j.reading().homed) ++homed;
    const std::uint32_t faults = flags & joint_flag::kFaults & ~joint_flag::kUnhomed;
    if (faults != 0 && worst_joint < 0) worst_joint = i;
  }
  homed_ = homed;
  // One line for people: snprintf into a stack buffer, assigned within the
  // reserved capacity. "DEGRADED: <cause>; 6/6 homed, ..."
  char text[256];  // status_t.message: at most 255 characters
  constexpr int cap = static_cast<int>(sizeof(text));
  int n = 0;
  // Appends what snprintf wrote, never past the buffer (a cut text stays a text).
  const auto add = [&](int written) { n = std::min(n + std::max(written, 0), cap - 1); };
  const auto rest = [&] { return static_cast<std::size_t>(cap - n); };
  const std::string_view name = messages::state_name(static_cast<std::int8_t>(state));
  add(std::snprintf(text, sizeof(text), "%.*s: ", static_cast<int>(name.size()), name.data()));
  if (cause_.reason != StateReason::kNone) {
    const std::string_view joint =
        cause_.joint >= 0 ? std::string_view(s.joint_name[cause_.joint]) : std::string_view();
    add(static_cast<int>(describe_cause(cause_, joint, text + n, rest())));
    add(std::snprintf(text + n, rest(), "; "));
  }
  // The final status may cover no cycle (docs/messages.md, status_t.seq).
  char valid[40] = "no cycle since the last status";
  if (facts_.cycles > 0) {
    std::snprintf(valid, sizeof(valid), "%.1f%% valid",
                  100.0 * facts_.valid_poses / static_cast<double>(facts_.cycles));
  }
  add(std::snprintf(text + n, rest(), "%d/%d homed, %s, %lld overruns since start", homed,
                    kJointCount, valid, static_cast<long long>(end.overruns)));
  if (worst_joint >= 0 && cause_.reason != StateReason::kJointFault) {
    char flags[192];
    messages::write_joint_flag_names(
        static_cast<std::int32_t>(facts_.joint_flags_or[static_cast<std::size_t>(worst_joint)]),
        flags, sizeof flags);
    add(std::snprintf(text + n, rest(), "; joint %s %s", s.joint_name[worst_joint].c_str(), flags));
  }
  if ((facts_.sample_flags_or & drivers::sample_flag::kClockUnsync) != 0) {
    add(std::snprintf(text + n, rest(), "; clock unsynchronised"));
  }
  if (s.foreign_run_id != 0) {
    add(std::snprintf(text + n, rest(), "; ANOTHER RUN %016llx on these channels",
                      static_cast<unsigned long long>(s.foreign_run_id)));
  }
  n = append_service_text(text, n, cap, end);
  append_publish_text(text, n, cap, state, end);
  s.message.assign(text);
}

void StatusAssembler::fill_source(const WindowEnd& end) noexcept {
  source_status_t& m = source_status_;
  m.utime = status_.utime;
  m.mono_ns = status_.mono_ns;
  m.seq = status_.seq;
  m.counter_count = 0;
  m.state.clear();
  if (end.diagnostics == nullptr) return;
  const drivers::SourceDiagnostics& d = *end.diagnostics;
  // Within the capacity reserved at construction: nothing reallocates.
  m.state.assign(d.state());
  std::size_t i = 0;
  for (const drivers::SourceCounter& c : d.counters()) {
    if (i == m.counter_name.size()) break;
    m.counter_name[i].assign(c.name);
    m.counter_value[i] = c.value;
    ++i;
  }
  m.counter_count = static_cast<std::int16_t>(i);
}

// A new segment in the window, a reload waiting for a restart, log lines lost.
int StatusAssembler::append_service_text(char* text, int n, int cap,
                                         const WindowEnd& end) const noexcept {
  const auto rest = [&] { return n > 0 && n < cap ? static_cast<std::size_t>(cap - n) : 0; };
  if (segment_seq_ >= 0 && rest() > 0) {
    n += std::snprintf(text + n, rest(), "; new segment from seq %lld (calibration or model)",
                       static_cast<long long>(segment_seq_));
  }
  if (restart_pending_ && rest() > 0) {
    n += std::snprintf(text + n, rest(), "; restart pending: config not in effect as a whole");
  }
  if (end.log_lines_dropped > 0 && rest() > 0) {
    n += std::snprintf(text + n, rest(), "; %lld log lines dropped",
                       static_cast<long long>(end.log_lines_dropped));
  }
  return n;
}

// A failing publish path (since which seq, how many lost, why); after it
// recovered, what was lost, for as long as the service stays degraded.
int StatusAssembler::append_publish_text(char* text, int n, int cap, ServiceState state,
                                         const WindowEnd& end) const noexcept {
  if (n <= 0 || n >= cap) return n;
  const PublishHealth& p = end.publish;
  const auto rest = static_cast<std::size_t>(cap - n);
  if (p.failing_since_ns != 0) {
    const char* name = strerrorname_np(p.last_errno);
    return n + std::snprintf(text + n, rest, "; publishing failing since seq %lld: %lld lost (%s)",
                             static_cast<long long>(p.failing_since_seq),
                             static_cast<long long>(p.lost_in_episode),
                             name != nullptr ? name : "error");
  }
  if (p.recoveries > 0 && state == ServiceState::kDegraded &&
      end.now_mono_ns - p.recovered_at_ns < 10'000'000'000) {
    return n + std::snprintf(text + n, rest,
                             "; publishing recovered at seq %lld: %lld lost from seq %lld",
                             static_cast<long long>(p.recovered_to_seq),
                             static_cast<long long>(p.recovered_lost),
                             static_cast<long long>(p.recovered_from_seq));
  }
  return n;
}

}  // namespace exodaq::core
