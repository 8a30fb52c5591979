#include "exodaq/core/health.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstdio>

#include "exodaq/messages/flag_names.hpp"

namespace exodaq::core {

// The log's and the journal's lower-case form of messages::state_name (the one
// table of state names), made once, without allocating.
const char* state_name(ServiceState s) noexcept {
  using Name = std::array<char, 24>;
  static const std::array<Name, 8> kLower = [] {
    std::array<Name, 8> out{};
    for (std::size_t i = 0; i < out.size(); ++i) {
      const std::string_view upper = messages::state_name(static_cast<std::int8_t>(i));
      for (std::size_t c = 0; c < upper.size() && c + 1 < out[i].size(); ++c)
        out[i][c] = static_cast<char>(std::tolower(static_cast<unsigned char>(upper[c])));
    }
    return out;
  }();
  const auto i = static_cast<std::size_t>(static_cast<std::uint8_t>(s));
  return i < kLower.size() ? kLower[i].data() : "unknown";
}

Percentiles TimingWindow::percentiles() noexcept {
  Percentiles p;
  if (n_ == 0) return p;
  auto* begin = values_.data();
  auto* end = begin + n_;
  const auto at = [&](double q) {
    const auto k = static_cast<std::ptrdiff_t>(std::lround(q * static_cast<double>(n_ - 1)));
    std::nth_element(begin, begin + k, end);
    return static_cast<double>(begin[k]) / 1000.0;
  };
  p.p50_us = at(0.50);
  p.p99_us = at(0.99);
  p.max_us = static_cast<double>(*std::max_element(begin, end)) / 1000.0;
  return p;
}

std::string_view reason_name(StateReason r) noexcept {
  switch (r) {
    case StateReason::kNone:
      return "NONE";
    case StateReason::kNoSamples:
      return "NO_SAMPLES";
    case StateReason::kBusDown:
      return "BUS_DOWN";
    case StateReason::kForeignRun:
      return "FOREIGN_RUN";
    case StateReason::kJointFault:
      return "JOINT_FAULT";
    case StateReason::kSampleFlags:
      return "SAMPLE_FLAGS";
    case StateReason::kOverruns:
      return "OVERRUNS";
    case StateReason::kPublishFailures:
      return "PUBLISH_FAILURES";
    case StateReason::kClockHold:
      return "CLOCK_HOLD";
    case StateReason::kRecovering:
      return "RECOVERING";
  }
  return "UNKNOWN_REASON";
}

namespace {

// The sample flags that degrade (FOREIGN_RUN is a reason of its own).
constexpr std::uint32_t kDegradingSamples =
    drivers::sample_flag::kMissing | drivers::sample_flag::kSeqGap |
    drivers::sample_flag::kDuplicate | drivers::sample_flag::kOutOfOrder |
    drivers::sample_flag::kBoardError | drivers::sample_flag::kBusError |
    drivers::sample_flag::kPartial | drivers::sample_flag::kClockStep;

constexpr std::uint32_t bit(StateReason r) {
  return 1U << static_cast<unsigned>(r);
}

// Everything in the window that degrades: the first reason (in the order of
// StateReason) with its facts, the others in `also`. kNone: a clean window.
StateCause degraded_cause(const WindowFacts& f) noexcept {
  StateCause c;
  const auto found = [&](StateReason r) {
    if (c.reason == StateReason::kNone) {
      c.reason = r;
      return true;
    }
    c.also |= bit(r);
    return false;
  };
  if ((f.sample_flags_or & drivers::sample_flag::kForeignRun) != 0) found(StateReason::kForeignRun);
  if (f.overruns > 0 && found(StateReason::kOverruns)) c.value = f.overruns;
  int faulted = 0;
  int first = -1;
  for (int i = 0; i < kJointCount; ++i) {
    const std::uint32_t flags = f.joint_flags_or[static_cast<std::size_t>(i)];
    if ((flags & joint_flag::kFaults & ~joint_flag::kUnhomed) == 0) continue;
    ++faulted;
    if (first < 0) first = i;
  }
  if (faulted > 0 && found(StateReason::kJointFault)) {
    c.joint = first;
    c.flags = f.joint_flags_or[static_cast<std::size_t>(first)];
    c.value = faulted;
  }
  if (const std::uint32_t bad = f.sample_flags_or & kDegradingSamples;
      bad != 0 && found(StateReason::kSampleFlags)) {
    c.flags = bad;
  }
  if (f.publish_failures > 0 && found(StateReason::kPublishFailures)) c.value = f.publish_failures;
  if (f.clock_hold) found(StateReason::kClockHold);
  return c;
}

// snprintf that never runs past `cap`: returns the new length. A fixed text
// goes through "%s" (clang's -Wformat-security in the fuzz build).
template <typename... A>
std::size_t put(char* out, std::size_t n, std::size_t cap, const char* format, A... args) {
  if (n + 1 >= cap) return n;
  const int w = std::snprintf(out + n, cap - n, format, args...);
  if (w < 0) return n;
  return std::min(n + static_cast<std::size_t>(w), cap - 1);
}

}  // namespace

std::size_t describe_cause(const StateCause& c, std::string_view joint_name, char* out,
                           std::size_t cap) noexcept {
  if (cap == 0) return 0;
  out[0] = '\0';
  char window[48] = "in the window";
  if (c.window_ns > 0) {
    std::snprintf(window, sizeof window, "in the last %.1f s window",
                  static_cast<double>(c.window_ns) * 1e-9);
  }
  char flags[192];
  const auto ll = [](std::int64_t v) { return static_cast<long long>(v); };
  std::size_t n = 0;
  switch (c.reason) {
    case StateReason::kNone:
      return 0;
    case StateReason::kNoSamples:
      n = put(out, n, cap, "no sample for %lld ms (threshold %lld ms)", ll(c.value),
              ll(c.threshold));
      break;
    case StateReason::kBusDown: {
      const std::string_view bus = messages::bus_state_name(static_cast<std::int8_t>(c.value));
      n = put(out, n, cap, "bus %.*s: no frame can arrive", static_cast<int>(bus.size()),
              bus.data());
      break;
    }
    case StateReason::kForeignRun:
      n = put(out, n, cap, "%s",
              "another run publishes on these channels (threshold: any status heard)");
      break;
    case StateReason::kJointFault:
      messages::write_joint_flag_names(static_cast<std::int32_t>(c.flags), flags, sizeof flags);
      n = put(out, n, cap, "joint %.*s %s", static_cast<int>(joint_name.size()), joint_name.data(),
              flags);
      if (c.value > 1) n = put(out, n, cap, " and %lld more joint(s)", ll(c.value - 1));
      n = put(out, n, cap, " %s (threshold: any fault flag)", window);
      break;
    case StateReason::kSampleFlags:
      messages::write_sample_flag_names(static_cast<std::int32_t>(c.flags), flags, sizeof flags);
      n = put(out, n, cap, "samples flagged %s %s (threshold: any)", flags, window);
      break;
    case StateReason::kOverruns:
      n = put(out, n, cap, "%lld overrun%s %s (threshold: more than %lld)", ll(c.value),
              c.value == 1 ? "" : "s", window, ll(c.threshold));
      break;
    case StateReason::kPublishFailures:
      n = put(out, n, cap, "%lld message%s not published %s (threshold: more than %lld)",
              ll(c.value), c.value == 1 ? "" : "s", window, ll(c.threshold));
      break;
    case StateReason::kClockHold:
      n = put(out, n, cap, "%s", "clock unsynchronised under clock.require_sync: hold");
      break;
    case StateReason::kRecovering: {
      const std::string_view was = reason_name(c.was);
      n = put(out, n, cap, "recovering from %.*s: %lld of %lld clean windows in a row",
              static_cast<int>(was.size()), was.data(), ll(c.value), ll(c.threshold));
      break;
    }
  }
  const char* sep = " (also ";
  for (unsigned r = 0; r < 32; ++r) {
    if ((c.also & (1U << r)) == 0) continue;
    const std::string_view name = reason_name(static_cast<StateReason>(r));
    n = put(out, n, cap, "%s%.*s", sep, static_cast<int>(name.size()), name.data());
    sep = ", ";
  }
  if (c.also != 0) n = put(out, n, cap, "%s", ")");
  return n;
}

Verdict judge(ServiceState current, const WindowFacts& f, std::int64_t ms_since_last_sample,
              std::int64_t fault_after_ms) noexcept {
  if (current == ServiceState::kStopping) return {current, {}};
  const bool bus_dead =
      f.bus_state == drivers::BusState::kOff || f.bus_state == drivers::BusState::kDown;
  if (ms_since_last_sample > fault_after_ms || bus_dead) {
    // Nothing has ever arrived: still starting, unless the bus itself is dead.
    if (current == ServiceState::kStarting && !bus_dead) return {current, {}};
    StateCause c;
    if (bus_dead) {
      c.reason = StateReason::kBusDown;
      c.value = static_cast<std::int64_t>(f.bus_state);
    } else {
      c.reason = StateReason::kNoSamples;
      c.value = ms_since_last_sample;
      c.threshold = fault_after_ms;
    }
    return {ServiceState::kFault, c};
  }
  const StateCause degraded = degraded_cause(f);
  // Another run on our channels: degraded, whatever homing says (docs/operations.md).
  if (degraded.reason == StateReason::kForeignRun) return {ServiceState::kDegraded, degraded};
  if (f.samples_present == 0 && current == ServiceState::kStarting) return {current, {}};
  if (!f.all_homed) return {ServiceState::kHoming, {}};
  if (degraded.reason == StateReason::kNone) return {ServiceState::kRunning, {}};
  return {ServiceState::kDegraded, degraded};
}

ServiceState ServiceStateMachine::next(ServiceState current, const WindowFacts& facts,
                                       std::int64_t ms_since_last_sample) noexcept {
  if (current == ServiceState::kStopping) {
    cause_ = {};
    return current;
  }
  Verdict v = judge(current, facts, ms_since_last_sample, settings_.fault_after_ms);
  if (settings_.hold_fault_while_samples && facts.samples_present > 0 &&
      v.state == ServiceState::kFault) {
    v = {current, cause_};
  }
  if (v.state == ServiceState::kDegraded && v.cause.reason != StateReason::kRecovering) {
    last_reason_ = v.cause.reason;
  }
  clean_windows_ = v.state == ServiceState::kRunning ? clean_windows_ + 1 : 0;
  if (v.state == ServiceState::kRunning && current == ServiceState::kDegraded &&
      clean_windows_ < settings_.clean_windows_to_recover) {
    v.state = current;
    v.cause = {};
    v.cause.reason = StateReason::kRecovering;
    v.cause.value = clean_windows_;
    v.cause.threshold = settings_.clean_windows_to_recover;
    v.cause.was = last_reason_;
  }
  cause_ = v.cause;
  return v.state;
}

}  // namespace exodaq::core
