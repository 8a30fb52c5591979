#pragma once
// The seam between the SocketCAN backend and the kernel: everything the
// backend does with a CAN socket and the clocks goes through CanPort, so tests
// drive the backend's frame handling and state machine with an in-memory port
// (tests/can/memory_can_port.hpp) on every machine, and only the socket calls
// themselves need a kernel with CAN (tests/vm).
//
// Every call is non-blocking except wait_readable(), which blocks at most until
// the given absolute CLOCK_MONOTONIC deadline. Error returns are negative errno
// values (−ENETDOWN, −ENODEV, −EAGAIN, …), never exceptions.
#include <cerrno>
#include <cstdint>
#include <memory>
#include <string>

#include "exodaq/drivers/can_frame.hpp"

namespace exodaq::drivers {

// What a receive call learnt besides the frames.
struct CanRxInfo {
  // Frames the kernel dropped on this socket since the previous receive call
  // (SO_RXQ_OVFL delta; the port keeps the cumulative counter).
  std::int64_t dropped = 0;
  // Frames returned without a kernel receive timestamp (stamped 0).
  int unstamped = 0;
};

// How the port was opened: the protocol's identifier filters (the frames
// it wants; every other node's traffic stays in the kernel) and buffers.
struct CanPortConfig {
  std::string interface = "can0";
  can::CanIdFilterSet filters{};
  int rcvbuf_bytes = 1 << 20;
  // Also receive the frames this socket sends (flag kOwn), stamped by the
  // kernel as they go on the bus: a SYNC's true instant.
  bool receive_own = false;
};

class CanPort {
 public:
  virtual ~CanPort() = default;
  CanPort() = default;
  CanPort(const CanPort&) = delete;
  CanPort& operator=(const CanPort&) = delete;

  // (Re)opens the port: closes any previous socket, then socket, filters,
  // error filter, timestamps, SO_RXQ_OVFL, SO_RCVBUF, bind. Returns 0 when the
  // port is open and the interface is up; −ENODEV when the interface does not
  // exist, −ENETDOWN when it exists but is down (the port is left closed), or
  // another −errno. Never blocks; a handful of syscalls.
  virtual int open() noexcept = 0;
  virtual void close() noexcept = 0;
  virtual bool is_open() const noexcept = 0;

  // Receives up to `max` frames that are already queued. Each frame's wall_ns
  // is the kernel receive timestamp (CLOCK_REALTIME) or 0 when the kernel gave
  // none; mono_ns is left 0 (the backend derives it). Returns the number of
  // frames (0: nothing queued) or −errno (−ENETDOWN when the interface went
  // down, −ENODEV when it disappeared).
  virtual int receive(can::CanFrame* frames, int max, CanRxInfo& info) noexcept = 0;

  // Sends one frame without blocking. 0, or −errno (−EAGAIN/−ENOBUFS: the TX
  // queue is full; −ENETDOWN: interface down).
  virtual int send(const can::CanFrame& frame) noexcept = 0;

  // Blocks until a frame can be received or the absolute CLOCK_MONOTONIC
  // deadline passes. 1: readable (or an error is pending: receive() reports
  // it), 0: deadline reached, −errno on failure.
  virtual int wait_readable(std::int64_t deadline_mono_ns) noexcept = 0;

  // The clocks the backend reads (injectable for tests).
  virtual std::int64_t now_mono_ns() noexcept = 0;
  virtual std::int64_t now_wall_ns() noexcept = 0;
};

// An error (positive errno) from any CanPort call that means the interface is
// gone or down: close the port and re-open it later.
inline bool is_interface_loss(int err) noexcept {
  return err == ENETDOWN || err == ENODEV || err == ENXIO || err == ENETUNREACH || err == EBADF;
}

// The real port: a CAN_RAW socket (Linux only). Filters: config.filters
// (CAN_RAW_FILTER). Error frames: CAN_RAW_ERR_FILTER = can::err_class::kSubscribed.
// Timestamps: SO_TIMESTAMPING software RX (falls back to SO_TIMESTAMPNS).
std::unique_ptr<CanPort> make_socketcan_port(const CanPortConfig& config);

}  // namespace exodaq::drivers
