#pragma once
// Sample time: maps CLOCK_MONOTONIC sample instants to NTP-aligned wall time
// (utime) so that a stream never runs backwards, NTP's slews pass through and a
// step of the system clock is detected, counted, flagged and slewed out at a
// bounded rate. Clock health comes from ntp_adjtime(), read off the loop
// thread. See docs/time.md.
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <thread>

#include "exodaq/settings/service_settings.hpp"

namespace exodaq::core {

struct ClockHealth {
  bool valid = false;         // ntp_adjtime() answered
  bool synchronised = false;  // within the policy's error bounds
  bool unsync_flag = true;    // STA_UNSYNC as the kernel reports it
  double est_error_us = 0.0;
  double max_error_us = 0.0;
  double offset_us = 0.0;
  int time_state = 0;  // ntp_adjtime return value (TIME_OK, TIME_ERROR, ...)
};

// The two clocks and the kernel's NTP state. Injectable so tests can step,
// slew and unsynchronise the wall clock deterministically.
class ClockSource {
 public:
  virtual ~ClockSource() = default;
  virtual std::int64_t mono_ns() noexcept = 0;
  virtual std::int64_t wall_ns() noexcept = 0;
  virtual ClockHealth ntp_health() noexcept = 0;  // fills everything but `synchronised`
};

// The real clocks: clock_gettime and read-only ntp_adjtime.
std::unique_ptr<ClockSource> make_system_clock();

// The policy is part of the service configuration (settings library).
using settings::ClockPolicy;
using settings::RequireSync;

// Latest offset (wall - mono) and health, written by ClockMonitor's thread,
// read by the loop with relaxed atomics (no lock, no syscall).
struct ClockShared {
  std::atomic<std::int64_t> offset_ns{0};
  std::atomic<std::int64_t> offset_generation{0};
  std::atomic<bool> synchronised{false};
  std::atomic<bool> health_valid{false};
  std::atomic<double> est_error_us{0.0};
  std::atomic<double> max_error_us{0.0};
  std::atomic<double> ntp_offset_us{0.0};
};

// Off the loop thread: measures the wall - mono offset at 10 Hz (the tightest
// of three bracketed readings) and reads ntp_adjtime() once a second.
class ClockMonitor {
 public:
  ClockMonitor(ClockSource& clock, const ClockPolicy& policy, ClockShared& shared);
  ~ClockMonitor();
  ClockMonitor(const ClockMonitor&) = delete;
  ClockMonitor& operator=(const ClockMonitor&) = delete;

  void measure_offset() noexcept;  // one offset measurement (also called by the thread)
  void read_health() noexcept;     // one ntp_adjtime read
  void start();                    // the 10 Hz thread
  void stop() noexcept;
  void set_policy(const ClockPolicy& policy) noexcept;

 private:
  void run();

  ClockSource& clock_;
  ClockShared& shared_;
  std::atomic<double> max_est_error_us_;
  std::atomic<double> max_max_error_us_;
  std::mutex mutex_;
  std::condition_variable wake_;
  bool stopping_ = false;
  std::thread thread_;
};

// On the loop thread: turns a sample's mono_ns into utime. Never runs
// backwards; a step is slewed out at policy.step_slew_ppm while samples are
// flagged; ordinary changes are tracked at policy.slew_ppm. A sample's own
// wall stamp (the kernel's receive time of its CAN frame), given as `wall_ns`,
// is utime itself while it agrees with the mapping within kStampAgreementNs:
// the driver's and the clock monitor's REALTIME - MONOTONIC estimates differ
// by their brackets' noise, which must not move utime off the kernel stamp.
class WallTimeMapper {
 public:
  void set_policy(const ClockPolicy& policy) noexcept { policy_ = policy; }

  struct Result {
    std::int64_t utime_us = 0;
    bool stepping = false;  // a step is being absorbed: utime may be off by more than the threshold
    bool new_step = false;  // a step was detected at this sample
  };
  static constexpr std::int64_t kStampAgreementNs = 10'000;
  Result map(std::int64_t mono_ns, std::int64_t target_offset_ns, std::int64_t target_generation,
             std::int64_t wall_ns = 0) noexcept;

  std::int64_t steps() const noexcept { return steps_; }
  // utime minus the measured wall clock at the last sample (the correction still to slew out).
  std::int64_t pending_correction_ns() const noexcept { return applied_ - last_target_; }

 private:
  ClockPolicy policy_;
  bool started_ = false;
  std::int64_t applied_ = 0;
  std::int64_t last_mono_ = 0;
  std::int64_t last_utime_ns_ = 0;
  std::int64_t last_target_ = 0;
  std::int64_t last_generation_ = -1;
  std::int64_t steps_ = 0;
  bool stepping_ = false;
};

}  // namespace exodaq::core
