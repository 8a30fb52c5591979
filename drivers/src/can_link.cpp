#include "exodaq/drivers/can_link.hpp"

#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>
#include <utility>

namespace exodaq::drivers {

CanLink::CanLink(std::unique_ptr<CanPort> port, std::string interface,
                 std::int64_t reopen_interval_ns)
    : port_(std::move(port)),
      interface_(std::move(interface)),
      reopen_interval_ns_(reopen_interval_ns) {
  if (!port_) throw std::invalid_argument("CAN link: no CAN port");
}

bool CanLink::start() {
  stats_ = CanLinkStats{};
  up_ = false;
  socket_may_hold_more_ = false;
  offset_.reset();
  offset_.measure(*port_);
  stats_.offset_ns = offset_.ns();
  last_open_attempt_mono_ = port_->now_mono_ns();
  const int r = port_->open();
  if (r == 0) {
    up_ = true;
    stats_.open = true;
    return true;
  }
  stats_.last_errno = -r;
  if (is_interface_loss(-r)) return false;  // not there yet (or down): keep retrying
  throw std::runtime_error("socketcan: cannot open " + interface_ + ": " + std::strerror(-r));
}

void CanLink::stop() noexcept {
  port_->close();
  up_ = false;
  stats_.open = false;
}

void WallMonoOffset::measure(CanPort& port) noexcept {
  const std::int64_t m0 = port.now_mono_ns();
  const std::int64_t w = port.now_wall_ns();
  const std::int64_t m1 = port.now_mono_ns();
  const std::int64_t width = m1 - m0;
  const std::int64_t offset = w - (m0 + width / 2);
  if (!valid_ || width <= width_ns_ || std::llabs(offset - ns_) > width_ns_ + width + 1000) {
    ns_ = offset;
    width_ns_ = width;
    valid_ = true;
  }
}

bool CanLink::poll_open(FrameSink& sink) noexcept {
  offset_.measure(*port_);
  stats_.offset_ns = offset_.ns();
  if (up_) return true;
  const std::int64_t now = port_->now_mono_ns();
  if (now - last_open_attempt_mono_ < reopen_interval_ns_) return false;
  last_open_attempt_mono_ = now;
  ++stats_.reopen_attempts;
  const int r = port_->open();
  if (r != 0) {
    stats_.last_errno = -r;
    return false;
  }
  up_ = true;
  stats_.open = true;
  ++stats_.reopens;
  sink.on_link(true);
  return true;
}

void CanLink::go_down(int err, FrameSink& sink) noexcept {
  port_->close();
  const bool was_up = up_;
  if (was_up) ++stats_.interface_losses;
  up_ = false;
  stats_.open = false;
  stats_.last_errno = err;
  last_open_attempt_mono_ = port_->now_mono_ns();
  sink.on_link(false);
}

bool CanLink::drain(FrameSink& sink) noexcept {
  socket_may_hold_more_ = false;
  while (up_) {
    if (!sink.wants_more()) {
      socket_may_hold_more_ = true;  // the socket keeps the rest until there is room
      return true;
    }
    CanRxInfo info;
    const int n = port_->receive(rx_.data(), kBatch, info);
    if (n < 0) {
      if (n == -EAGAIN || n == -EWOULDBLOCK || n == -EINTR) return true;
      if (is_interface_loss(-n)) {
        go_down(-n, sink);
        return false;
      }
      ++stats_.receive_errors;
      stats_.last_errno = -n;
      return true;
    }
    if (info.dropped > 0) sink.on_rx_overflows(info.dropped);
    for (int i = 0; i < n; ++i) {
      can::CanFrame& f = rx_[static_cast<std::size_t>(i)];
      if (f.wall_ns == 0) {
        ++stats_.unstamped_frames;
        f.wall_ns = port_->now_wall_ns();
      }
      f.mono_ns = f.wall_ns - offset_.ns();
      sink.on_frame(f);
    }
    if (n < kBatch) return true;
  }
  return false;
}

void CanLink::receive_until(std::int64_t deadline, FrameSink& sink) noexcept {
  while (up_) {
    if (!drain(sink)) return;
    if (sink.satisfied()) return;
    if (port_->now_mono_ns() >= deadline) return;
    const int r = port_->wait_readable(deadline);
    if (r == 0) {
      drain(sink);  // a frame may have slipped in at the deadline
      return;
    }
    if (r < 0) {
      if (r == -EINTR) continue;
      if (is_interface_loss(-r)) {
        go_down(-r, sink);
      } else {
        ++stats_.receive_errors;
        stats_.last_errno = -r;
      }
      return;
    }
  }
}

int CanLink::send(const can::CanFrame& frame, FrameSink& sink) noexcept {
  if (!up_) return -ENETDOWN;
  const int r = port_->send(frame);
  if (r == 0) return 0;
  if (is_interface_loss(-r)) {
    go_down(-r, sink);
  } else {
    stats_.last_errno = -r;
  }
  return r;
}

void CanLink::diagnose(SourceDiagnostics& out) const noexcept {
  out.add("unstamped_frames", stats_.unstamped_frames);
  out.add("interface_losses", stats_.interface_losses);
  out.add("reopen_attempts", stats_.reopen_attempts);
  out.add("reopens", stats_.reopens);
  out.add("receive_errors", stats_.receive_errors);
  char text[SourceDiagnostics::kMaxStateBytes];
  const int e = stats_.last_errno;
  const char* err = e != 0 ? strerrorname_np(e) : nullptr;
  if (stats_.open) {
    std::snprintf(text, sizeof text, "%s open%s%s", interface_.c_str(),
                  err != nullptr ? ", last error " : "", err != nullptr ? err : "");
  } else {
    std::snprintf(text, sizeof text, "%s down: %s", interface_.c_str(),
                  err != nullptr ? err : "not opened");
  }
  out.set_state(text);
}

}  // namespace exodaq::drivers
