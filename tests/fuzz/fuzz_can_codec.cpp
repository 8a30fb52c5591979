// Fuzz target can_codec: can::decode() on any frame, with the default
// identifiers or any identifier set validate() accepts.
// Input: [ids selector u8][id u32][dlc u8][flags u8][data 8] and, when the
// selector's bit 7 is set, a ProtocolIds (7 x u32) to try.
#include "exodaq/drivers/can_codec.hpp"
#include "fuzz_input.hpp"

namespace can = exodaq::drivers::can;

namespace {

bool same(const can::Decoded& a, const can::Decoded& b) {
  if (a.kind != b.kind || a.reject != b.reject) return false;
  switch (a.kind) {
    case can::FrameKind::kCountsA:
    case can::FrameKind::kCountsB:
      return a.counts.first_channel == b.counts.first_channel &&
             a.counts.count16 == b.counts.count16 &&
             a.counts.index_latched == b.counts.index_latched && a.counts.seq == b.counts.seq;
    case can::FrameKind::kIndex:
      return a.index.channel == b.index.channel && a.index.count16 == b.index.count16 &&
             a.index.seq == b.index.seq;
    case can::FrameKind::kHeartbeat:
      return a.heartbeat.state == b.heartbeat.state && a.heartbeat.errors == b.heartbeat.errors &&
             a.heartbeat.channel_quadrature_errors == b.heartbeat.channel_quadrature_errors &&
             a.heartbeat.protocol_version == b.heartbeat.protocol_version;
    default:
      return true;
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  exodaq::fuzz::Bytes in(data, size);
  const std::uint8_t selector = in.u8();
  can::CanFrame f;
  f.id = in.u32();
  f.dlc = in.u8();
  f.flags = in.u8();
  in.copy(f.data.data(), f.data.size());

  can::ProtocolIds ids;
  ids.board = selector & 0x03U;
  if ((selector & 0x80U) != 0) {
    can::ProtocolIds custom;
    custom.sync = in.u32();
    custom.counts_a = in.u32();
    custom.counts_b = in.u32();
    custom.index_base = in.u32();
    custom.heartbeat = in.u32();
    custom.board = in.u32();
    custom.board_stride = in.u32();
    if (can::validate(custom) == nullptr) ids = custom;
  }
  FUZZ_CHECK(can::validate(ids) == nullptr);

  const can::Decoded d = can::decode(f, ids);
  FUZZ_CHECK(!can::to_string(d.kind).empty());
  FUZZ_CHECK(!can::to_string(d.reject).empty());
  FUZZ_CHECK((d.kind == can::FrameKind::kRejected) == (d.reject != can::Reject::kNone));

  // What was accepted is what the encoders write: decoding the re-encoded
  // payload gives the same payload, and the frame's checks held.
  const bool plain = (f.flags & (can::frame_flag::kFd | can::frame_flag::kRtr |
                                 can::frame_flag::kExtended | can::frame_flag::kError)) == 0;
  switch (d.kind) {
    case can::FrameKind::kCountsA:
    case can::FrameKind::kCountsB: {
      const int which = d.kind == can::FrameKind::kCountsA ? 0 : 1;
      FUZZ_CHECK(plain && f.dlc == can::kCountsDlc);
      FUZZ_CHECK(f.id == (which == 0 ? ids.counts_a_id() : ids.counts_b_id()));
      FUZZ_CHECK(d.counts.first_channel == which * can::kChannelsPerCountsFrame);
      FUZZ_CHECK((d.counts.index_latched & ~0x07U) == 0);
      const auto again = can::decode(
          can::encode_counts(which, d.counts.count16, d.counts.index_latched, d.counts.seq, ids),
          ids);
      FUZZ_CHECK(same(d, again));
      break;
    }
    case can::FrameKind::kIndex: {
      FUZZ_CHECK(plain && f.dlc == can::kIndexDlc);
      FUZZ_CHECK(d.index.channel >= 0 && d.index.channel < can::kBoardChannels);
      FUZZ_CHECK(f.id == ids.index_id(d.index.channel));
      const auto again =
          can::decode(can::encode_index(d.index.channel, d.index.count16, d.index.seq, ids), ids);
      FUZZ_CHECK(same(d, again));
      break;
    }
    case can::FrameKind::kHeartbeat: {
      FUZZ_CHECK(plain && f.id == ids.heartbeat_id());
      FUZZ_CHECK(f.dlc >= can::kHeartbeatMinDlc && f.dlc <= can::kMaxClassicDlc);
      const auto again = can::decode(can::encode_heartbeat(d.heartbeat, f.dlc, ids), ids);
      FUZZ_CHECK(same(d, again));
      break;
    }
    case can::FrameKind::kSync:
      FUZZ_CHECK(plain && f.id == ids.sync_id() && f.dlc == can::kSyncDlc);
      break;
    case can::FrameKind::kError: {
      FUZZ_CHECK((f.flags & can::frame_flag::kError) != 0);
      FUZZ_CHECK((d.error.classes & ~can::err_class::kMask) == 0);
      const auto again = can::decode(can::encode_error(d.error), ids);
      FUZZ_CHECK(again.kind == can::FrameKind::kError && again.error.classes == d.error.classes);
      break;
    }
    case can::FrameKind::kRejected:
      break;
  }
  return 0;
}
