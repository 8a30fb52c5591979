#pragma once
// An in-memory CanPort with a simulated clock: frames are scheduled at an
// arrival time on CLOCK_MONOTONIC and become receivable (stamped with that
// time as the "kernel" receive timestamp) once the port's clock reaches it.
// wait_readable() advances the clock to the next arrival or to the deadline,
// so a test runs the SocketCAN backend's real read() deterministically and
// instantly. Interface loss, send errors and kernel drops are switches;
// `admit` stands for the kernel's CAN_RAW_FILTER (a frame it refuses is never
// queued), so several ports can share one simulated bus (test_two_boards.cpp).
// Allocation-free after construction (fixed ring, reserved send log).
#include <array>
#include <cerrno>
#include <cstdint>
#include <functional>
#include <vector>

#include "exodaq/drivers/can_port.hpp"

namespace exodaq::test {

class MemoryCanPort final : public drivers::CanPort {
 public:
  using Frame = drivers::can::CanFrame;
  static constexpr std::int64_t kWallOffsetNs = 1'700'000'000'000'000'000 - 5'000'000'000;

  MemoryCanPort() { sent.reserve(1 << 16); }

  // --- test controls ------------------------------------------------------
  std::int64_t mono = 5'000'000'000;  // the port's CLOCK_MONOTONIC, ns
  bool exists = true;                 // interface present (open() → −ENODEV)
  bool up = true;                     // interface up (open() → −ENETDOWN)
  bool stamp = true;                  // give kernel timestamps
  int open_error = 0;                 // forced open() error (e.g. EAFNOSUPPORT)
  int send_error = 0;                 // every send() fails with this while set
  std::int64_t pending_drops = 0;     // reported by the next receive (SO_RXQ_OVFL)
  bool receive_own = false;           // each frame sent comes back flagged kOwn, stamped then
  std::int64_t send_delay_ns = 0;  // a send happens this long after the clock's reading (preempted)
  int open_calls = 0;
  std::vector<Frame> sent;
  // Called before each clock reading, may move `mono` on (not allocation-free).
  std::function<void(MemoryCanPort&)> on_now;
  // Called by wait_readable() first: a simulated peer may run up to the
  // deadline, pushing what it sends (not allocation-free).
  std::function<void(MemoryCanPort&, std::int64_t deadline)> on_wait;
  // Called for each frame sent (e.g. a board answering SYNC).
  std::function<void(const Frame&, MemoryCanPort&)> on_send;
  // The socket's receive filter: frames it refuses are not queued (empty: all
  // are), counted in `filtered`.
  std::function<bool(const Frame&)> admit;
  std::int64_t filtered = 0;

  void advance_to(std::int64_t t) noexcept {
    if (t > mono) mono = t;
  }
  // Schedules a frame to arrive at `arrival_mono`, stamped then.
  void push(const Frame& f, std::int64_t arrival_mono) noexcept {
    push(f, arrival_mono, arrival_mono);
  }
  // A frame the kernel stamped at `stamp_mono` (as it entered the stack) but
  // queued to the socket only at `arrival_mono` (a receive softirq deferred to
  // ksoftirqd, a vCPU held off by the host between the two).
  void push(const Frame& f, std::int64_t arrival_mono, std::int64_t stamp_mono) noexcept {
    if (admit && !admit(f)) {
      ++filtered;
      return;
    }
    Slot& s = ring_[static_cast<std::size_t>((head_ + size_) % kRing)];
    s.frame = f;
    s.arrival = arrival_mono;
    s.stamp = stamp_mono;
    ++size_;
  }
  // The interface goes down: the socket reports −ENETDOWN once, queued frames are lost.
  void take_down() noexcept {
    up = false;
    pending_error_ = ENETDOWN;
    size_ = 0;
  }
  // The interface disappears (rmmod, USB adapter unplugged).
  void remove() noexcept {
    exists = false;
    up = false;
    pending_error_ = ENODEV;
    size_ = 0;
  }
  void bring_up() noexcept {
    exists = true;
    up = true;
  }
  int queued() const noexcept { return size_; }
  bool is_open() const noexcept override { return open_; }

  // --- CanPort ------------------------------------------------------------
  int open() noexcept override {
    ++open_calls;
    open_ = false;
    if (open_error != 0) return -open_error;
    if (!exists) return -ENODEV;
    if (!up) return -ENETDOWN;
    open_ = true;
    pending_error_ = 0;
    return 0;
  }
  void close() noexcept override { open_ = false; }

  int receive(Frame* frames, int max, drivers::CanRxInfo& info) noexcept override {
    if (!open_) return -EBADF;
    if (pending_error_ != 0) {
      const int e = pending_error_;
      pending_error_ = 0;
      return -e;
    }
    info.dropped = pending_drops;
    pending_drops = 0;
    int n = 0;
    while (n < max && size_ > 0 && front().arrival <= mono) {
      Frame f = front().frame;
      f.wall_ns = stamp ? front().stamp + kWallOffsetNs : 0;
      f.mono_ns = 0;
      if (!stamp) ++info.unstamped;
      frames[n++] = f;
      head_ = (head_ + 1) % kRing;
      --size_;
    }
    return n;
  }

  int send(const Frame& frame) noexcept override {
    if (!open_) return -EBADF;
    if (send_error != 0) return -send_error;
    mono += send_delay_ns;
    sent.push_back(frame);
    if (receive_own) {
      Frame own = frame;
      own.flags |= drivers::can::frame_flag::kOwn;
      push(own, mono);
    }
    if (on_send) on_send(frame, *this);
    return 0;
  }

  int wait_readable(std::int64_t deadline) noexcept override {
    if (!open_) return -EBADF;
    if (pending_error_ != 0) return 1;
    if (on_wait) on_wait(*this, deadline);
    if (size_ > 0 && front().arrival <= deadline) {
      advance_to(front().arrival);
      return 1;
    }
    advance_to(deadline);
    return 0;
  }

  std::int64_t now_mono_ns() noexcept override {
    if (on_now) on_now(*this);  // e.g. the reader descheduled just before it reads the clock
    return mono;
  }
  std::int64_t now_wall_ns() noexcept override { return mono + kWallOffsetNs; }

 private:
  static constexpr int kRing = 8192;
  struct Slot {
    Frame frame{};
    std::int64_t arrival = 0;
    std::int64_t stamp = 0;
  };
  const Slot& front() const noexcept { return ring_[static_cast<std::size_t>(head_)]; }

  std::array<Slot, kRing> ring_{};
  int head_ = 0;
  int size_ = 0;
  bool open_ = false;
  int pending_error_ = 0;
};

}  // namespace exodaq::test
