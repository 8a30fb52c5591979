#pragma once
// The SocketCAN transport every CAN protocol's source uses: a CanPort opened
// with the protocol's identifier filters, re-opened after the interface is
// lost (at most once per reopen interval, without blocking), its frames
// stamped on both clocks from the kernel's receive stamp, received in
// batches, waited for until a deadline, and sent without blocking. The
// protocol sees what arrives through a FrameSink; the link knows nothing of
// any protocol. Loop thread, one owner; allocation-free after construction.
// docs/can-protocol.md ("The socketcan backend").
#include <array>
#include <cstdint>
#include <memory>
#include <string>

#include "exodaq/drivers/can_frame.hpp"
#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/drivers/source_diagnostics.hpp"

namespace exodaq::drivers {

// What a protocol implements to receive from a CanLink.
class FrameSink {
 public:
  // A received frame; mono_ns and wall_ns are its receive stamp.
  virtual void on_frame(const can::CanFrame& frame) noexcept = 0;
  // Frames the kernel dropped on the socket since the last receive.
  virtual void on_rx_overflows(std::int64_t dropped) noexcept = 0;
  // The interface was lost (false) or the port re-opened (true).
  virtual void on_link(bool up) noexcept = 0;
  // false: stop receiving for now (the socket keeps the rest: the deep buffer).
  virtual bool wants_more() const noexcept { return true; }
  // true: a wait for frames may end (what the protocol waited for arrived).
  virtual bool satisfied() const noexcept { return false; }

 protected:
  ~FrameSink() = default;
};

// CLOCK_REALTIME − CLOCK_MONOTONIC, for moving the kernel's realtime receive
// stamps to the monotonic clock. Each measure() reads mono, wall, mono: the
// wall reading belongs to the bracket's midpoint. The offset only changes
// when the wall clock is stepped (NTP slews both), so the tightest bracket
// seen is kept (a reading preempted between the clocks changes nothing)
// until a reading differs by more than both brackets' widths + 1 µs: a step.
class WallMonoOffset {
 public:
  void reset() noexcept { valid_ = false; }
  void measure(CanPort& port) noexcept;
  std::int64_t ns() const noexcept { return ns_; }

 private:
  std::int64_t ns_ = 0;
  std::int64_t width_ns_ = 0;
  bool valid_ = false;
};

// The link's own counters (the protocol counts its frames itself).
struct CanLinkStats {
  std::int64_t unstamped_frames = 0;  // no kernel timestamp: stamped with the read time
  std::int64_t interface_losses = 0;  // transitions to down
  std::int64_t reopen_attempts = 0;
  std::int64_t reopens = 0;  // successful re-opens after a loss
  std::int64_t receive_errors = 0;
  int last_errno = 0;
  bool open = false;
  std::int64_t offset_ns = 0;  // CLOCK_REALTIME − CLOCK_MONOTONIC in use
};

class CanLink {
 public:
  static constexpr int kBatch = 32;

  CanLink(std::unique_ptr<CanPort> port, std::string interface,
          std::int64_t reopen_interval_ns = 1'000'000'000);

  // Opens the port. true: up. false: the interface is missing or down, the
  // link stays down and keeps retrying (poll_open). Other failures (no CAN
  // in the kernel: EAFNOSUPPORT) throw std::runtime_error naming the interface.
  bool start();
  void stop() noexcept;

  // Once per loop wake: refreshes the wall − mono offset and, when down and
  // the reopen interval has passed, tries to re-open (sink.on_link(true)).
  // Returns whether the link is up.
  bool poll_open(FrameSink& sink) noexcept;
  bool up() const noexcept { return up_; }

  // Receives every queued frame while sink.wants_more(); false when the link
  // went down doing so (sink.on_link(false)).
  bool drain(FrameSink& sink) noexcept;
  // Drains, then waits for frames until sink.satisfied() or the absolute
  // CLOCK_MONOTONIC deadline.
  void receive_until(std::int64_t deadline_mono_ns, FrameSink& sink) noexcept;
  // The last drain stopped because the sink wanted no more, not because the
  // socket was empty.
  bool socket_may_hold_more() const noexcept { return socket_may_hold_more_; }

  // Sends one frame without blocking: 0, or −errno (−EAGAIN/−ENOBUFS: the TX
  // queue is full). An interface loss takes the link down (sink.on_link(false)).
  int send(const can::CanFrame& frame, FrameSink& sink) noexcept;

  std::int64_t now_mono_ns() noexcept { return port_->now_mono_ns(); }
  std::int64_t offset_ns() const noexcept { return offset_.ns(); }  // wall − mono
  const std::string& interface() const noexcept { return interface_; }
  const CanLinkStats& stats() const noexcept { return stats_; }

  // The counters as named ones, and the state: "can0 open" or "can0 down: ENODEV".
  void diagnose(SourceDiagnostics& out) const noexcept;

 private:
  void go_down(int err, FrameSink& sink) noexcept;

  std::unique_ptr<CanPort> port_;
  std::string interface_;
  std::int64_t reopen_interval_ns_;
  CanLinkStats stats_{};
  std::array<can::CanFrame, kBatch> rx_{};
  bool up_ = false;
  bool socket_may_hold_more_ = false;
  std::int64_t last_open_attempt_mono_ = 0;
  WallMonoOffset offset_;
};

}  // namespace exodaq::drivers
