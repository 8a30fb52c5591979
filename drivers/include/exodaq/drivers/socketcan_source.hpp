#pragma once
// The `socketcan` encoder backend: protocol v1 frames from an encoder interface
// board on a CAN interface (can0 on the rig, vcan0 in tests), decoded by the
// same BoardDecoder the sim backend uses, over the SocketCAN transport any
// CAN protocol uses (CanLink: the port, its re-opening, stamps and waits;
// can_link.hpp). The socket and the clocks sit behind CanPort (can_port.hpp)
// so tests drive this class with an in-memory port.
// One read() per loop wake: re-open a lost port (at most once per
// reopen_interval_ns, non-blocking), then
// - sync master: send SYNC (counted late when it leaves more than a tenth of
//   a period after the deadline), receive and wait until the answer is
//   complete or the poll deadline (deadline + read_deadline_ns, never past
//   the cycle's end minus a tenth; from the SYNC on when it was late), deliver the
//   newest complete cycle (older ones superseded), flush a lone half as
//   PARTIAL, else MISSING;
// - following a free-running board: deliver every complete cycle, oldest
//   first, one per read (backlog() says more wait; the socket is drained only
//   while the decoder has room, so it stays the deep buffer), waiting up to the
//   poll deadline only when none is there; MISSING only once the board is
//   overdue, else nothing this wake.
// Samples carry the kernel receive stamps. read() allocates nothing. The whole
// behaviour (time stamps, interface loss and recovery): docs/can-protocol.md
// ("The socketcan backend").
#include <array>
#include <cstdint>
#include <memory>
#include <string_view>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/can_link.hpp"
#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/encoder_source.hpp"

namespace exodaq::drivers {

struct SocketCanSourceConfig {
  CanPortConfig port{};  // port.filters: can::port_filters(decoder.ids, !sync_master)
  bool sync_master = true;
  std::int64_t read_deadline_ns = 400'000;  // after the cycle's deadline
  std::int64_t reopen_interval_ns = 1'000'000'000;
  BoardDecoderConfig decoder{};
};

// Backend-side counters beyond SourceStats (tests, logs): protocol v1's own
// and the transport's.
struct SocketCanDetail {
  std::int64_t sync_sent = 0;
  std::int64_t sync_send_failures = 0;  // EAGAIN / ENOBUFS / other send errors while up
  std::int64_t superseded_samples = 0;  // complete cycles replaced by a newer one
  std::int64_t late_syncs = 0;  // SYNCs sent more than a tenth of a period after the deadline
  std::int64_t partial_flushes = 0;
  CanLinkStats link{};  // unstamped frames, interface losses, reopens, errno, offset
};

class SocketCanSource final : public EncoderSource, private FrameSink {
 public:
  SocketCanSource(const SocketCanSourceConfig& config, std::unique_ptr<CanPort> port);

  std::string_view name() const noexcept override { return "socketcan"; }
  // Opens the port. An interface that is missing or down is not an error
  // here: the source starts in kDown and keeps retrying (the daemon reports
  // it). Other failures (no CAN support in the kernel: EAFNOSUPPORT) throw.
  void start() override;
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  SourceStats stats() const noexcept override {
    SourceStats s = decoder_.stats();
    s.late_syncs = detail_.late_syncs;
    return s;
  }
  // detail() and the decoder's counters; the state: "can0 open" or
  // "can0 down: ENODEV".
  void diagnose(SourceDiagnostics& out) const noexcept override;
  bool free_running() const noexcept override { return !config_.sync_master; }
  int backlog() const noexcept override;
  void stop() noexcept override;

  const BoardDecoder& decoder() const noexcept { return decoder_; }
  SocketCanDetail detail() const noexcept;
  const SocketCanSourceConfig& config() const noexcept { return config_; }

 private:
  // Following a free-running board, receive only while a whole batch of
  // cycles (at most CanLink::kBatch / 2) still fits the decoder's queue.
  static constexpr int kRefillBelow = BoardDecoder::kQueueCapacity - CanLink::kBatch / 2;

  // FrameSink: what the link receives goes to the decoder.
  void on_frame(const can::CanFrame& frame) noexcept override;
  void on_rx_overflows(std::int64_t dropped) noexcept override;
  void on_link(bool up) noexcept override;
  bool wants_more() const noexcept override;
  bool satisfied() const noexcept override;

  void send_sync() noexcept;
  // Closes a lone half as PARTIAL when it is due; true when `out` holds a sample.
  bool flush_partial(bool got, std::int64_t sync_mono, std::int64_t period,
                     EncoderSample& out) noexcept;
  // Until when a read waits for frames, counted from `from` (the deadline, or a late SYNC).
  std::int64_t poll_deadline(std::int64_t from, std::int64_t period) const noexcept;
  ReadStatus read_sync_master(const CycleTime& time, std::int64_t period, std::int64_t now,
                              EncoderSample& out) noexcept;
  ReadStatus read_free_running(const CycleTime& time, std::int64_t period,
                               EncoderSample& out) noexcept;
  // Free-running: the oldest complete (or due partial) cycle; false: none.
  bool take_queued(std::int64_t period, EncoderSample& out) noexcept;

  SocketCanSourceConfig config_;
  CanLink link_;
  BoardDecoder decoder_;
  SocketCanDetail detail_{};
  EncoderSample scratch_{};
  std::int64_t sync_mono_ = 0;             // sync master: this cycle's SYNC (satisfied())
  std::int64_t newest_complete_mono_ = 0;  // stamp of the frame that last completed a cycle
  std::int64_t partial_since_mono_ = 0;    // stamp of the half now pending
  std::int64_t last_delivered_mono_ = 0;   // free-running: stamp of the last sample delivered
};

}  // namespace exodaq::drivers
