#include "exodaq/drivers/can_codec.hpp"

namespace exodaq::drivers::can {
namespace {

void put_u16(std::array<std::uint8_t, kMaxClassicDlc>& d, int at, std::uint16_t v) noexcept {
  d[static_cast<std::size_t>(at)] = static_cast<std::uint8_t>(v & 0xFF);
  d[static_cast<std::size_t>(at) + 1] = static_cast<std::uint8_t>(v >> 8);
}

std::uint16_t get_u16(const std::array<std::uint8_t, kMaxClassicDlc>& d, int at) noexcept {
  return static_cast<std::uint16_t>(d[static_cast<std::size_t>(at)] |
                                    (d[static_cast<std::size_t>(at) + 1] << 8));
}

Decoded rejected(Reject why) noexcept {
  Decoded out;
  out.kind = FrameKind::kRejected;
  out.reject = why;
  return out;
}

Decoded decode_counts(const CanFrame& f, int which) noexcept {
  if (f.dlc != kCountsDlc) return rejected(Reject::kWrongDlc);
  Decoded out;
  out.kind = which == 0 ? FrameKind::kCountsA : FrameKind::kCountsB;
  out.counts.first_channel = which * kChannelsPerCountsFrame;
  for (int i = 0; i < kChannelsPerCountsFrame; ++i) {
    out.counts.count16[static_cast<std::size_t>(i)] = get_u16(f.data, 2 * i);
  }
  out.counts.index_latched = static_cast<std::uint8_t>(f.data[6] & 0x07);
  out.counts.seq = f.data[7];
  return out;
}

}  // namespace

const char* validate(const ProtocolIds& ids) noexcept {
  std::array<std::uint32_t, 4 + kBoardChannels> all{ids.sync_id(), ids.counts_a_id(),
                                                    ids.counts_b_id(), ids.heartbeat_id()};
  for (int c = 0; c < kBoardChannels; ++c) all[4 + static_cast<std::size_t>(c)] = ids.index_id(c);
  for (std::size_t i = 0; i < all.size(); ++i) {
    if (all[i] > kStandardIdMask) return "CAN identifier does not fit in 11 bits (CAN 2.0A)";
    for (std::size_t j = i + 1; j < all.size(); ++j) {
      if (all[i] == all[j]) return "two protocol frames share one CAN identifier";
    }
  }
  return nullptr;
}

std::string_view to_string(FrameKind kind) noexcept {
  switch (kind) {
    case FrameKind::kRejected:
      return "rejected";
    case FrameKind::kSync:
      return "sync";
    case FrameKind::kCountsA:
      return "counts_a";
    case FrameKind::kCountsB:
      return "counts_b";
    case FrameKind::kIndex:
      return "index";
    case FrameKind::kHeartbeat:
      return "heartbeat";
    case FrameKind::kError:
      return "error";
  }
  return "?";
}

std::string_view to_string(Reject reason) noexcept {
  switch (reason) {
    case Reject::kNone:
      return "none";
    case Reject::kUnknownId:
      return "unknown id";
    case Reject::kWrongDlc:
      return "wrong dlc";
    case Reject::kRtr:
      return "rtr";
    case Reject::kExtended:
      return "extended id";
    case Reject::kFd:
      return "can fd";
  }
  return "?";
}

Decoded decode(const CanFrame& f, const ProtocolIds& ids) noexcept {
  {
    Decoded out;
    if (decode_error(f, out.error)) {
      out.kind = FrameKind::kError;
      return out;
    }
  }
  if ((f.flags & frame_flag::kFd) != 0) return rejected(Reject::kFd);
  if ((f.flags & frame_flag::kRtr) != 0) return rejected(Reject::kRtr);
  if ((f.flags & frame_flag::kExtended) != 0) return rejected(Reject::kExtended);

  const std::uint32_t id = f.id;
  if (id == ids.counts_a_id()) return decode_counts(f, 0);
  if (id == ids.counts_b_id()) return decode_counts(f, 1);
  if (id >= ids.index_id(0) && id < ids.index_id(kBoardChannels)) {
    if (f.dlc != kIndexDlc) return rejected(Reject::kWrongDlc);
    Decoded out;
    out.kind = FrameKind::kIndex;
    out.index.channel = static_cast<int>(id - ids.index_id(0));
    out.index.count16 = get_u16(f.data, 0);
    out.index.seq = f.data[2];
    return out;
  }
  if (id == ids.heartbeat_id()) {
    if (f.dlc < kHeartbeatMinDlc || f.dlc > kMaxClassicDlc) return rejected(Reject::kWrongDlc);
    Decoded out;
    out.kind = FrameKind::kHeartbeat;
    out.heartbeat.state = f.data[0];
    out.heartbeat.errors = f.data[1];
    out.heartbeat.channel_quadrature_errors = f.dlc > 2 ? f.data[2] : 0;
    out.heartbeat.protocol_version = f.dlc > 3 ? f.data[3] : 0;
    return out;
  }
  if (id == ids.sync_id()) {
    if (f.dlc != kSyncDlc) return rejected(Reject::kWrongDlc);
    Decoded out;
    out.kind = FrameKind::kSync;
    return out;
  }
  return rejected(Reject::kUnknownId);
}

CanFrame encode_sync(const ProtocolIds& ids) noexcept {
  CanFrame f;
  f.id = ids.sync_id();
  f.dlc = kSyncDlc;
  return f;
}

CanFrame encode_counts(int which, const std::array<std::uint16_t, kChannelsPerCountsFrame>& count16,
                       std::uint8_t index_latched, std::uint8_t seq,
                       const ProtocolIds& ids) noexcept {
  CanFrame f;
  f.id = which == 0 ? ids.counts_a_id() : ids.counts_b_id();
  f.dlc = kCountsDlc;
  for (int i = 0; i < kChannelsPerCountsFrame; ++i) {
    put_u16(f.data, 2 * i, count16[static_cast<std::size_t>(i)]);
  }
  f.data[6] = static_cast<std::uint8_t>(index_latched & 0x07);
  f.data[7] = seq;
  return f;
}

CanFrame encode_index(int channel, std::uint16_t count16, std::uint8_t seq,
                      const ProtocolIds& ids) noexcept {
  CanFrame f;
  f.id = ids.index_id(channel);
  f.dlc = kIndexDlc;
  put_u16(f.data, 0, count16);
  f.data[2] = seq;
  return f;
}

CanFrame encode_heartbeat(const HeartbeatPayload& hb, std::uint8_t dlc,
                          const ProtocolIds& ids) noexcept {
  CanFrame f;
  f.id = ids.heartbeat_id();
  if (dlc < kHeartbeatMinDlc) dlc = kHeartbeatMinDlc;
  if (dlc > kMaxClassicDlc) dlc = kMaxClassicDlc;
  f.dlc = dlc;
  f.data[0] = hb.state;
  f.data[1] = hb.errors;
  if (dlc > 2) f.data[2] = hb.channel_quadrature_errors;
  if (dlc > 3) f.data[3] = hb.protocol_version;
  return f;
}

CanIdFilterSet port_filters(const ProtocolIds& ids, bool receive_sync) noexcept {
  CanIdFilterSet set;
  const auto block = [&set](std::uint32_t id) { set.add({id & 0x7E0U, 0x7E0U}); };
  block(ids.counts_a_id());
  block(ids.counts_b_id());
  block(ids.heartbeat_id());
  for (int c = 0; c < kBoardChannels; ++c) block(ids.index_id(c));
  if (receive_sync) block(ids.sync_id());
  return set;
}

}  // namespace exodaq::drivers::can
