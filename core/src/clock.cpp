#include "exodaq/core/clock.hpp"

#include <sys/timex.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>

#include "exodaq/common/clock_now.hpp"

namespace exodaq::core {

namespace {
class SystemClock final : public ClockSource {
 public:
  std::int64_t mono_ns() noexcept override { return clock_ns(CLOCK_MONOTONIC); }
  std::int64_t wall_ns() noexcept override { return clock_ns(CLOCK_REALTIME); }
  ClockHealth ntp_health() noexcept override {
    ClockHealth h;
    timex tx{};
    tx.modes = 0;  // read only: needs no privilege and no CAP_SYS_TIME
    const int state = ntp_adjtime(&tx);
    if (state < 0) return h;
    h.valid = true;
    h.time_state = state;
    h.unsync_flag = (tx.status & STA_UNSYNC) != 0;
    h.est_error_us = static_cast<double>(tx.esterror);
    h.max_error_us = static_cast<double>(tx.maxerror);
    // offset is in us, or ns when STA_NANO is set.
    h.offset_us = (tx.status & STA_NANO) != 0 ? static_cast<double>(tx.offset) / 1000.0
                                              : static_cast<double>(tx.offset);
    return h;
  }
};
}  // namespace

std::unique_ptr<ClockSource> make_system_clock() {
  return std::make_unique<SystemClock>();
}

ClockMonitor::ClockMonitor(ClockSource& clock, const ClockPolicy& policy, ClockShared& shared)
    : clock_(clock),
      shared_(shared),
      max_est_error_us_(policy.max_est_error_us),
      max_max_error_us_(policy.max_max_error_us) {
  measure_offset();
  read_health();
}

ClockMonitor::~ClockMonitor() {
  stop();
}

void ClockMonitor::set_policy(const ClockPolicy& policy) noexcept {
  max_est_error_us_.store(policy.max_est_error_us);
  max_max_error_us_.store(policy.max_max_error_us);
}

void ClockMonitor::measure_offset() noexcept {
  // mono, wall, mono: the wall reading belongs to the midpoint; keep the
  // tightest bracket of three so a preemption does not bias the offset.
  std::int64_t best_width = INT64_MAX;
  std::int64_t best_offset = 0;
  for (int i = 0; i < 3; ++i) {
    const std::int64_t m0 = clock_.mono_ns();
    const std::int64_t w = clock_.wall_ns();
    const std::int64_t m1 = clock_.mono_ns();
    if (m1 - m0 < best_width) {
      best_width = m1 - m0;
      best_offset = w - (m0 + (m1 - m0) / 2);
    }
  }
  shared_.offset_ns.store(best_offset, std::memory_order_relaxed);
  shared_.offset_generation.fetch_add(1, std::memory_order_release);
}

void ClockMonitor::read_health() noexcept {
  const ClockHealth h = clock_.ntp_health();
  // chrony leaves STA_UNSYNC set unless rtcsync is on, so the error bounds are
  // the primary signal (docs/time.md).
  const bool sync = h.valid && h.est_error_us <= max_est_error_us_.load() &&
                    h.max_error_us <= max_max_error_us_.load();
  shared_.health_valid.store(h.valid, std::memory_order_relaxed);
  shared_.est_error_us.store(h.est_error_us, std::memory_order_relaxed);
  shared_.max_error_us.store(h.max_error_us, std::memory_order_relaxed);
  shared_.ntp_offset_us.store(h.offset_us, std::memory_order_relaxed);
  shared_.synchronised.store(sync, std::memory_order_relaxed);
}

void ClockMonitor::start() {
  stopping_ = false;
  thread_ = std::thread([this] { run(); });
}

void ClockMonitor::stop() noexcept {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void ClockMonitor::run() {
  int tick = 0;
  std::unique_lock<std::mutex> lock(mutex_);
  while (!stopping_) {
    wake_.wait_for(lock, std::chrono::milliseconds(100), [this] { return stopping_; });
    if (stopping_) break;
    lock.unlock();
    measure_offset();
    if (++tick % 10 == 0) read_health();
    lock.lock();
  }
}

namespace {
// The sample's own wall stamp when it has one that agrees with the mapping.
std::int64_t stamp_or_mapped(std::int64_t mapped_ns, std::int64_t wall_ns) noexcept {
  const bool agrees =
      wall_ns > 0 && std::llabs(wall_ns - mapped_ns) <= WallTimeMapper::kStampAgreementNs;
  return agrees ? wall_ns : mapped_ns;
}
}  // namespace

WallTimeMapper::Result WallTimeMapper::map(std::int64_t mono_ns, std::int64_t target,
                                           std::int64_t generation, std::int64_t wall_ns) noexcept {
  Result r;
  if (!started_) {
    started_ = true;
    applied_ = target;
    last_mono_ = mono_ns;
    last_target_ = target;
    last_generation_ = generation;
    last_utime_ns_ = stamp_or_mapped(mono_ns + applied_, wall_ns);
    r.utime_us = last_utime_ns_ / 1000;
    return r;
  }
  const std::int64_t dt = std::max<std::int64_t>(mono_ns - last_mono_, 0);
  last_mono_ = mono_ns;
  if (generation != last_generation_) {
    // A fresh offset measurement: a jump larger than the threshold relative to
    // the previous measurement is a step of the system clock.
    if (std::llabs(target - last_target_) > policy_.step_threshold_ns) {
      ++steps_;
      r.new_step = true;
    }
    last_generation_ = generation;
    last_target_ = target;
  }
  // A step (or a large initial error) is slewed out at the step rate until
  // fully absorbed; samples are flagged while utime is further than the
  // threshold from the measured wall clock.
  const std::int64_t diff = target - applied_;
  if (std::llabs(diff) > policy_.step_threshold_ns) stepping_ = true;
  const double ppm = stepping_ ? policy_.step_slew_ppm : policy_.slew_ppm;
  const auto max_change =
      static_cast<std::int64_t>(std::ceil(static_cast<double>(dt) * ppm * 1e-6));
  applied_ += std::clamp(diff, -max_change, max_change);
  if (applied_ == target) stepping_ = false;
  const bool off = std::llabs(target - applied_) > policy_.step_threshold_ns;
  std::int64_t utime_ns = mono_ns + applied_;
  if (!off && !r.new_step) utime_ns = stamp_or_mapped(utime_ns, wall_ns);
  if (utime_ns < last_utime_ns_) utime_ns = last_utime_ns_;  // never backwards
  last_utime_ns_ = utime_ns;
  r.utime_us = utime_ns / 1000;
  r.stepping = off || r.new_step;
  return r;
}

}  // namespace exodaq::core
