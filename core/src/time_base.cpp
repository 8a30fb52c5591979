#include "exodaq/core/time_base.hpp"

#include <time.h>

#include <cerrno>

#include "exodaq/common/clock_now.hpp"

namespace exodaq::core {

namespace {
class MonotonicLoopClock final : public LoopClock {
 public:
  std::int64_t now_ns() noexcept override { return mono_now_ns(); }
  void sleep_until(std::int64_t deadline_ns) noexcept override { sleep_until_mono(deadline_ns); }
};
}  // namespace

std::unique_ptr<LoopClock> make_monotonic_loop_clock() {
  return std::make_unique<MonotonicLoopClock>();
}

LiveTimeBase::LiveTimeBase(const ClockShared& clock, const ClockPolicy& policy,
                           std::int64_t period_ns, LoopClock& loop_clock)
    : clock_(clock), period_ns_(period_ns), loop_clock_(loop_clock) {
  set_policy(policy);
}

void LiveTimeBase::set_policy(const ClockPolicy& policy) noexcept {
  policy_ = policy;
  mapper_.set_policy(policy);
}

std::int64_t LiveTimeBase::wait(std::int64_t deadline_ns) noexcept {
  loop_clock_.sleep_until(deadline_ns);
  return deadline_ns;
}

std::int64_t LiveTimeBase::overrun(std::int64_t end_ns,
                                   std::int64_t next_deadline_ns) const noexcept {
  if (end_ns <= next_deadline_ns) return 0;
  return (end_ns - next_deadline_ns) / period_ns_ + 1;
}

SampleTime LiveTimeBase::stamp(const drivers::EncoderSample& sample) noexcept {
  SampleTime t;
  const auto mapped =
      mapper_.map(sample.mono_ns, clock_.offset_ns.load(std::memory_order_relaxed),
                  clock_.offset_generation.load(std::memory_order_acquire), sample.wall_ns);
  t.utime_us = mapped.utime_us;
  t.new_step = mapped.new_step;
  if (mapped.stepping) {
    t.flags |= drivers::sample_flag::kClockStep;
    t.clock_invalid = true;
  }
  const bool unsync = !clock_.synchronised.load(std::memory_order_relaxed);
  if (unsync && policy_.require_sync != RequireSync::kIgnore) {
    t.flags |= drivers::sample_flag::kClockUnsync;
    if (policy_.require_sync == RequireSync::kHold) t.clock_invalid = true;
  }
  t.clock_hold = unsync && policy_.require_sync == RequireSync::kHold;
  return t;
}

RecordedTimeBase::RecordedTimeBase(const drivers::EncoderSource& source, double speed,
                                   const ClockPolicy& policy, LoopClock& loop_clock)
    : source_(source), speed_(speed), policy_(policy), loop_clock_(loop_clock) {}

std::int64_t RecordedTimeBase::wait(std::int64_t deadline_ns) noexcept {
  const std::int64_t next = source_.next_sample_mono_ns();
  if (next < 0) {
    loop_clock_.sleep_until(deadline_ns);
    return deadline_ns;
  }
  if (first_recorded_ns_ < 0) {
    first_recorded_ns_ = next;
    start_ns_ = loop_clock_.now_ns();
  }
  if (!(speed_ > 0.0)) return loop_clock_.now_ns();
  const std::int64_t due = start_ns_ + static_cast<std::int64_t>(
                                           static_cast<double>(next - first_recorded_ns_) / speed_);
  loop_clock_.sleep_until(due);
  return due;
}

std::int64_t RecordedTimeBase::seq(std::int64_t counted) const noexcept {
  // The recording's cycle numbers, gaps from the live run's overruns included.
  const std::int64_t recorded = source_.recorded_seq();
  return recorded >= 0 ? recorded : counted;
}

SampleTime RecordedTimeBase::stamp(const drivers::EncoderSample& sample) noexcept {
  SampleTime t;
  t.utime_us = sample.wall_ns / 1000;
  t.flags = drivers::sample_flag::kReplay;
  // The live run's clock verdict, carried in the recorded flags.
  t.clock_invalid = (sample.flags & drivers::sample_flag::kClockStep) != 0 ||
                    ((sample.flags & drivers::sample_flag::kClockUnsync) != 0 &&
                     policy_.require_sync == RequireSync::kHold);
  return t;
}

std::unique_ptr<TimeBase> make_time_base(const drivers::EncoderSource& source,
                                         const ClockShared& clock, const ClockPolicy& policy,
                                         std::int64_t period_ns, LoopClock& loop_clock) {
  if (const auto speed = source.recording_speed())
    return std::make_unique<RecordedTimeBase>(source, *speed, policy, loop_clock);
  return std::make_unique<LiveTimeBase>(clock, policy, period_ns, loop_clock);
}

}  // namespace exodaq::core
