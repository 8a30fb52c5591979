#pragma once
// CANopen communication (CiA 301) on classic CAN 2.0A: the predefined
// connection set's identifiers, NMT, heartbeat and boot-up, SYNC with and
// without its counter, EMCY, expedited SDO, and one decoder that either
// returns a tagged payload or a precise rejection reason.
//
// Pure functions on plain values: no I/O, no allocation. Frames are
// can::CanFrame (exodaq/drivers/can_codec.hpp); stamps are passed through.
// Multi-byte fields are little-endian, as CiA 301 sends them.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/drivers/can_codec.hpp"

namespace exodaq::drivers::canopen {

using can::CanFrame;

// ---------------------------------------------------------------------------
// Node ids and identifiers (predefined connection set)
// ---------------------------------------------------------------------------

using NodeId = std::uint8_t;
inline constexpr NodeId kMinNodeId = 1;
inline constexpr NodeId kMaxNodeId = 127;
inline constexpr NodeId kAllNodes = 0;  // NMT broadcast
constexpr bool is_node_id(int node) noexcept {
  return node >= kMinNodeId && node <= kMaxNodeId;
}

inline constexpr int kTpdoCount = 4;  // TPDO1..4 of the predefined connection set

// Function codes: bits 10..7 of an 11-bit COB-ID; bits 6..0 are the node id.
enum class FunctionCode : std::uint8_t {
  kNmt = 0x0,
  kSyncEmcy = 0x1,  // node 0: SYNC, node 1..127: EMCY
  kTime = 0x2,
  kTpdo1 = 0x3,
  kRpdo1 = 0x4,
  kTpdo2 = 0x5,
  kRpdo2 = 0x6,
  kTpdo3 = 0x7,
  kRpdo3 = 0x8,
  kTpdo4 = 0x9,
  kRpdo4 = 0xA,
  kSdoTx = 0xB,         // server → client (response)
  kSdoRx = 0xC,         // client → server (request)
  kErrorControl = 0xE,  // heartbeat, boot-up
};

namespace cob {
inline constexpr std::uint32_t kNmt = 0x000;
inline constexpr std::uint32_t kSync = 0x080;
inline constexpr std::uint32_t kTime = 0x100;
inline constexpr std::uint32_t kIdMask = 0x7FF;

constexpr std::uint32_t make(FunctionCode fc, NodeId node) noexcept {
  return (static_cast<std::uint32_t>(fc) << 7) | node;
}
constexpr FunctionCode function_of(std::uint32_t id) noexcept {
  return static_cast<FunctionCode>((id >> 7) & 0xF);
}
constexpr NodeId node_of(std::uint32_t id) noexcept {
  return static_cast<NodeId>(id & 0x7F);
}

constexpr std::uint32_t emcy(NodeId node) noexcept {
  return make(FunctionCode::kSyncEmcy, node);
}
// pdo 1..4: 0x180/0x280/0x380/0x480 + node.
constexpr std::uint32_t tpdo(int pdo, NodeId node) noexcept {
  return 0x180 + 0x100 * static_cast<std::uint32_t>(pdo - 1) + node;
}
// pdo 1..4: 0x200/0x300/0x400/0x500 + node.
constexpr std::uint32_t rpdo(int pdo, NodeId node) noexcept {
  return 0x200 + 0x100 * static_cast<std::uint32_t>(pdo - 1) + node;
}
constexpr std::uint32_t sdo_tx(NodeId node) noexcept {
  return make(FunctionCode::kSdoTx, node);
}
constexpr std::uint32_t sdo_rx(NodeId node) noexcept {
  return make(FunctionCode::kSdoRx, node);
}
constexpr std::uint32_t heartbeat(NodeId node) noexcept {
  return make(FunctionCode::kErrorControl, node);
}
}  // namespace cob

// ---------------------------------------------------------------------------
// NMT and node states
// ---------------------------------------------------------------------------

inline constexpr std::uint8_t kNmtDlc = 2;  // command specifier, node id (0: all)

enum class NmtCommand : std::uint8_t {
  kStart = 0x01,
  kStop = 0x02,
  kEnterPreOperational = 0x80,
  kResetNode = 0x81,
  kResetCommunication = 0x82,
};

// Byte 0 of a heartbeat; kBootUp is the boot-up message (same identifier).
// Bit 7 is node guarding's toggle bit: reserved (0) in a heartbeat.
enum class NmtState : std::uint8_t {
  kBootUp = 0x00,
  kStopped = 0x04,
  kOperational = 0x05,
  kPreOperational = 0x7F,
};
inline constexpr std::uint8_t kHeartbeatDlc = 1;

constexpr bool is_nmt_command(std::uint8_t cs) noexcept {
  return cs == 0x01 || cs == 0x02 || cs == 0x80 || cs == 0x81 || cs == 0x82;
}
constexpr bool is_nmt_state(std::uint8_t s) noexcept {
  return s == 0x00 || s == 0x04 || s == 0x05 || s == 0x7F;
}

// ---------------------------------------------------------------------------
// SYNC
// ---------------------------------------------------------------------------

// Object 0x1019 (synchronous counter overflow value): 0 = SYNC without data,
// 2..240 = SYNC with one counter byte counting 1..overflow; 1 and 241..255
// are reserved.
inline constexpr std::uint8_t kSyncCounterMax = 240;
constexpr bool is_sync_overflow(int overflow) noexcept {
  return overflow == 0 || (overflow >= 2 && overflow <= kSyncCounterMax);
}
constexpr bool is_sync_counter(int counter) noexcept {
  return counter >= 1 && counter <= kSyncCounterMax;
}
// The counter after `counter` for an overflow value 2..240: 1 follows
// `overflow`. The producer's first counter is 1.
constexpr std::uint8_t next_sync_counter(std::uint8_t counter, std::uint8_t overflow) noexcept {
  return counter >= overflow ? std::uint8_t{1} : static_cast<std::uint8_t>(counter + 1);
}

// ---------------------------------------------------------------------------
// EMCY
// ---------------------------------------------------------------------------

inline constexpr std::uint8_t kEmcyDlc = 8;

// Error register (object 0x1001), byte 2 of an EMCY. Bit 6 is reserved.
namespace error_register {
inline constexpr std::uint8_t kGeneric = 1U << 0;
inline constexpr std::uint8_t kCurrent = 1U << 1;
inline constexpr std::uint8_t kVoltage = 1U << 2;
inline constexpr std::uint8_t kTemperature = 1U << 3;
inline constexpr std::uint8_t kCommunication = 1U << 4;
inline constexpr std::uint8_t kDeviceProfile = 1U << 5;
inline constexpr std::uint8_t kManufacturer = 1U << 7;
}  // namespace error_register

// EMCY error codes used here (CiA 301 table; the high byte is the class).
namespace emcy_code {
inline constexpr std::uint16_t kNoError = 0x0000;  // error reset: the node's errors cleared
inline constexpr std::uint16_t kGeneric = 0x1000;
inline constexpr std::uint16_t kVoltage = 0x3000;
inline constexpr std::uint16_t kDeviceHardware = 0x5000;
inline constexpr std::uint16_t kCanOverrun = 0x8110;
inline constexpr std::uint16_t kCanErrorPassive = 0x8120;
inline constexpr std::uint16_t kHeartbeatError = 0x8130;  // life guard or heartbeat error
inline constexpr std::uint16_t kRecoveredFromBusOff = 0x8140;
inline constexpr std::uint16_t kPdoLength = 0x8210;  // PDO not processed due to length error
inline constexpr std::uint16_t kUnexpectedSyncLength = 0x8240;
}  // namespace emcy_code

struct EmcyPayload {
  std::uint16_t error_code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
};

// ---------------------------------------------------------------------------
// SDO (expedited transfers only)
// ---------------------------------------------------------------------------

inline constexpr std::uint8_t kSdoDlc = 8;
inline constexpr int kSdoExpeditedMax = 4;  // bytes

// Byte 0 of an SDO frame: command specifier in bits 7..5.
namespace sdo_cs {
// client → server (ccs)
inline constexpr std::uint8_t kDownloadSegment = 0;
inline constexpr std::uint8_t kInitiateDownload = 1;
inline constexpr std::uint8_t kInitiateUpload = 2;
inline constexpr std::uint8_t kUploadSegment = 3;
inline constexpr std::uint8_t kAbort = 4;
inline constexpr std::uint8_t kBlockUpload = 5;
inline constexpr std::uint8_t kBlockDownload = 6;
// server → client (scs)
inline constexpr std::uint8_t kServerUploadSegment = 0;
inline constexpr std::uint8_t kServerDownloadSegment = 1;
inline constexpr std::uint8_t kServerInitiateUpload = 2;
inline constexpr std::uint8_t kServerInitiateDownload = 3;
inline constexpr std::uint8_t kServerBlockDownload = 5;
inline constexpr std::uint8_t kServerBlockUpload = 6;
}  // namespace sdo_cs

// SDO abort codes (CiA 301, "SDO abort codes" table).
enum class SdoAbort : std::uint32_t {
  kToggleBit = 0x05030000,
  kTimeout = 0x05040000,
  kUnknownCommand = 0x05040001,
  kInvalidBlockSize = 0x05040002,
  kInvalidSequenceNumber = 0x05040003,
  kCrcError = 0x05040004,
  kOutOfMemory = 0x05040005,
  kUnsupportedAccess = 0x06010000,
  kWriteOnly = 0x06010001,
  kReadOnly = 0x06010002,
  kNoObject = 0x06020000,
  kNotMappable = 0x06040041,
  kPdoLengthExceeded = 0x06040042,
  kParameterIncompatible = 0x06040043,
  kInternalIncompatible = 0x06040047,
  kHardwareError = 0x06060000,
  kLengthMismatch = 0x06070010,
  kLengthTooHigh = 0x06070012,
  kLengthTooLow = 0x06070013,
  kNoSubIndex = 0x06090011,
  kInvalidValue = 0x06090030,
  kValueTooHigh = 0x06090031,
  kValueTooLow = 0x06090032,
  kMaxBelowMin = 0x06090036,
  kResourceNotAvailable = 0x060A0023,
  kGeneralError = 0x08000000,
  kCannotTransfer = 0x08000020,
  kCannotTransferLocalControl = 0x08000021,
  kCannotTransferDeviceState = 0x08000022,
  kNoDictionary = 0x08000023,
  kNoData = 0x08000024,
};

// The CiA 301 description of an abort code; "unknown abort code" otherwise.
std::string_view abort_name(std::uint32_t code) noexcept;

// An object dictionary entry's address.
struct Multiplexer {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  friend constexpr bool operator==(const Multiplexer&, const Multiplexer&) = default;
};

enum class SdoKind : std::uint8_t {
  kUploadRequest,     // client: read the entry
  kUploadResponse,    // server: the entry's value (expedited)
  kDownloadRequest,   // client: write the value (expedited)
  kDownloadResponse,  // server: written
  kAbort,             // either side: transfer aborted with `abort_code`
};

struct SdoPayload {
  SdoKind kind = SdoKind::kAbort;
  bool from_client = false;  // arrived on 0x600 + node (request) rather than 0x580 + node
  NodeId node = 0;           // the server's node id
  Multiplexer at{};
  std::uint32_t value = 0;  // expedited data, little-endian, unused bytes 0
  std::uint8_t size = 0;    // data bytes 1..4 (4 when the size is not indicated)
  bool size_indicated = false;
  std::uint32_t abort_code = 0;
};

// ---------------------------------------------------------------------------
// Decoder
// ---------------------------------------------------------------------------

enum class FrameKind : std::uint8_t {
  kRejected = 0,
  kNmt,
  kSync,
  kEmcy,
  kTpdo,
  kRpdo,
  kSdo,
  kHeartbeat,
  kBootUp,
};

enum class Reject : std::uint8_t {
  kNone = 0,
  kErrorFrame,      // controller error frame: the transport's business, never data
  kFd,              // CAN FD frame (CiA 301 is classic CAN here)
  kRtr,             // remote request (node guarding, RTR PDOs: not used)
  kExtended,        // 29-bit identifier
  kUnknownId,       // outside the predefined connection set (or node id 0 where one is needed)
  kWrongLength,     // the service's fixed length (NMT 2, SYNC 0/1, EMCY 8, SDO 8, heartbeat 1)
  kReservedBits,    // a reserved bit set (heartbeat bit 7, SDO command byte)
  kUnknownCommand,  // NMT command or SDO command specifier CiA 301 does not define
  kUnknownState,    // heartbeat state other than 0x00/0x04/0x05/0x7F
  kBadNodeId,       // NMT addressed to node 128..255
  kBadSyncCounter,  // SYNC counter 0 or above 240
  kUnsupported,     // valid CiA 301, not handled here: TIME, segmented and block SDO
};
inline constexpr int kRejectCount = static_cast<int>(Reject::kUnsupported) + 1;

std::string_view to_string(FrameKind kind) noexcept;
std::string_view to_string(Reject reason) noexcept;

struct NmtPayload {
  NmtCommand command = NmtCommand::kStart;
  NodeId node = 0;  // 0: all nodes
};

struct SyncPayload {
  bool has_counter = false;
  std::uint8_t counter = 0;  // 1..240 when has_counter
};

struct HeartbeatPayload {
  NodeId node = 0;
  NmtState state = NmtState::kBootUp;
};

// A PDO as raw bytes: its layout is the mapping's business (cia406.hpp).
struct PdoPayload {
  int pdo = 0;  // 1..4
  NodeId node = 0;
  std::uint8_t length = 0;
};

// Tagged result: `kind` says which member is meaningful; `reject` is kNone
// unless kind == kRejected. `node` is the sender (or addressee) for every
// node-addressed service, 0 for NMT, SYNC and rejected frames.
struct Decoded {
  FrameKind kind = FrameKind::kRejected;
  Reject reject = Reject::kNone;
  NodeId node = 0;
  NmtPayload nmt{};
  SyncPayload sync{};
  EmcyPayload emcy{};
  SdoPayload sdo{};
  HeartbeatPayload heartbeat{};
  PdoPayload pdo{};
};

// Checks in this order: error flag, FD, RTR, extended, identifier, length,
// content (reserved bits, command, state, counter). Reserved data bytes that
// CiA 301 tells receivers to ignore (bytes 4..7 of an upload request or a
// download response, EMCY error register bit 6) are ignored. (Not named
// decode: can::decode(CanFrame) would make unqualified calls ambiguous.)
Decoded decode_frame(const CanFrame& frame) noexcept;

// ---------------------------------------------------------------------------
// Encoders
// ---------------------------------------------------------------------------

CanFrame encode_nmt(NmtCommand command, NodeId node) noexcept;
CanFrame encode_sync() noexcept;
CanFrame encode_sync(std::uint8_t counter) noexcept;  // DLC 1
CanFrame encode_heartbeat(NodeId node, NmtState state) noexcept;
CanFrame encode_boot_up(NodeId node) noexcept;
CanFrame encode_emcy(NodeId node, const EmcyPayload& emcy) noexcept;

CanFrame encode_sdo_upload_request(NodeId node, Multiplexer at) noexcept;
// size 1..4 (size indicated).
CanFrame encode_sdo_upload_response(NodeId node, Multiplexer at, std::uint32_t value,
                                    std::uint8_t size) noexcept;
CanFrame encode_sdo_download_request(NodeId node, Multiplexer at, std::uint32_t value,
                                     std::uint8_t size) noexcept;
CanFrame encode_sdo_download_response(NodeId node, Multiplexer at) noexcept;
// from_client: on 0x600 + node (the client aborts), else on 0x580 + node.
CanFrame encode_sdo_abort(NodeId node, Multiplexer at, std::uint32_t code,
                          bool from_client) noexcept;

// `length` bytes (0..8) of `data` on TPDO `pdo` (1..4) of `node`.
CanFrame encode_tpdo(int pdo, NodeId node, const std::array<std::uint8_t, 8>& data,
                     std::uint8_t length) noexcept;

}  // namespace exodaq::drivers::canopen
