#pragma once
// The `socketcan` encoder backend: protocol v1 frames from an encoder interface
// board on a CAN interface (can0 on the rig, vcan0 in tests), decoded by the
// same BoardDecoder the sim backend uses. The socket sits behind CanPort
// (can_port.hpp) so tests drive this class with an in-memory port.
//
// One read() per loop cycle, at the cycle's deadline (its start):
//   1. If the port is down: at most once per second, try to re-open it (a few
//      non-blocking syscalls: if_nametoindex, socket, setsockopt, bind,
//      SIOCGIFFLAGS — done on the loop thread, bounded, never blocking).
//      Still down: a kMissing sample with kBusError, bus state kDown.
//   2. Sync master: send SYNC (non-blocking; EAGAIN/ENOBUFS are counted in
//      sync_send_failures, never waited for).
//   3. Receive every queued frame into the decoder, then wait (ppoll) for more
//      until the cycle's sample is complete or the poll deadline passes:
//      deadline_mono_ns + read_deadline_us, never later than the end of the
//      cycle minus a guard of period/10.
//        sync master: complete = a full cycle whose count frames were received
//                     after this cycle's SYNC was sent;
//        free-running board: complete = any full cycle not yet delivered.
//   4. Deliver the newest complete cycle. Older complete cycles still queued
//      (the board got ahead, or a late answer to an earlier SYNC) are
//      superseded: counted in superseded_samples, their event flags and index
//      latches merged into the delivered sample so nothing is lost but the
//      intermediate counts (which the unwrapping bridges). At the poll
//      deadline with only one half of a cycle (sync master; free-run: when the
//      half is older than half a period) the half is flushed as kPartial.
//      Nothing at all: kMissing (make_missing) with the cycle's stamps.
//
// Time stamps. A frame's wall_ns is the kernel's software receive timestamp
// (CLOCK_REALTIME, taken when the frame entered the network stack). Its
// mono_ns = wall_ns − offset, offset = CLOCK_REALTIME − CLOCK_MONOTONIC
// measured at each read() (mono/wall/mono bracket; the tightest bracket is
// kept until the offset moves by more than bracket + 1 µs, i.e. a clock step).
// The sample carries both (BoardDecoder: stamps of the count frame that
// completed the cycle). The daemon maps mono_ns back to utime with its own
// offset estimate, so while the wall clock is steady the published utime is
// the kernel receive timestamp (to within the two offset estimates' error,
// well under 1 µs on real hardware: ±1 µs after truncation to µs), and
// encoder_raw_t.wall_ns carries the kernel stamp exactly. A missing sample is
// stamped with the cycle's deadline.
//
// Interface loss. −ENETDOWN or −ENODEV from any call (or POLLERR) closes the
// port and sets bus state kDown (samples then carry kBusError: the daemon
// degrades). Re-open attempts at 1 Hz; on success the bus state returns to
// kUnknown and becomes kActive with the next frame. Error frames update the bus
// state (BoardDecoder::on_frame). SO_RXQ_OVFL drops go to add_rx_overflows().
//
// read() allocates nothing (frame buffer, decoder queue and stats are members).
#include <array>
#include <cstdint>
#include <memory>
#include <string_view>

#include "exodaq/drivers/board_decoder.hpp"
#include "exodaq/drivers/can_port.hpp"
#include "exodaq/drivers/encoder_source.hpp"
#include "exodaq/drivers/source_options.hpp"

namespace exodaq::drivers {

struct SocketCanSourceConfig {
  CanPortConfig port{};
  bool sync_master = true;
  std::int64_t read_deadline_ns = 400'000;  // after the cycle's deadline
  std::int64_t reopen_interval_ns = 1'000'000'000;
  BoardDecoderConfig decoder{};  // decoder.ids must equal port.ids
};

// Backend-side counters beyond SourceStats (tests, logs).
struct SocketCanDetail {
  std::int64_t sync_sent = 0;
  std::int64_t sync_send_failures = 0;  // EAGAIN / ENOBUFS / other send errors while up
  std::int64_t superseded_samples = 0;  // complete cycles replaced by a newer one
  std::int64_t partial_flushes = 0;
  std::int64_t unstamped_frames = 0;  // no kernel timestamp: stamped with the read time
  std::int64_t interface_losses = 0;  // transitions to kDown
  std::int64_t reopen_attempts = 0;
  std::int64_t reopens = 0;  // successful re-opens after a loss
  std::int64_t receive_errors = 0;
  int last_errno = 0;
  bool open = false;
  std::int64_t offset_ns = 0;  // CLOCK_REALTIME − CLOCK_MONOTONIC in use
};

class SocketCanSource final : public EncoderSource {
 public:
  SocketCanSource(const SocketCanSourceConfig& config, std::unique_ptr<CanPort> port);

  std::string_view name() const noexcept override { return "socketcan"; }
  // Opens the port. An interface that is missing or down is not an error
  // here: the source starts in kDown and keeps retrying (the daemon reports
  // it). Other failures (no CAN support in the kernel: EAFNOSUPPORT) throw.
  void start() override;
  ReadStatus read(const CycleTime& time, EncoderSample& out) noexcept override;
  SourceStats stats() const noexcept override { return decoder_.stats(); }
  void stop() noexcept override;

  const BoardDecoder& decoder() const noexcept { return decoder_; }
  const SocketCanDetail& detail() const noexcept { return detail_; }
  const SocketCanSourceConfig& config() const noexcept { return config_; }

 private:
  static constexpr int kBatch = 32;

  void measure_offset() noexcept;
  bool try_open(std::int64_t now_mono) noexcept;
  void go_down(int err) noexcept;
  // Receives everything queued; false when the port failed (now down).
  bool drain() noexcept;
  void feed(const can::CanFrame& frame) noexcept;
  bool have_current(std::int64_t sync_mono) const noexcept;
  bool take_newest(EncoderSample& out) noexcept;

  SocketCanSourceConfig config_;
  std::unique_ptr<CanPort> port_;
  BoardDecoder decoder_;
  SocketCanDetail detail_{};
  std::array<can::CanFrame, kBatch> rx_{};
  EncoderSample scratch_{};
  bool up_ = false;
  std::int64_t last_open_attempt_mono_ = 0;
  std::int64_t offset_ns_ = 0;
  std::int64_t offset_width_ns_ = INT64_MAX;
  bool offset_valid_ = false;
  std::int64_t newest_complete_mono_ = 0;  // stamp of the frame that last completed a cycle
  std::int64_t partial_since_mono_ = 0;    // stamp of the half now pending
};

}  // namespace exodaq::drivers
