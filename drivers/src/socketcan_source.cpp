#include "exodaq/drivers/socketcan_source.hpp"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

namespace exodaq::drivers {
SocketCanSource::SocketCanSource(const SocketCanSourceConfig& config, std::unique_ptr<CanPort> port)
    : config_(config), port_(std::move(port)), decoder_(config.decoder) {
  if (!port_) throw std::invalid_argument("socketcan: no CAN port");
  if (config_.read_deadline_ns <= 0) {
    throw std::invalid_argument("socketcan: read deadline must be positive");
  }
}

void SocketCanSource::start() {
  decoder_.reset();
  detail_ = SocketCanDetail{};
  up_ = false;
  offset_valid_ = false;
  offset_width_ns_ = INT64_MAX;
  newest_complete_mono_ = 0;
  partial_since_mono_ = 0;
  socket_may_hold_more_ = false;
  last_delivered_mono_ = 0;
  measure_offset();
  last_open_attempt_mono_ = port_->now_mono_ns();
  const int r = port_->open();
  if (r == 0) {
    up_ = true;
    detail_.open = true;
    decoder_.set_bus_state(BusState::kUnknown);
    return;
  }
  detail_.last_errno = -r;
  if (is_interface_loss(-r)) {
    // Not there yet (or down): run degraded and keep retrying.
    decoder_.set_bus_state(BusState::kDown);
    return;
  }
  throw std::runtime_error("socketcan: cannot open " + config_.port.interface + ": " +
                           std::strerror(-r));
}

void SocketCanSource::diagnose(SourceDiagnostics& out) const noexcept {
  const SocketCanDetail d = detail();
  out.add("sync_sent", d.sync_sent);
  out.add("sync_send_failures", d.sync_send_failures);
  out.add("late_syncs", d.late_syncs);
  out.add("partial_flushes", d.partial_flushes);
  out.add("unstamped_frames", d.unstamped_frames);
  out.add("interface_losses", d.interface_losses);
  out.add("reopen_attempts", d.reopen_attempts);
  out.add("reopens", d.reopens);
  out.add("receive_errors", d.receive_errors);
  decoder_.diagnose(out);
  char text[SourceDiagnostics::kMaxStateBytes];
  const char* err = d.last_errno != 0 ? strerrorname_np(d.last_errno) : nullptr;
  if (d.open) {
    std::snprintf(text, sizeof text, "%s open%s%s", config_.port.interface.c_str(),
                  err != nullptr ? ", last error " : "", err != nullptr ? err : "");
  } else {
    std::snprintf(text, sizeof text, "%s down: %s", config_.port.interface.c_str(),
                  err != nullptr ? err : "not opened");
  }
  out.set_state(text);
}

void SocketCanSource::stop() noexcept {
  port_->close();
  up_ = false;
  detail_.open = false;
}

void SocketCanSource::measure_offset() noexcept {
  // mono, wall, mono: the wall reading belongs to the bracket's midpoint.
  // CLOCK_REALTIME − CLOCK_MONOTONIC only changes when the wall clock is
  // stepped (NTP slews both), so the tightest bracket seen is kept until a
  // reading differs by more than both brackets' widths + 1 µs (a step).
  const std::int64_t m0 = port_->now_mono_ns();
  const std::int64_t w = port_->now_wall_ns();
  const std::int64_t m1 = port_->now_mono_ns();
  const std::int64_t width = m1 - m0;
  const std::int64_t offset = w - (m0 + width / 2);
  if (!offset_valid_ || width <= offset_width_ns_ ||
      std::llabs(offset - offset_ns_) > offset_width_ns_ + width + 1000) {
    offset_ns_ = offset;
    offset_width_ns_ = width;
    offset_valid_ = true;
  }
  detail_.offset_ns = offset_ns_;
}

bool SocketCanSource::try_open(std::int64_t now_mono) noexcept {
  if (now_mono - last_open_attempt_mono_ < config_.reopen_interval_ns) return false;
  last_open_attempt_mono_ = now_mono;
  ++detail_.reopen_attempts;
  const int r = port_->open();
  if (r != 0) {
    detail_.last_errno = -r;
    return false;
  }
  up_ = true;
  detail_.open = true;
  ++detail_.reopens;
  // Active again with the next frame the decoder accepts.
  decoder_.set_bus_state(BusState::kUnknown);
  return true;
}

void SocketCanSource::go_down(int err) noexcept {
  port_->close();
  if (up_) ++detail_.interface_losses;
  up_ = false;
  detail_.open = false;
  detail_.last_errno = err;
  decoder_.set_bus_state(BusState::kDown);
  last_open_attempt_mono_ = port_->now_mono_ns();
}

void SocketCanSource::feed(const can::CanFrame& frame) noexcept {
  const int queued = decoder_.queued();
  const std::int64_t overflows = decoder_.detail().queue_overflows;
  const bool had_partial = decoder_.has_partial();
  decoder_.on_frame(frame);
  const bool completed =
      decoder_.queued() > queued || decoder_.detail().queue_overflows > overflows;
  if (completed) newest_complete_mono_ = frame.mono_ns;
  if (decoder_.has_partial() && (!had_partial || completed)) partial_since_mono_ = frame.mono_ns;
}

bool SocketCanSource::drain() noexcept {
  socket_may_hold_more_ = false;
  for (;;) {
    if (!config_.sync_master && decoder_.queued() >= kRefillBelow) {
      socket_may_hold_more_ = true;  // the socket keeps the rest until there is room
      return true;
    }
    CanRxInfo info;
    const int n = port_->receive(rx_.data(), kBatch, info);
    if (n < 0) {
      if (n == -EAGAIN || n == -EWOULDBLOCK || n == -EINTR) return true;
      if (is_interface_loss(-n)) {
        go_down(-n);
        return false;
      }
      ++detail_.receive_errors;
      detail_.last_errno = -n;
      return true;
    }
    if (info.dropped > 0) decoder_.add_rx_overflows(info.dropped);
    for (int i = 0; i < n; ++i) {
      can::CanFrame& f = rx_[static_cast<std::size_t>(i)];
      if (f.wall_ns == 0) {
        ++detail_.unstamped_frames;
        f.wall_ns = port_->now_wall_ns();
      }
      f.mono_ns = f.wall_ns - offset_ns_;
      feed(f);
    }
    if (n < kBatch) return true;
  }
}

bool SocketCanSource::have_current(std::int64_t sync_mono) const noexcept {
  if (decoder_.queued() == 0) return false;
  // Sync master: the cycle must have been received after this cycle's SYNC.
  return !config_.sync_master || newest_complete_mono_ >= sync_mono;
}

void SocketCanSource::send_sync() noexcept {
  const int r = port_->send(can::encode_sync(config_.port.ids));
  if (r == 0) {
    ++detail_.sync_sent;
  } else if (is_interface_loss(-r)) {
    go_down(-r);
  } else {
    ++detail_.sync_send_failures;  // EAGAIN / ENOBUFS: TX queue full, never waited for
    detail_.last_errno = -r;
  }
}

void SocketCanSource::receive_until(std::int64_t poll_deadline, std::int64_t sync_mono) noexcept {
  while (up_) {
    if (!drain()) return;
    if (have_current(sync_mono)) return;
    if (port_->now_mono_ns() >= poll_deadline) return;
    const int r = port_->wait_readable(poll_deadline);
    if (r == 0) {
      drain();  // a frame may have slipped in at the deadline
      return;
    }
    if (r < 0) {
      if (r == -EINTR) continue;
      if (is_interface_loss(-r)) {
        go_down(-r);
      } else {
        ++detail_.receive_errors;
        detail_.last_errno = -r;
      }
      return;
    }
  }
}

bool SocketCanSource::flush_partial(bool got, std::int64_t sync_mono, std::int64_t period,
                                    EncoderSample& out) noexcept {
  if (!decoder_.has_partial()) return false;
  const bool flush = config_.sync_master
                         // Only one half answered this cycle's SYNC by the deadline.
                         ? !got || newest_complete_mono_ < sync_mono
                         // Free-running: the other half is overdue by now.
                         : port_->now_mono_ns() - partial_since_mono_ > period / 2;
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
  if (config_.sync_master || !up_) return 0;
  return decoder_.queued() + (socket_may_hold_more_ ? 1 : 0);
}

std::int64_t SocketCanSource::poll_deadline(std::int64_t from, std::int64_t period) const noexcept {
  // Wait for a cycle until the read deadline, never past the end of the
  // cycle minus a guard of a tenth of the period.
  return std::min(from + config_.read_deadline_ns, from + period - period / 10);
}

ReadStatus SocketCanSource::read(const CycleTime& time, EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  const std::int64_t period = time.period_ns > 0 ? time.period_ns : 1'000'000;
  measure_offset();
  const std::int64_t now = port_->now_mono_ns();
  if (!up_ && !try_open(now)) {
    if (time.catch_up) return ReadStatus::kNothingDue;
    decoder_.make_missing(out, start, start + offset_ns_);
    return ReadStatus::kNoSample;
  }
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
  const std::int64_t sync_mono = now;
  send_sync();
  receive_until(poll_deadline(late ? now : start, period), sync_mono);
  const bool got = decoder_.poll_newest(out) >= 0;  // older complete cycles are superseded
  if (flush_partial(got, sync_mono, period, out) || got) return ReadStatus::kSample;
  decoder_.make_missing(out, start, start + offset_ns_);
  return ReadStatus::kNoSample;
}

ReadStatus SocketCanSource::read_free_running(const CycleTime& time, std::int64_t period,
                                              EncoderSample& out) noexcept {
  const std::int64_t start = time.deadline_mono_ns;
  if (time.catch_up) {
    drain();
  } else {
    receive_until(poll_deadline(start, period), 0);
  }
  if (take_queued(period, out)) return ReadStatus::kSample;
  if (time.catch_up) return ReadStatus::kNothingDue;
  if (up_) {
    // Not overdue yet: the board's clock drifted just past this wake, the next
    // wake brings two. Overdue at `now`: whatever reached the socket before
    // `now` (the reader may have been descheduled since its last look) is
    // taken first; only then MISSING, every wake.
    if (!free_running_board_overdue(decoder_, last_delivered_mono_, port_->now_mono_ns(), period))
      return ReadStatus::kNothingDue;
    if (drain() && take_queued(period, out)) return ReadStatus::kSample;
  }
  decoder_.make_missing(out, start, start + offset_ns_);
  return ReadStatus::kNoSample;
}

bool SocketCanSource::take_queued(std::int64_t period, EncoderSample& out) noexcept {
  // Every complete cycle, oldest first: none is superseded.
  if (!decoder_.poll_sample(out) && !flush_partial(false, 0, period, out)) return false;
  last_delivered_mono_ = out.mono_ns;
  return true;
}

}  // namespace exodaq::drivers
