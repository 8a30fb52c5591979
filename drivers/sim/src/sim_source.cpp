#include "exodaq/drivers/sim_source.hpp"

#include <time.h>

#include <algorithm>
#include <cmath>

#include "exodaq/common/clock_now.hpp"

namespace exodaq::drivers {
namespace {

BoardDecoderConfig decoder_config(const SimOptions& o) {
  BoardDecoderConfig c;
  c.ids = o.board.ids;
  return c;
}

}  // namespace

SimSource::SimSource(const SimOptions& options)
    : options_(options), rig_(options), decoder_(decoder_config(options)) {}

void SimSource::start() {
  rig_ = sim::SimRig(options_);  // rewind the encoders to power-up
  decoder_.reset();
  pending_n_ = 0;
  cycle_ = 0;
  last_read_s_ = -1.0;
  last_now_ns_ = 0;
  last_delivered_mono_ns_ = 0;
  const std::int64_t mono = mono_now_ns();
  start_mono_ns_ = options_.start_mono_ns != 0 ? options_.start_mono_ns : mono;
  wall_offset_ns_ =
      options_.wall_offset_ns != 0 ? options_.wall_offset_ns : clock_ns(CLOCK_REALTIME) - mono;
}

void SimSource::queue_frames(int n) noexcept {
  for (int i = 0; i < n; ++i) {
    const can::CanFrame& f = frames_[static_cast<std::size_t>(i)];
    if (pending_n_ == kPendingCapacity) {  // cannot happen (delays < kMaxDelayPeriods)
      decoder_.on_frame(f);
      continue;
    }
    int at = pending_n_++;  // keep bus order: by stamp, stable
    for (; at > 0 && pending_[static_cast<std::size_t>(at - 1)].mono_ns > f.mono_ns; --at) {
      pending_[static_cast<std::size_t>(at)] = pending_[static_cast<std::size_t>(at - 1)];
    }
    pending_[static_cast<std::size_t>(at)] = f;
  }
}

bool SimSource::feed_one(std::int64_t until_mono_ns) noexcept {
  if (pending_n_ == 0 || pending_[0].mono_ns > until_mono_ns) return false;
  decoder_.on_frame(pending_[0]);
  for (int i = 1; i < pending_n_; ++i) {
    pending_[static_cast<std::size_t>(i - 1)] = pending_[static_cast<std::size_t>(i)];
  }
  --pending_n_;
  return true;
}

ReadStatus SimSource::read(const CycleTime& time, EncoderSample& out) noexcept {
  return options_.board_clock.free_running ? read_free_running(time, out) : read_aligned(time, out);
}

ReadStatus SimSource::read_aligned(const CycleTime& time, EncoderSample& out) noexcept {
  // The simulated board free-runs with the loop's deadlines: cycle k is the
  // loop's cycle k, so a deadline the loop skipped (overrun) is a board cycle
  // nobody read, seen by the decoder as a sequence gap, and sample k is always
  // taken at t_k = k * period. Callers that do not count cycles get 0, 1, 2...
  const std::int64_t k = time.cycle > cycle_ ? time.cycle : cycle_;
  if (cycle_ == 0 && options_.start_mono_ns == 0 && time.deadline_mono_ns > 0) {
    // The board samples at the loop's deadlines: sample k is taken at deadline
    // k, so stamps and the loop's clock agree (t_k = k * period still holds).
    start_mono_ns_ = time.deadline_mono_ns - k * options_.period_ns;
  }
  cycle_ = k + 1;
  stall_if_due(rig_.sample_time_s(k));
  queue_frames(rig_.step(k, frames_, start_mono_ns_, wall_offset_ns_));
  // The reader waits half a period for the cycle (jitter stays below that).
  while (feed_one(start_mono_ns_ + k * options_.period_ns + options_.period_ns / 2)) {
  }
  if (decoder_.poll_newest(out) >= 0 || decoder_.flush(out)) return ReadStatus::kSample;
  const std::int64_t mono = start_mono_ns_ + rig_.sample_offset_ns(k);
  decoder_.make_missing(out, mono, mono + wall_offset_ns_);
  return ReadStatus::kNoSample;
}

void SimSource::run_board_until(std::int64_t until, bool first_only) noexcept {
  // Room for what one more board cycle (and frames held back) can complete.
  constexpr int kRoom = BoardDecoder::kQueueCapacity - 8;
  for (;;) {
    while (decoder_.queued() < kRoom && feed_one(until)) {
      if (first_only && decoder_.queued() > 0) return;
    }
    if (decoder_.queued() >= kRoom) return;  // the rest waits on the bus, as in a socket
    if (start_mono_ns_ + rig_.sample_offset_ns(cycle_) > until) return;
    queue_frames(rig_.step(cycle_, frames_, start_mono_ns_, wall_offset_ns_));
    ++cycle_;
  }
}

ReadStatus SimSource::read_free_running(const CycleTime& time, EncoderSample& out) noexcept {
  const std::int64_t period = options_.period_ns;
  if (cycle_ == 0 && last_now_ns_ == 0 && options_.start_mono_ns == 0 &&
      time.deadline_mono_ns > 0) {
    start_mono_ns_ = time.deadline_mono_ns;  // the board powers up with the loop's first deadline
  }
  std::int64_t now = std::max(std::max(time.now_mono_ns, time.deadline_mono_ns), last_now_ns_);
  now += stall_if_due(sim_time_s(now));  // a stalled reader comes back later
  last_now_ns_ = now;
  run_board_until(now, false);
  std::int64_t waited = now;
  if (!time.catch_up && decoder_.queued() == 0) {
    // Nothing yet: the reader waits (simulated) up to half a period past the
    // deadline for the next cycle, as the socketcan backend waits for its poll deadline.
    waited = std::max(now, time.deadline_mono_ns + period / 2);
    run_board_until(waited, true);
  }
  if (decoder_.poll_sample(out)) {
    last_delivered_mono_ns_ = out.mono_ns;
    return ReadStatus::kSample;
  }
  if (time.catch_up) return ReadStatus::kNothingDue;
  if (decoder_.has_partial() && waited - decoder_.partial_mono_ns() > period / 2 &&
      decoder_.flush(out)) {
    last_delivered_mono_ns_ = out.mono_ns;
    return ReadStatus::kSample;
  }
  if (!free_running_board_overdue(decoder_, last_delivered_mono_ns_, waited, period))
    return ReadStatus::kNothingDue;
  decoder_.make_missing(out, time.deadline_mono_ns, time.deadline_mono_ns + wall_offset_ns_);
  return ReadStatus::kNoSample;
}

void SimSource::diagnose(SourceDiagnostics& out) const noexcept {
  out.add("board_cycles", cycle_);
  decoder_.diagnose(out);
  out.set_state(options_.board_clock.free_running ? "simulated board, free-running clock"
                                                  : "simulated board, aligned clock");
}

int SimSource::backlog() const noexcept {
  if (!options_.board_clock.free_running) return 0;
  const bool more = (pending_n_ > 0 && pending_[0].mono_ns <= last_now_ns_) ||
                    start_mono_ns_ + rig_.sample_offset_ns(cycle_) <= last_now_ns_;
  return decoder_.queued() + (more ? 1 : 0);
}

std::int64_t SimSource::stall_if_due(double t_s) noexcept {
  std::int64_t slept = 0;
  for (const sim::SimFault& f : options_.faults) {
    if (f.kind == sim::SimFault::Kind::kStall && last_read_s_ < f.start_s && t_s >= f.start_s) {
      const auto ns = static_cast<std::int64_t>(std::llround(f.duration_s * 1e9));
      sleep_until_mono(mono_now_ns() + ns);
      slept += ns;
    }
  }
  last_read_s_ = t_s;
  return slept;
}

}  // namespace exodaq::drivers
