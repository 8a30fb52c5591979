#pragma once
// The clock part of status_t for people (exodaq status, exodaq echo). The
// kernel reports an error bound of 16 s when it has no estimate (no NTP
// source): that is "unknown", not a measurement. With the daemon's config
// known, an unsynchronised clock under `clock.require_sync: ignore` (the
// simulated rig) is said to be ignored rather than shouted.
#include <cstdio>
#include <optional>
#include <string>

#include "exodaq/messages/csv.hpp"
#include "exodaq/settings/service_settings.hpp"
#include "exodaq/status_t.hpp"

namespace exodaq::tools {

inline constexpr double kKernelUnknownErrorUs = 16'000'000.0;  // NTP_PHASE_LIMIT-derived

// The kernel's estimate, or nothing when it has none (16 s and more).
inline bool clock_error_known(double us) {
  return us < kKernelUnknownErrorUs;
}

inline std::string clock_error_text(double us) {
  if (!clock_error_known(us)) return "unknown";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.1f us", us);
  return buf;
}

// For JSON: the number, or null when unknown.
inline std::string clock_error_json(double us) {
  if (!clock_error_known(us)) return "null";
  return messages::csv::number(us);
}

// "synchronised", "NOT SYNCHRONISED" or "not synchronised (ignored: clock.require_sync: ignore)".
inline std::string clock_state_text(const status_t& s,
                                    std::optional<settings::RequireSync> policy) {
  if (s.clock_synchronised) return "synchronised";
  if (policy == settings::RequireSync::kIgnore) {
    return "not synchronised (ignored: clock.require_sync: ignore)";
  }
  return "NOT SYNCHRONISED";
}

}  // namespace exodaq::tools
