#include "exodaq/drivers/socketcan_source.hpp"

#include <algorithm>
#include <cerrno>
#include <stdexcept>
#include <utility>

namespace exodaq::drivers {
SocketCanSource::SocketCanSource(const SocketCanSourceConfig& config, std::unique_ptr<CanPort> port)
    : config_(config),
      link_(std::move(port), config.port.interface, config.reopen_interval_ns),
      decoder_(config.decoder) {
  if (config_.read_deadline_ns <= 0) {
    throw std::invalid_argument("socketcan: read deadline must be positive");
  }
}

void SocketCanSource::start() {
  decoder_.reset();
  detail_ = SocketCanDetail{};
  newest_complete_mono_ = 0;
  partial_since_mono_ = 0;
  last_delivered_mono_ = 0;
  // Not there yet (or down): run degraded and keep retrying.
  decoder_.set_bus_state(link_.start() ? BusState::kUnknown : BusState::kDown);
}

SocketCanDetail SocketCanSource::detail() const noexcept {
  SocketCanDetail d = detail_;
  d.superseded_samples = decoder_.stats().superseded_samples;  // the decoder counts them
  d.link = link_.stats();
  return d;
}

void SocketCanSource::diagnose(SourceDiagnostics& out) const noexcept {
  out.add("sync_sent", detail_.sync_sent);
  out.add("sync_send_failures", detail_.sync_send_failures);
  out.add("late_syncs", detail_.late_syncs);
  out.add("partial_flushes", detail_.partial_flushes);
  link_.diagnose(out);
  decoder_.diagnose(out);
}

void SocketCanSource::stop() noexcept {
  link_.stop();
}

void SocketCanSource::on_frame(const can::CanFrame& frame) noexcept {
  const int queued = decoder_.queued();
  const std::int64_t overflows = decoder_.detail().queue_overflows;
  const bool had_partial = decoder_.has_partial();
  decoder_.on_frame(frame);
  const bool completed =
      decoder_.queued() > queued || decoder_.detail().queue_overflows > overflows;
  if (completed) newest_complete_mono_ = frame.mono_ns;
  if (decoder_.has_partial() && (!had_partial || completed)) partial_since_mono_ = frame.mono_ns;
}

void SocketCanSource::on_rx_overflows(std::int64_t dropped) noexcept {
  decoder_.add_rx_overflows(dropped);
}

void SocketCanSource::on_link(bool up) noexcept {
  // Back up: active again with the next frame the decoder accepts.
  decoder_.set_bus_state(up ? BusState::kUnknown : BusState::kDown);
}

bool SocketCanSource::wants_more() const noexcept {
  return config_.sync_master || decoder_.queued() < kRefillBelow;
}

bool SocketCanSource::satisfied() const noexcept {
  if (decoder_.queued() == 0) return false;
  // Sync master: the cycle must have been received after this cycle's SYNC.
  return !config_.sync_master || newest_complete_mono_ >= sync_mono_;
}

void SocketCanSource::send_sync() noexcept {
  const int r = link_.send(can::encode_sync(config_.decoder.ids), *this);
  if (r == 0) {
    ++detail_.sync_sent;
  } else if (!is_interface_loss(-r)) {
    ++detail_.sync_send_failures;  // EAGAIN / ENOBUFS: TX queue full, never waited for
  }
}

bool SocketCanSource::flush_partial(bool got, std::int64_t sync_mono, std::int64_t period,
                                    EncoderSample& out) noexcept {
  if (!decoder_.has_partial()) return false;
  const bool flush = config_.sync_master
                         // Only one half answered this cycle's SYNC by the deadline.
                         ? !got || newest_complete_mono_ < sync_mono
                         // Free-running: the other half is overdue by now.
                         : link_.now_mono_ns() - partial_since_mono_ > period / 2;
  if (!flush) return false;
  if (!got) {
    if (!decoder_.flush(out)) return false;
    ++detail_.partial_flushes;
    return true;
  }
  if (decoder_.flush(scratch_)) {
    merge_superseded(out, scratch_);
    out = scratch_;
    decoder_.count_superseded(1);
    ++detail_.partial_flushes;
  }
  return true;
}

int SocketCanSource::backlog() const noexcept {
  if (config_.sync_master || !link_.up()) return 0;
  return decoder_.queued() + (link_.socket_may_hold_more() ? 1 : 0);
}

std::int64_t SocketCanSource::poll_deadline(std::int64_t from, std::int64_t period) const noexcept {
  // Wait for a cycle until the read deadline, never past the end of the
  // cycle minus a guard of a tenth of the period.
  return std::min(from + config_.read_deadline_ns, from + period - period / 10);
}

ReadStatus SocketCanSource::read(const CycleTime& time, EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  const std::int64_t period = time.period_ns > 0 ? time.period_ns : 1'000'000;
  if (!link_.poll_open(*this)) {
    if (time.catch_up) return ReadStatus::kNothingDue;
    decoder_.make_missing(out, start, start + link_.offset_ns());
    return ReadStatus::kNoSample;
  }
  const std::int64_t now = link_.now_mono_ns();
  return config_.sync_master ? read_sync_master(time, period, now, out)
                             : read_free_running(time, period, out);
}

ReadStatus SocketCanSource::read_sync_master(const CycleTime& time, std::int64_t period,
                                             std::int64_t now, EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  if (time.catch_up) return ReadStatus::kNothingDue;  // one SYNC, one sample
  // The board samples when the SYNC arrives: a late SYNC moves the sample
  // instant (stamped truthfully, the receive stamp of its count frames), and
  // the answer is waited for from the SYNC on, not from the missed deadline.
  const bool late = now - start > period / 10;
  if (late) ++detail_.late_syncs;
  sync_mono_ = now;
  send_sync();
  link_.receive_until(poll_deadline(late ? now : start, period), *this);
  const bool got = decoder_.poll_newest(out) >= 0;  // older complete cycles are superseded
  if (flush_partial(got, sync_mono_, period, out) || got) return ReadStatus::kSample;
  decoder_.make_missing(out, start, start + link_.offset_ns());
  return ReadStatus::kNoSample;
}

ReadStatus SocketCanSource::read_free_running(const CycleTime& time, std::int64_t period,
                                              EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  sync_mono_ = 0;
  if (time.catch_up) {
    link_.drain(*this);
  } else {
    link_.receive_until(poll_deadline(start, period), *this);
  }
  if (take_queued(period, out)) return ReadStatus::kSample;
  if (time.catch_up) return ReadStatus::kNothingDue;
  if (link_.up()) {
    // Not overdue yet: the board's clock drifted just past this wake, the next
    // wake brings two. Overdue at `now`: whatever reached the socket before
    // `now` (the reader may have been descheduled since its last look) is
    // taken first; only then MISSING, every wake.
    if (!free_running_board_overdue(decoder_, last_delivered_mono_, link_.now_mono_ns(), period))
      return ReadStatus::kNothingDue;
    if (link_.drain(*this) && take_queued(period, out)) return ReadStatus::kSample;
  }
  decoder_.make_missing(out, start, start + link_.offset_ns());
  return ReadStatus::kNoSample;
}

bool SocketCanSource::take_queued(std::int64_t period, EncoderSample& out) noexcept {
  // Every complete cycle, oldest first: none is superseded.
  if (!decoder_.poll_sample(out) && !flush_partial(false, 0, period, out)) return false;
  last_delivered_mono_ = out.mono_ns;
  return true;
}

}  // namespace exodaq::drivers
