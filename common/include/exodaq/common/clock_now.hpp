#pragma once
// The clocks, read the same way everywhere (one clock_gettime, no allocation),
// and the one way to sleep until a CLOCK_MONOTONIC instant.
#include <time.h>

#include <atomic>
#include <cerrno>
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

// Sleeps until CLOCK_MONOTONIC reaches mono_ns (an absolute deadline: no
// drift from the time spent before the call). A signal resumes the sleep,
// unless `stop` is given and set (a Ctrl-C handler ends a paced loop at once).
inline void sleep_until_mono(std::int64_t mono_ns,
                             const std::atomic<bool>* stop = nullptr) noexcept {
  const timespec ts{static_cast<time_t>(mono_ns / 1'000'000'000),
                    static_cast<long>(mono_ns % 1'000'000'000)};
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR &&
         (stop == nullptr || !stop->load())) {
  }
}

}  // namespace exodaq
