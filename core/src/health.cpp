#include "exodaq/core/health.hpp"

#include <algorithm>
#include <cmath>

namespace exodaq::core {

const char* state_name(ServiceState s) noexcept {
  switch (s) {
    case ServiceState::kStarting:
      return "starting";
    case ServiceState::kHoming:
      return "homing";
    case ServiceState::kRunning:
      return "running";
    case ServiceState::kDegraded:
      return "degraded";
    case ServiceState::kFault:
      return "fault";
    case ServiceState::kStopping:
      return "stopping";
  }
  return "unknown";
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

ServiceState next_state(ServiceState current, const WindowFacts& f,
                        std::int64_t ms_since_last_sample, std::int64_t fault_after_ms) noexcept {
  if (current == ServiceState::kStopping) return current;
  const bool bus_dead =
      f.bus_state == drivers::BusState::kOff || f.bus_state == drivers::BusState::kDown;
  if (ms_since_last_sample > fault_after_ms || bus_dead) {
    // Nothing has ever arrived: still starting, unless the bus itself is dead.
    if (current == ServiceState::kStarting && !bus_dead) return current;
    return ServiceState::kFault;
  }
  if (f.samples_present == 0 && current == ServiceState::kStarting) return current;
  if (!f.all_homed) return ServiceState::kHoming;
  std::uint32_t joint_faults = 0;
  for (auto flags : f.joint_flags_or)
    joint_faults |= flags & joint_flag::kFaults & ~joint_flag::kUnhomed;
  const std::uint32_t bad_samples =
      drivers::sample_flag::kMissing | drivers::sample_flag::kSeqGap |
      drivers::sample_flag::kDuplicate | drivers::sample_flag::kOutOfOrder |
      drivers::sample_flag::kBoardError | drivers::sample_flag::kBusError |
      drivers::sample_flag::kPartial | drivers::sample_flag::kClockStep;
  const bool clean = joint_faults == 0 && (f.sample_flags_or & bad_samples) == 0 &&
                     f.overruns == 0 && f.publish_failures == 0 && !f.clock_hold;
  return clean ? ServiceState::kRunning : ServiceState::kDegraded;
}

ServiceState ServiceStateMachine::next(ServiceState current, const WindowFacts& facts,
                                       std::int64_t ms_since_last_sample) noexcept {
  if (current == ServiceState::kStopping) return current;
  ServiceState next = next_state(current, facts, ms_since_last_sample, settings_.fault_after_ms);
  if (settings_.hold_fault_while_samples && facts.samples_present > 0 &&
      next == ServiceState::kFault) {
    next = current;
  }
  clean_windows_ = next == ServiceState::kRunning ? clean_windows_ + 1 : 0;
  if (next == ServiceState::kRunning && current == ServiceState::kDegraded &&
      clean_windows_ < settings_.clean_windows_to_recover) {
    next = current;
  }
  return next;
}

}  // namespace exodaq::core
