#pragma once
// The loop's time policy: when a cycle starts, which seq it carries and how
// its sample is stamped. LiveTimeBase: CLOCK_MONOTONIC deadlines, NTP-aligned
// utime (WallTimeMapper over ClockShared). RecordedTimeBase: paced by the
// recording (at its speed, or flat out), its utime, seq and clock verdict kept.
// Loop thread only; nothing allocates, only wait() blocks. See docs/time.md.
#include <cstdint>
#include <memory>

#include "exodaq/core/clock.hpp"
#include "exodaq/drivers/encoder_source.hpp"

namespace exodaq::core {

// The loop's own clock: CLOCK_MONOTONIC now, and sleeping to an absolute
// deadline. Injectable (AcquisitionOptions::loop_clock), so tests run the live
// loop on a simulated clock and stall it (a wake that comes late) without a
// hook in the loop itself.
class LoopClock {
 public:
  virtual ~LoopClock() = default;
  virtual std::int64_t now_ns() noexcept = 0;
  virtual void sleep_until(std::int64_t deadline_ns) noexcept = 0;  // absolute, CLOCK_MONOTONIC
};

// clock_gettime / clock_nanosleep(TIMER_ABSTIME) on CLOCK_MONOTONIC.
std::unique_ptr<LoopClock> make_monotonic_loop_clock();

// What the time base says about one sample.
struct SampleTime {
  std::int64_t utime_us = 0;
  std::uint32_t flags = 0;     // sample_flag bits it adds: REPLAY, CLOCK_STEP, CLOCK_UNSYNC
  bool clock_invalid = false;  // the clock policy makes this sample's pose invalid
  bool clock_hold = false;     // unsynchronised under require_sync: hold
  bool new_step = false;       // a wall-clock step was detected at this sample
};

class TimeBase {
 public:
  virtual ~TimeBase() = default;

  // Sleeps until the cycle planned for `deadline_ns` may start; returns the
  // deadline that cycle runs against.
  virtual std::int64_t wait(std::int64_t deadline_ns) noexcept = 0;
  // The loop clock's now (CLOCK_MONOTONIC, or the injected clock).
  virtual std::int64_t now() noexcept = 0;
  // Deadlines a cycle ending at `end_ns` overran (`next_deadline_ns` included):
  // skipped, not run. 0 when it ended in time or the time base never skips.
  virtual std::int64_t overrun(std::int64_t end_ns,
                               std::int64_t next_deadline_ns) const noexcept = 0;
  // The seq of the sample just read, given the loop's own count.
  virtual std::int64_t seq(std::int64_t counted) const noexcept = 0;
  virtual SampleTime stamp(const drivers::EncoderSample& sample) noexcept = 0;
  virtual void set_policy(const ClockPolicy& policy) noexcept = 0;

  // utime minus the measured wall clock (the correction still to slew out),
  // and the wall-clock steps seen.
  virtual std::int64_t utime_correction_ns() const noexcept { return 0; }
  virtual std::int64_t clock_steps() const noexcept { return 0; }
  // A recording's time: a window with samples is never a dead source.
  virtual bool recorded() const noexcept = 0;
};

class LiveTimeBase final : public TimeBase {
 public:
  LiveTimeBase(const ClockShared& clock, const ClockPolicy& policy, std::int64_t period_ns,
               LoopClock& loop_clock);
  std::int64_t wait(std::int64_t deadline_ns) noexcept override;
  std::int64_t now() noexcept override { return loop_clock_.now_ns(); }
  std::int64_t overrun(std::int64_t end_ns, std::int64_t next_deadline_ns) const noexcept override;
  std::int64_t seq(std::int64_t counted) const noexcept override { return counted; }
  SampleTime stamp(const drivers::EncoderSample& sample) noexcept override;
  void set_policy(const ClockPolicy& policy) noexcept override;
  std::int64_t utime_correction_ns() const noexcept override {
    return mapper_.pending_correction_ns();
  }
  std::int64_t clock_steps() const noexcept override { return mapper_.steps(); }
  bool recorded() const noexcept override { return false; }

 private:
  const ClockShared& clock_;
  ClockPolicy policy_;
  std::int64_t period_ns_;
  LoopClock& loop_clock_;
  WallTimeMapper mapper_;
};

class RecordedTimeBase final : public TimeBase {
 public:
  // `speed`: x real time; <= 0 as fast as possible.
  RecordedTimeBase(const drivers::EncoderSource& source, double speed, const ClockPolicy& policy,
                   LoopClock& loop_clock);
  std::int64_t wait(std::int64_t deadline_ns) noexcept override;
  std::int64_t now() noexcept override { return loop_clock_.now_ns(); }
  std::int64_t overrun(std::int64_t, std::int64_t) const noexcept override { return 0; }
  std::int64_t seq(std::int64_t counted) const noexcept override;
  SampleTime stamp(const drivers::EncoderSample& sample) noexcept override;
  void set_policy(const ClockPolicy& policy) noexcept override { policy_ = policy; }
  bool recorded() const noexcept override { return true; }

 private:
  const drivers::EncoderSource& source_;
  double speed_;
  ClockPolicy policy_;
  LoopClock& loop_clock_;
  std::int64_t first_recorded_ns_ = -1;
  std::int64_t start_ns_ = 0;
};

// The recording's time when the source plays one (recording_speed()), else live.
std::unique_ptr<TimeBase> make_time_base(const drivers::EncoderSource& source,
                                         const ClockShared& clock, const ClockPolicy& policy,
                                         std::int64_t period_ns, LoopClock& loop_clock);

}  // namespace exodaq::core
