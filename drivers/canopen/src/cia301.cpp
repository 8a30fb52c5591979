#include "exodaq/drivers/canopen/cia301.hpp"

#include "le_bytes.hpp"

namespace exodaq::drivers::canopen {
namespace {

namespace flag = can::frame_flag;

Decoded rejected(Reject why, NodeId node = 0) noexcept {
  Decoded out;
  out.reject = why;
  out.node = node;
  return out;
}

Decoded decode_nmt(const CanFrame& f) noexcept {
  if (f.dlc != kNmtDlc) return rejected(Reject::kWrongLength);
  if (!is_nmt_command(f.data[0])) return rejected(Reject::kUnknownCommand);
  if (f.data[1] > kMaxNodeId) return rejected(Reject::kBadNodeId);
  Decoded out;
  out.kind = FrameKind::kNmt;
  out.nmt.command = static_cast<NmtCommand>(f.data[0]);
  out.nmt.node = f.data[1];
  return out;
}

Decoded decode_sync(const CanFrame& f) noexcept {
  if (f.dlc > 1) return rejected(Reject::kWrongLength);
  Decoded out;
  out.kind = FrameKind::kSync;
  if (f.dlc == 1) {
    if (!is_sync_counter(f.data[0])) return rejected(Reject::kBadSyncCounter);
    out.sync.has_counter = true;
    out.sync.counter = f.data[0];
  }
  return out;
}

Decoded decode_emcy(const CanFrame& f, NodeId node) noexcept {
  if (f.dlc != kEmcyDlc) return rejected(Reject::kWrongLength, node);
  Decoded out;
  out.kind = FrameKind::kEmcy;
  out.node = node;
  out.emcy.error_code = get_u16(f.data, 0);
  out.emcy.error_register = f.data[2];
  for (std::size_t i = 0; i < out.emcy.manufacturer.size(); ++i) {
    out.emcy.manufacturer[i] = f.data[3 + i];
  }
  return out;
}

Decoded decode_error_control(const CanFrame& f, NodeId node) noexcept {
  if (f.dlc != kHeartbeatDlc) return rejected(Reject::kWrongLength, node);
  if ((f.data[0] & 0x80) != 0) return rejected(Reject::kReservedBits, node);
  if (!is_nmt_state(f.data[0])) return rejected(Reject::kUnknownState, node);
  Decoded out;
  out.node = node;
  out.heartbeat.node = node;
  out.heartbeat.state = static_cast<NmtState>(f.data[0]);
  out.kind = out.heartbeat.state == NmtState::kBootUp ? FrameKind::kBootUp : FrameKind::kHeartbeat;
  return out;
}

// Byte 0 of an initiate transfer: cs(3) x(1) n(2) e(1) s(1).
struct InitiateBits {
  bool reserved = false;
  bool expedited = false;
  bool size_indicated = false;
  std::uint8_t unused = 0;  // n: bytes of the 4 that carry no data
};

InitiateBits initiate_bits(std::uint8_t b0) noexcept {
  return {(b0 & 0x10) != 0, (b0 & 0x02) != 0, (b0 & 0x01) != 0,
          static_cast<std::uint8_t>((b0 >> 2) & 0x03)};
}

// Fills value/size of an expedited initiate (download request, upload
// response); kNone, kReservedBits or kUnsupported (segmented).
Reject expedited_data(const CanFrame& f, SdoPayload& sdo) noexcept {
  const InitiateBits bits = initiate_bits(f.data[0]);
  if (bits.reserved) return Reject::kReservedBits;
  if (!bits.expedited) return Reject::kUnsupported;
  if (!bits.size_indicated && bits.unused != 0) return Reject::kReservedBits;
  sdo.size_indicated = bits.size_indicated;
  sdo.size = static_cast<std::uint8_t>(kSdoExpeditedMax - bits.unused);
  sdo.value = get_u32(f.data, 4) & size_mask(sdo.size);
  return Reject::kNone;
}

Reject decode_request(const CanFrame& f, SdoPayload& sdo) noexcept {
  const std::uint8_t cs = f.data[0] >> 5;
  switch (cs) {
    case sdo_cs::kInitiateDownload:
      sdo.kind = SdoKind::kDownloadRequest;
      return expedited_data(f, sdo);
    case sdo_cs::kInitiateUpload:
      sdo.kind = SdoKind::kUploadRequest;
      return (f.data[0] & 0x1F) != 0 ? Reject::kReservedBits : Reject::kNone;
    case sdo_cs::kAbort:
      sdo.kind = SdoKind::kAbort;
      sdo.abort_code = get_u32(f.data, 4);
      return (f.data[0] & 0x1F) != 0 ? Reject::kReservedBits : Reject::kNone;
    case sdo_cs::kDownloadSegment:
    case sdo_cs::kUploadSegment:
    case sdo_cs::kBlockUpload:
    case sdo_cs::kBlockDownload:
      return Reject::kUnsupported;
    default:
      return Reject::kUnknownCommand;
  }
}

Reject decode_response(const CanFrame& f, SdoPayload& sdo) noexcept {
  const std::uint8_t cs = f.data[0] >> 5;
  switch (cs) {
    case sdo_cs::kServerInitiateUpload:
      sdo.kind = SdoKind::kUploadResponse;
      return expedited_data(f, sdo);
    case sdo_cs::kServerInitiateDownload:
      sdo.kind = SdoKind::kDownloadResponse;
      return (f.data[0] & 0x1F) != 0 ? Reject::kReservedBits : Reject::kNone;
    case sdo_cs::kAbort:
      sdo.kind = SdoKind::kAbort;
      sdo.abort_code = get_u32(f.data, 4);
      return (f.data[0] & 0x1F) != 0 ? Reject::kReservedBits : Reject::kNone;
    case sdo_cs::kServerUploadSegment:
    case sdo_cs::kServerDownloadSegment:
    case sdo_cs::kServerBlockDownload:
    case sdo_cs::kServerBlockUpload:
      return Reject::kUnsupported;
    default:
      return Reject::kUnknownCommand;
  }
}

Decoded decode_sdo(const CanFrame& f, NodeId node, bool from_client) noexcept {
  if (f.dlc != kSdoDlc) return rejected(Reject::kWrongLength, node);
  SdoPayload sdo;
  sdo.from_client = from_client;
  sdo.node = node;
  sdo.at = {get_u16(f.data, 1), f.data[3]};
  const Reject why = from_client ? decode_request(f, sdo) : decode_response(f, sdo);
  if (why != Reject::kNone) return rejected(why, node);
  Decoded out;
  out.kind = FrameKind::kSdo;
  out.node = node;
  out.sdo = sdo;
  return out;
}

Decoded decode_pdo(const CanFrame& f, NodeId node, int pdo, bool transmit) noexcept {
  Decoded out;
  out.kind = transmit ? FrameKind::kTpdo : FrameKind::kRpdo;
  out.node = node;
  out.pdo.pdo = pdo;
  out.pdo.node = node;
  out.pdo.length = f.dlc;
  return out;
}

CanFrame frame(std::uint32_t id, std::uint8_t dlc) noexcept {
  CanFrame f;
  f.id = id;
  f.dlc = dlc;
  return f;
}

CanFrame sdo_frame(std::uint32_t id, std::uint8_t b0, Multiplexer at, std::uint32_t data) noexcept {
  CanFrame f = frame(id, kSdoDlc);
  f.data[0] = b0;
  put_u16(f.data, 1, at.index);
  f.data[3] = at.sub;
  put_u32(f.data, 4, data);
  return f;
}

std::uint8_t expedited_b0(std::uint8_t cs, std::uint8_t size) noexcept {
  const auto unused = static_cast<std::uint8_t>(kSdoExpeditedMax - size);
  return static_cast<std::uint8_t>((cs << 5) | (unused << 2) | 0x03);
}

}  // namespace

std::string_view abort_name(std::uint32_t code) noexcept {
  switch (static_cast<SdoAbort>(code)) {
    case SdoAbort::kToggleBit:
      return "toggle bit not alternated";
    case SdoAbort::kTimeout:
      return "SDO protocol timed out";
    case SdoAbort::kUnknownCommand:
      return "client/server command specifier not valid or unknown";
    case SdoAbort::kInvalidBlockSize:
      return "invalid block size";
    case SdoAbort::kInvalidSequenceNumber:
      return "invalid sequence number";
    case SdoAbort::kCrcError:
      return "CRC error";
    case SdoAbort::kOutOfMemory:
      return "out of memory";
    case SdoAbort::kUnsupportedAccess:
      return "unsupported access to an object";
    case SdoAbort::kWriteOnly:
      return "attempt to read a write only object";
    case SdoAbort::kReadOnly:
      return "attempt to write a read only object";
    case SdoAbort::kNoObject:
      return "object does not exist in the object dictionary";
    case SdoAbort::kNotMappable:
      return "object cannot be mapped to the PDO";
    case SdoAbort::kPdoLengthExceeded:
      return "the number and length of the objects to be mapped would exceed PDO length";
    case SdoAbort::kParameterIncompatible:
      return "general parameter incompatibility reason";
    case SdoAbort::kInternalIncompatible:
      return "general internal incompatibility in the device";
    case SdoAbort::kHardwareError:
      return "access failed due to a hardware error";
    case SdoAbort::kLengthMismatch:
      return "data type does not match, length of service parameter does not match";
    case SdoAbort::kLengthTooHigh:
      return "data type does not match, length of service parameter too high";
    case SdoAbort::kLengthTooLow:
      return "data type does not match, length of service parameter too low";
    case SdoAbort::kNoSubIndex:
      return "sub-index does not exist";
    case SdoAbort::kInvalidValue:
      return "invalid value for parameter";
    case SdoAbort::kValueTooHigh:
      return "value of parameter written too high";
    case SdoAbort::kValueTooLow:
      return "value of parameter written too low";
    case SdoAbort::kMaxBelowMin:
      return "maximum value is less than minimum value";
    case SdoAbort::kResourceNotAvailable:
      return "resource not available: SDO connection";
    case SdoAbort::kGeneralError:
      return "general error";
    case SdoAbort::kCannotTransfer:
      return "data cannot be transferred or stored to the application";
    case SdoAbort::kCannotTransferLocalControl:
      return "data cannot be transferred or stored to the application because of local control";
    case SdoAbort::kCannotTransferDeviceState:
      return "data cannot be transferred or stored to the application because of the present "
             "device state";
    case SdoAbort::kNoDictionary:
      return "object dictionary dynamic generation fails or no object dictionary is present";
    case SdoAbort::kNoData:
      return "no data available";
  }
  return "unknown abort code";
}

std::string_view to_string(FrameKind kind) noexcept {
  switch (kind) {
    case FrameKind::kRejected:
      return "rejected";
    case FrameKind::kNmt:
      return "nmt";
    case FrameKind::kSync:
      return "sync";
    case FrameKind::kEmcy:
      return "emcy";
    case FrameKind::kTpdo:
      return "tpdo";
    case FrameKind::kRpdo:
      return "rpdo";
    case FrameKind::kSdo:
      return "sdo";
    case FrameKind::kHeartbeat:
      return "heartbeat";
    case FrameKind::kBootUp:
      return "boot-up";
  }
  return "?";
}

std::string_view to_string(Reject reason) noexcept {
  switch (reason) {
    case Reject::kNone:
      return "none";
    case Reject::kErrorFrame:
      return "error frame";
    case Reject::kFd:
      return "can fd";
    case Reject::kRtr:
      return "rtr";
    case Reject::kExtended:
      return "extended id";
    case Reject::kUnknownId:
      return "unknown id";
    case Reject::kWrongLength:
      return "wrong length";
    case Reject::kReservedBits:
      return "reserved bits set";
    case Reject::kUnknownCommand:
      return "unknown command specifier";
    case Reject::kUnknownState:
      return "unknown nmt state";
    case Reject::kBadNodeId:
      return "bad node id";
    case Reject::kBadSyncCounter:
      return "bad sync counter";
    case Reject::kUnsupported:
      return "unsupported service";
  }
  return "?";
}

Decoded decode_frame(const CanFrame& f) noexcept {
  if ((f.flags & flag::kError) != 0) return rejected(Reject::kErrorFrame);
  if ((f.flags & flag::kFd) != 0) return rejected(Reject::kFd);
  if ((f.flags & flag::kRtr) != 0) return rejected(Reject::kRtr);
  if ((f.flags & flag::kExtended) != 0) return rejected(Reject::kExtended);
  if (f.id > cob::kIdMask) return rejected(Reject::kUnknownId);

  const NodeId node = cob::node_of(f.id);
  const FunctionCode fc = cob::function_of(f.id);
  if (fc == FunctionCode::kNmt) {
    return f.id == cob::kNmt ? decode_nmt(f) : rejected(Reject::kUnknownId);
  }
  if (fc == FunctionCode::kSyncEmcy) return node == 0 ? decode_sync(f) : decode_emcy(f, node);
  if (fc == FunctionCode::kTime) {
    return f.id == cob::kTime ? rejected(Reject::kUnsupported) : rejected(Reject::kUnknownId);
  }
  if (node == 0) return rejected(Reject::kUnknownId);
  switch (fc) {
    case FunctionCode::kTpdo1:
    case FunctionCode::kTpdo2:
    case FunctionCode::kTpdo3:
    case FunctionCode::kTpdo4:
      return decode_pdo(f, node, static_cast<int>(fc) / 2, true);
    case FunctionCode::kRpdo1:
    case FunctionCode::kRpdo2:
    case FunctionCode::kRpdo3:
    case FunctionCode::kRpdo4:
      return decode_pdo(f, node, static_cast<int>(fc) / 2 - 1, false);
    case FunctionCode::kSdoTx:
      return decode_sdo(f, node, false);
    case FunctionCode::kSdoRx:
      return decode_sdo(f, node, true);
    case FunctionCode::kErrorControl:
      return decode_error_control(f, node);
    default:
      return rejected(Reject::kUnknownId);
  }
}

CanFrame encode_nmt(NmtCommand command, NodeId node) noexcept {
  CanFrame f = frame(cob::kNmt, kNmtDlc);
  f.data[0] = static_cast<std::uint8_t>(command);
  f.data[1] = node;
  return f;
}

CanFrame encode_sync() noexcept {
  return frame(cob::kSync, 0);
}

CanFrame encode_sync(std::uint8_t counter) noexcept {
  CanFrame f = frame(cob::kSync, 1);
  f.data[0] = counter;
  return f;
}

CanFrame encode_heartbeat(NodeId node, NmtState state) noexcept {
  CanFrame f = frame(cob::heartbeat(node), kHeartbeatDlc);
  f.data[0] = static_cast<std::uint8_t>(state);
  return f;
}

CanFrame encode_boot_up(NodeId node) noexcept {
  return encode_heartbeat(node, NmtState::kBootUp);
}

CanFrame encode_emcy(NodeId node, const EmcyPayload& emcy) noexcept {
  CanFrame f = frame(cob::emcy(node), kEmcyDlc);
  put_u16(f.data, 0, emcy.error_code);
  f.data[2] = emcy.error_register;
  for (std::size_t i = 0; i < emcy.manufacturer.size(); ++i) f.data[3 + i] = emcy.manufacturer[i];
  return f;
}

CanFrame encode_sdo_upload_request(NodeId node, Multiplexer at) noexcept {
  return sdo_frame(cob::sdo_rx(node), sdo_cs::kInitiateUpload << 5, at, 0);
}

CanFrame encode_sdo_upload_response(NodeId node, Multiplexer at, std::uint32_t value,
                                    std::uint8_t size) noexcept {
  return sdo_frame(cob::sdo_tx(node), expedited_b0(sdo_cs::kServerInitiateUpload, size), at,
                   value & size_mask(size));
}

CanFrame encode_sdo_download_request(NodeId node, Multiplexer at, std::uint32_t value,
                                     std::uint8_t size) noexcept {
  return sdo_frame(cob::sdo_rx(node), expedited_b0(sdo_cs::kInitiateDownload, size), at,
                   value & size_mask(size));
}

CanFrame encode_sdo_download_response(NodeId node, Multiplexer at) noexcept {
  return sdo_frame(cob::sdo_tx(node), sdo_cs::kServerInitiateDownload << 5, at, 0);
}

CanFrame encode_sdo_abort(NodeId node, Multiplexer at, std::uint32_t code,
                          bool from_client) noexcept {
  return sdo_frame(from_client ? cob::sdo_rx(node) : cob::sdo_tx(node), sdo_cs::kAbort << 5, at,
                   code);
}

CanFrame encode_tpdo(int pdo, NodeId node, const std::array<std::uint8_t, 8>& data,
                     std::uint8_t length) noexcept {
  CanFrame f = frame(cob::tpdo(pdo, node), length > 8 ? std::uint8_t{8} : length);
  for (std::size_t i = 0; i < f.dlc; ++i) f.data[i] = data[i];
  return f;
}

}  // namespace exodaq::drivers::canopen
