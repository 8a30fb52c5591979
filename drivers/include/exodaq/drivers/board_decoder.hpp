#pragma once
// Stateful assembly of protocol v1 frames into one EncoderSample per board
// cycle. Shared by the sim backend, the SocketCAN backend and candump replay:
// whoever has frames feeds them in with on_frame() and takes completed cycles
// out with poll_sample()/poll_newest(). Allocation-free; not thread-safe (one
// owner thread). Cycle assembly, time stamps, sequence handling,
// resynchronisation and which sample carries which flag:
// docs/can-protocol.md ("Cycle assembly and sequence handling").
#include <algorithm>
#include <array>
#include <cstdint>
#include <memory>

#include "exodaq/drivers/can_codec.hpp"
#include "exodaq/drivers/encoder_sample.hpp"
#include "exodaq/drivers/frame_assembler.hpp"
#include "exodaq/drivers/source_diagnostics.hpp"

namespace exodaq::drivers {

struct BoardDecoderConfig {
  can::ProtocolIds ids{};
  // No count frame for this long: accept the next seq as new (a gap).
  std::int64_t resync_after_ns = 100'000'000;
  // This many consecutive count frames dropped as duplicate/out-of-order:
  // assume the board restarted and accept the next one.
  int resync_after_rejects = 8;
};

// Everything BoardDecoder counts; `source` is what the status channel shows.
struct BoardDecoderStats {
  SourceStats source{};
  std::int64_t samples = 0;          // samples delivered with present == true
  std::int64_t partial_samples = 0;  // of which kPartial
  std::int64_t lost_cycles = 0;      // seq values skipped in total
  std::int64_t resyncs = 0;
  std::int64_t sync_frames = 0;
  std::int64_t index_frames = 0;
  std::int64_t heartbeats = 0;
  std::int64_t queue_overflows = 0;        // completed samples dropped, consumer too slow
  std::array<std::int64_t, 6> rejected{};  // by can::Reject value (index 0 unused)
  std::int64_t last_heartbeat_mono_ns = 0;
  std::int64_t last_count_frame_mono_ns = 0;
  std::uint8_t board_state = 0;
  std::uint8_t protocol_version = 0;
};

// `older` is superseded by `newer` (a reader that fell behind delivers only the
// newest cycle): `newer` keeps older's event flags and index latches, so
// nothing is lost but the intermediate counts, which unwrapping bridges.
void merge_superseded(const EncoderSample& older, EncoderSample& newer) noexcept;

class BoardDecoder {
 public:
  // Completed cycles held for the reader. A free-running board's reader takes
  // them oldest first and drains its socket only while a batch still fits
  // (the socket is the deep buffer); a reader further behind than this
  // loses the oldest (queue_overflows).
  static constexpr int kQueueCapacity = 64;

  explicit BoardDecoder(const BoardDecoderConfig& config = {}) noexcept;

  // Forgets every cycle and counter (start of a stream).
  void reset() noexcept;

  // Feeds one received frame. Returns what the codec made of it (for tests and
  // for backends that act on SYNC/errors); the decoder has already counted it.
  can::FrameKind on_frame(const can::CanFrame& frame) noexcept;

  // Takes the oldest completed cycle. false: none complete.
  bool poll_sample(EncoderSample& out) noexcept;
  // Takes the newest completed cycle; older ones still queued are superseded
  // (merge_superseded, counted in superseded_samples). Returns how many were,
  // or -1 when none is complete.
  int poll_newest(EncoderSample& out) noexcept;
  // A reader that merged a sample into a newer one itself (a partial flush).
  void count_superseded(std::int64_t n) noexcept { stats_.source.superseded_samples += n; }

  // Number of completed cycles waiting for poll_sample().
  int queued() const noexcept { return queue_size_; }
  // A cycle with only one half so far (flush() would produce a sample).
  bool has_partial() const noexcept { return pending_.active; }
  // The receive stamp of the half-assembled cycle's last frame (0: none).
  std::int64_t partial_mono_ns() const noexcept {
    return pending_.active ? pending_.sample.mono_ns : 0;
  }

  // At the owner's deadline: closes a half-assembled cycle as kPartial and
  // delivers it (true), or returns false when none is pending. Call after
  // poll_sample() returned false.
  bool flush(EncoderSample& out) noexcept;

  // Nothing for this cycle: fills `out` with the last counts held,
  // present = false, channel_fresh = 0, kMissing (+ pending event and level
  // flags), the given stamps (the backend's cycle time), and counts one
  // missing sample.
  void make_missing(EncoderSample& out, std::int64_t mono_ns, std::int64_t wall_ns) noexcept;

  // Backend-side conditions that do not come as frames.
  void set_bus_state(BusState state) noexcept;  // e.g. kDown on ENETDOWN
  void add_rx_overflows(std::int64_t dropped) noexcept;

  const BoardDecoderStats& detail() const noexcept { return stats_; }
  // detail() as named counters (a source's diagnose() adds them to its own).
  void diagnose(SourceDiagnostics& out) const noexcept;
  SourceStats stats() const noexcept { return stats_.source; }
  const BoardDecoderConfig& config() const noexcept { return config_; }

 private:
  struct Pending {
    bool active = false;
    std::uint8_t seq = 0;
    std::uint32_t fresh = 0;  // channel bits received
    EncoderSample sample{};
  };

  void on_counts(const can::CanFrame& frame, const can::CountsPayload& counts,
                 bool first_half) noexcept;
  void on_index(const can::IndexPayload& index) noexcept;
  void on_heartbeat(const can::CanFrame& frame, const can::HeartbeatPayload& hb) noexcept;
  void on_error(const can::ErrorPayload& err) noexcept;
  bool needs_resync(const can::CanFrame& frame) const noexcept;
  void open_pending(std::uint8_t seq, int lost, bool resynced) noexcept;
  void close_pending() noexcept;  // queue the pending cycle (complete or partial)
  void drop_old(std::uint8_t seq, std::uint32_t half) noexcept;
  void merge_stashed_index(EncoderSample& s) noexcept;
  std::uint32_t level_flags() const noexcept;
  void finish(EncoderSample& out) noexcept;  // level flags, board state

  BoardDecoderConfig config_;
  BoardDecoderStats stats_{};
  Pending pending_{};

  std::array<EncoderSample, kQueueCapacity> queue_{};
  int queue_head_ = 0;
  int queue_size_ = 0;

  // The last cycle closed, for sequence checks.
  bool closed_valid_ = false;
  std::uint8_t closed_seq_ = 0;
  std::uint32_t closed_fresh_ = 0;  // channels it had when closed
  int consecutive_rejects_ = 0;

  // Last known values, held into partial and missing samples.
  EncoderSample held_{};

  // INDEX frames waiting for the sample of their cycle (or the next one).
  struct StashedIndex {
    bool valid = false;
    std::uint8_t seq = 0;
    std::uint16_t count16 = 0;
  };
  std::array<StashedIndex, kChannelCount> index_stash_{};

  std::uint32_t event_flags_ = 0;
  std::uint32_t board_errors_ = 0;  // errors | channel bits << 8
  std::uint32_t board_state_ = 0;
};

// Protocol v1's assembly of recorded frames (candump replay): the
// BoardDecoder, oldest cycle first, a half cycle at the end as PARTIAL.
std::unique_ptr<FrameAssembler> make_board_frame_assembler(const BoardDecoderConfig& config);

// Following a free-running board: it is overdue when it was last heard from
// (the last sample delivered, or the first half of a cycle still waiting for
// its second) more than one and a half periods before `now`, or never. Before
// that, a wake without a new sample has nothing to publish: the board's clock
// drifted just past the wake (the next wake brings two), or a half waits to be
// completed or flushed as PARTIAL.
inline bool free_running_board_overdue(const BoardDecoder& decoder,
                                       std::int64_t last_delivered_mono, std::int64_t now,
                                       std::int64_t period) noexcept {
  const std::int64_t heard = std::max(last_delivered_mono, decoder.partial_mono_ns());
  return heard == 0 || now - heard > period + period / 2;
}

}  // namespace exodaq::drivers
