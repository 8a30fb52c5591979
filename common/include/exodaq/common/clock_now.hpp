#pragma once
// The clocks, read the same way everywhere (one clock_gettime, no allocation).
#include <time.h>

#include <cstdint>

namespace exodaq {

inline std::int64_t clock_ns(clockid_t clock) noexcept {
  timespec ts{};
  clock_gettime(clock, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

// CLOCK_MONOTONIC, ns.
inline std::int64_t mono_now_ns() noexcept {
  return clock_ns(CLOCK_MONOTONIC);
}

// CLOCK_REALTIME, us since the Unix epoch (LCM's utime).
inline std::int64_t wall_now_us() noexcept {
  return clock_ns(CLOCK_REALTIME) / 1000;
}

}  // namespace exodaq
