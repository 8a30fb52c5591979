#include "exodaq/drivers/board_decoder.hpp"

#include <string_view>
#include <tuple>

namespace exodaq::drivers {
static_assert(can::kBoardChannels == kChannelCount,
              "protocol v1 carries one board channel per joint of the published messages");
namespace {

constexpr std::uint32_t kHalfA = 0x07;
constexpr std::uint32_t kHalfB = 0x38;
static_assert(kAllChannels == 0x3F, "protocol v1: six channels");
constexpr std::uint32_t kEventFlags = sample_flag::kSeqGap | sample_flag::kDuplicate |
                                      sample_flag::kOutOfOrder | sample_flag::kBusError;

}  // namespace

void merge_superseded(const EncoderSample& older, EncoderSample& newer) noexcept {
  newer.flags |= older.flags & kEventFlags;
  for (int c = 0; c < kChannelCount; ++c) {
    const std::uint32_t bit = 1U << c;
    if ((older.index_latched & bit) == 0 || (newer.index_latched & bit) != 0) continue;
    newer.index_latched |= bit;
    if ((older.index_count_valid & bit) != 0 && (newer.index_count_valid & bit) == 0) {
      newer.index_count_valid |= bit;
      newer.index_position[static_cast<std::size_t>(c)] =
          older.index_position[static_cast<std::size_t>(c)];
    }
  }
}

BoardDecoder::BoardDecoder(const BoardDecoderConfig& config) noexcept : config_(config) {
  reset();
}

void BoardDecoder::diagnose(SourceDiagnostics& out) const noexcept {
  // By can::Reject value; index 0 (kNone) is never counted.
  static constexpr std::array<std::string_view, 6> kRejected = {"",
                                                                "rejected_unknown_id",
                                                                "rejected_wrong_dlc",
                                                                "rejected_rtr",
                                                                "rejected_extended_id",
                                                                "rejected_can_fd"};
  static_assert(kRejected.size() == std::tuple_size_v<decltype(stats_.rejected)>);
  out.add("samples", stats_.samples);
  out.add("partial_samples", stats_.partial_samples);
  out.add("lost_cycles", stats_.lost_cycles);
  out.add("resyncs", stats_.resyncs);
  out.add("sync_frames", stats_.sync_frames);
  out.add("index_frames", stats_.index_frames);
  out.add("heartbeats", stats_.heartbeats);
  out.add("queue_overflows", stats_.queue_overflows);
  out.add("superseded_samples", stats_.source.superseded_samples);
  for (std::size_t r = 1; r < kRejected.size(); ++r) out.add(kRejected[r], stats_.rejected[r]);
  out.add("board_state", stats_.board_state);
  out.add("protocol_version", stats_.protocol_version);
}

void BoardDecoder::reset() noexcept {
  stats_ = BoardDecoderStats{};
  pending_ = Pending{};
  queue_head_ = 0;
  queue_size_ = 0;
  closed_valid_ = false;
  closed_seq_ = 0;
  closed_fresh_ = 0;
  consecutive_rejects_ = 0;
  held_ = EncoderSample{};
  held_.channel_fresh = 0;
  held_.seq_modulus = kSeq8Modulus;
  held_.modulus.fill(kCount16Modulus);
  index_stash_ = {};
  event_flags_ = 0;
  board_errors_ = 0;
  board_state_ = 0;
}

can::FrameKind BoardDecoder::on_frame(const can::CanFrame& frame) noexcept {
  ++stats_.source.frames;
  const can::Decoded d = can::decode(frame, config_.ids);
  if (d.kind != can::FrameKind::kRejected && d.kind != can::FrameKind::kError &&
      stats_.source.bus_state == BusState::kUnknown) {
    stats_.source.bus_state = BusState::kActive;
  }
  switch (d.kind) {
    case can::FrameKind::kRejected:
      ++stats_.source.bad_frames;
      ++stats_.rejected[static_cast<std::size_t>(d.reject)];
      break;
    case can::FrameKind::kSync:
      ++stats_.sync_frames;
      break;
    case can::FrameKind::kCountsA:
      on_counts(frame, d.counts, true);
      break;
    case can::FrameKind::kCountsB:
      on_counts(frame, d.counts, false);
      break;
    case can::FrameKind::kIndex:
      on_index(d.index);
      break;
    case can::FrameKind::kHeartbeat:
      on_heartbeat(frame, d.heartbeat);
      break;
    case can::FrameKind::kError:
      on_error(d.error);
      break;
  }
  return d.kind;
}

bool BoardDecoder::needs_resync(const can::CanFrame& frame) const noexcept {
  if (!pending_.active && !closed_valid_) return false;
  if (consecutive_rejects_ >= config_.resync_after_rejects) return true;
  const std::int64_t last = stats_.last_count_frame_mono_ns;
  return frame.mono_ns > 0 && last > 0 && frame.mono_ns - last > config_.resync_after_ns;
}

void BoardDecoder::on_counts(const can::CanFrame& frame, const can::CountsPayload& counts,
                             bool first_half) noexcept {
  const std::uint32_t half = first_half ? kHalfA : kHalfB;
  // A half of the cycle being assembled or of the one last closed belongs to
  // the board's running sequence however long the silence before it (a board
  // held off between its two frames): it completes that cycle or comes too
  // late for it, never opens it a second time, and the board was heard.
  const bool same_cycle = (pending_.active && counts.seq == pending_.seq) ||
                          (closed_valid_ && counts.seq == closed_seq_);
  if (same_cycle) stats_.last_count_frame_mono_ns = frame.mono_ns;
  bool resynced = false;
  if (!same_cycle && needs_resync(frame)) {
    if (pending_.active) close_pending();
    closed_valid_ = false;
    consecutive_rejects_ = 0;
    ++stats_.resyncs;
    resynced = true;
  }

  if (pending_.active) {
    const int d = can::seq_delta(pending_.seq, counts.seq);
    if (d < 0 || (d == 0 && (pending_.fresh & half) != 0)) {
      if (d == 0) {
        ++stats_.source.duplicates;
        event_flags_ |= sample_flag::kDuplicate;
        ++consecutive_rejects_;
      } else {
        drop_old(counts.seq, half);
      }
      return;
    }
    if (d > 0) {
      close_pending();
      open_pending(counts.seq, d - 1, false);
    }
  } else if (closed_valid_) {
    const int d = can::seq_delta(closed_seq_, counts.seq);
    if (d <= 0) {
      drop_old(counts.seq, half);
      return;
    }
    open_pending(counts.seq, d - 1, false);
  } else {
    open_pending(counts.seq, 0, resynced);
  }

  EncoderSample& s = pending_.sample;
  for (int i = 0; i < can::kChannelsPerCountsFrame; ++i) {
    s.position[static_cast<std::size_t>(counts.first_channel) + static_cast<std::size_t>(i)] =
        counts.count16[static_cast<std::size_t>(i)];
  }
  s.index_latched |= static_cast<std::uint32_t>(counts.index_latched & 0x07)
                     << counts.first_channel;
  s.mono_ns = frame.mono_ns;
  s.wall_ns = frame.wall_ns;
  pending_.fresh |= half;
  consecutive_rejects_ = 0;
  stats_.last_count_frame_mono_ns = frame.mono_ns;
  if (pending_.fresh == kAllChannels) close_pending();
}

void BoardDecoder::drop_old(std::uint8_t seq, std::uint32_t half) noexcept {
  if (closed_valid_ && seq == closed_seq_ && (closed_fresh_ & half) != 0) {
    ++stats_.source.duplicates;
    event_flags_ |= sample_flag::kDuplicate;
  } else {
    ++stats_.source.out_of_order;
    event_flags_ |= sample_flag::kOutOfOrder;
  }
  ++consecutive_rejects_;
}

void BoardDecoder::open_pending(std::uint8_t seq, int lost, bool resynced) noexcept {
  pending_.active = true;
  pending_.seq = seq;
  pending_.fresh = 0;
  EncoderSample& s = pending_.sample;
  s = held_;
  s.present = true;
  s.seq = seq;
  s.index_latched = 0;
  s.index_count_valid = 0;
  s.flags = 0;
  if (lost > 0) {
    ++stats_.source.seq_gaps;
    stats_.lost_cycles += lost;
    s.flags |= sample_flag::kSeqGap;
  } else if (resynced) {
    ++stats_.source.seq_gaps;
    s.flags |= sample_flag::kSeqGap;
  }
}

void BoardDecoder::close_pending() noexcept {
  EncoderSample& s = pending_.sample;
  s.channel_fresh = pending_.fresh;
  if (pending_.fresh != kAllChannels) {
    s.flags |= sample_flag::kPartial;
    ++stats_.partial_samples;
  }
  merge_stashed_index(s);
  s.flags |= event_flags_;  // drops/errors seen since the previous cycle closed
  event_flags_ = 0;
  held_.position = s.position;
  held_.seq = s.seq;
  closed_valid_ = true;
  closed_seq_ = pending_.seq;
  closed_fresh_ = pending_.fresh;
  pending_.active = false;

  if (queue_size_ == kQueueCapacity) {  // consumer fell behind: drop the oldest
    queue_head_ = (queue_head_ + 1) % kQueueCapacity;
    --queue_size_;
    ++stats_.queue_overflows;
  }
  queue_[static_cast<std::size_t>((queue_head_ + queue_size_) % kQueueCapacity)] = s;
  ++queue_size_;
}

void BoardDecoder::merge_stashed_index(EncoderSample& s) noexcept {
  const auto seq = static_cast<std::uint8_t>(s.seq);
  for (int c = 0; c < kChannelCount; ++c) {
    StashedIndex& st = index_stash_[static_cast<std::size_t>(c)];
    if (st.valid && can::seq_delta(st.seq, seq) >= 0) {
      s.index_position[static_cast<std::size_t>(c)] = st.count16;
      s.index_count_valid |= 1U << c;
      st.valid = false;
    }
  }
}

void BoardDecoder::on_index(const can::IndexPayload& index) noexcept {
  ++stats_.index_frames;
  const auto c = static_cast<std::size_t>(index.channel);
  for (int i = 0; i < queue_size_; ++i) {  // its cycle is complete but not taken yet
    EncoderSample& q = queue_[static_cast<std::size_t>((queue_head_ + i) % kQueueCapacity)];
    if (static_cast<std::uint8_t>(q.seq) == index.seq) {
      q.index_position[c] = index.count16;
      q.index_count_valid |= 1U << index.channel;
      return;
    }
  }
  if (pending_.active && pending_.seq == index.seq) {
    pending_.sample.index_position[c] = index.count16;
    pending_.sample.index_count_valid |= 1U << index.channel;
    return;
  }
  // Early (its cycle not begun) or late (its cycle already delivered): the
  // next sample not older than it carries it.
  index_stash_[c] = StashedIndex{true, index.seq, index.count16};
}

void BoardDecoder::on_heartbeat(const can::CanFrame& frame,
                                const can::HeartbeatPayload& hb) noexcept {
  ++stats_.heartbeats;
  stats_.last_heartbeat_mono_ns = frame.mono_ns;
  stats_.board_state = hb.state;
  stats_.protocol_version = hb.protocol_version;
  board_state_ = hb.state;
  board_errors_ = static_cast<std::uint32_t>(hb.errors) |
                  (static_cast<std::uint32_t>(hb.channel_quadrature_errors) << 8);
  stats_.source.board_errors = board_errors_;
}

void BoardDecoder::on_error(const can::ErrorPayload& err) noexcept {
  ++stats_.source.bus_errors;
  event_flags_ |= sample_flag::kBusError;
  stats_.source.bus_state = can::bus_state_after(stats_.source.bus_state, err);
  if ((err.classes & can::err_class::kCrtl) != 0 &&
      (err.controller & can::err_crtl::kRxOverflow) != 0) {
    ++stats_.source.rx_overflows;
  }
}

std::uint32_t BoardDecoder::level_flags() const noexcept {
  std::uint32_t f = 0;
  if (board_errors_ != 0) f |= sample_flag::kBoardError;
  const BusState b = stats_.source.bus_state;
  if (b == BusState::kOff || b == BusState::kDown) f |= sample_flag::kBusError;
  return f;
}

void BoardDecoder::finish(EncoderSample& out) noexcept {
  out.flags |= level_flags();
  out.board_state = board_state_;
  out.board_errors = board_errors_;
}

bool BoardDecoder::poll_sample(EncoderSample& out) noexcept {
  if (queue_size_ == 0) return false;
  out = queue_[static_cast<std::size_t>(queue_head_)];
  queue_head_ = (queue_head_ + 1) % kQueueCapacity;
  --queue_size_;
  finish(out);
  ++stats_.samples;
  return true;
}

int BoardDecoder::poll_newest(EncoderSample& out) noexcept {
  if (!poll_sample(out)) return -1;
  int superseded = 0;
  EncoderSample newer;
  while (poll_sample(newer)) {
    merge_superseded(out, newer);
    out = newer;
    ++superseded;
  }
  stats_.source.superseded_samples += superseded;
  return superseded;
}

bool BoardDecoder::flush(EncoderSample& out) noexcept {
  if (pending_.active) close_pending();
  return poll_sample(out);
}

void BoardDecoder::make_missing(EncoderSample& out, std::int64_t mono_ns,
                                std::int64_t wall_ns) noexcept {
  out = held_;
  out.mono_ns = mono_ns;
  out.wall_ns = wall_ns;
  out.present = false;
  out.index_latched = 0;
  out.index_count_valid = 0;
  out.channel_fresh = 0;
  out.flags = sample_flag::kMissing | event_flags_;
  event_flags_ = 0;
  finish(out);
  ++stats_.source.missing_samples;
}

void BoardDecoder::set_bus_state(BusState state) noexcept {
  stats_.source.bus_state = state;
}

void BoardDecoder::add_rx_overflows(std::int64_t dropped) noexcept {
  if (dropped > 0) stats_.source.rx_overflows += dropped;
}

namespace {
class BoardFrameAssembler final : public FrameAssembler {
 public:
  explicit BoardFrameAssembler(const BoardDecoderConfig& config) : decoder_(config) {}
  void on_frame(const can::CanFrame& frame) noexcept override { decoder_.on_frame(frame); }
  bool poll(EncoderSample& out) noexcept override { return decoder_.poll_sample(out); }
  bool finish(EncoderSample& out) noexcept override { return decoder_.flush(out); }
  SourceStats stats() const noexcept override { return decoder_.stats(); }

 private:
  BoardDecoder decoder_;
};
}  // namespace

std::unique_ptr<FrameAssembler> make_board_frame_assembler(const BoardDecoderConfig& config) {
  return std::make_unique<BoardFrameAssembler>(config);
}

}  // namespace exodaq::drivers
