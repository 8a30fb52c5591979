#pragma once
// CAN protocol v1 of the encoder interface board (docs/can-protocol.md):
// frame value type, encoders for every frame and one decoder that either
// returns a tagged payload or a precise rejection reason.
//
// Pure functions on plain values: no I/O, no allocation, no Linux headers.
// The SocketCAN backend adapts `struct can_frame` to CanFrame at its edge.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/common/wrapping.hpp"

namespace exodaq::drivers::can {

// ---------------------------------------------------------------------------
// Frame value type
// ---------------------------------------------------------------------------

// CanFrame::flags bits.
namespace frame_flag {
inline constexpr std::uint8_t kExtended = 1U << 0;  // 29-bit identifier (CAN_EFF_FLAG)
inline constexpr std::uint8_t kRtr = 1U << 1;       // remote transmission request (CAN_RTR_FLAG)
inline constexpr std::uint8_t kError = 1U << 2;  // error frame from the controller (CAN_ERR_FLAG)
inline constexpr std::uint8_t kFd = 1U << 3;     // CAN FD frame (struct canfd_frame)
}  // namespace frame_flag

inline constexpr std::uint8_t kMaxClassicDlc = 8;

struct CanFrame {
  std::uint32_t id = 0;    // identifier without flag bits (11 or 29 bits)
  std::uint8_t dlc = 0;    // payload length in bytes; > 8 only possible with kFd
  std::uint8_t flags = 0;  // frame_flag bits
  std::array<std::uint8_t, kMaxClassicDlc> data{};  // FD payload beyond 8 bytes is not kept
  std::int64_t mono_ns = 0;  // receive stamp, CLOCK_MONOTONIC (0 when unknown)
  std::int64_t wall_ns = 0;  // receive stamp, CLOCK_REALTIME (0 when unknown)
};

// ---------------------------------------------------------------------------
// Identifiers
// ---------------------------------------------------------------------------

inline constexpr int kBoardChannels = 6;  // protocol v1's, whatever the rig
inline constexpr int kChannelsPerCountsFrame = 3;

// Base identifiers of protocol v1 and the board number. Every board-sent ID
// (COUNTS_A/B, INDEX, HEARTBEAT) is base + board * board_stride; SYNC is a
// broadcast and never offset. Defaults: board 0 → 0x181, 0x182, 0x190..0x195,
// 0x701; board 1 → 0x1A1, 0x1A2, 0x1B0..0x1B5, 0x721.
struct ProtocolIds {
  std::uint32_t sync = 0x080;
  std::uint32_t counts_a = 0x181;
  std::uint32_t counts_b = 0x182;
  std::uint32_t index_base = 0x190;  // + channel 0..5
  std::uint32_t heartbeat = 0x701;
  std::uint32_t board = 0;
  std::uint32_t board_stride = 0x20;

  constexpr std::uint32_t sync_id() const noexcept { return sync; }
  constexpr std::uint32_t counts_a_id() const noexcept { return counts_a + offset(); }
  constexpr std::uint32_t counts_b_id() const noexcept { return counts_b + offset(); }
  constexpr std::uint32_t index_id(int channel) const noexcept {
    return index_base + offset() + static_cast<std::uint32_t>(channel);
  }
  constexpr std::uint32_t heartbeat_id() const noexcept { return heartbeat + offset(); }
  constexpr std::uint32_t offset() const noexcept { return board * board_stride; }
};

// nullptr when every effective ID fits in 11 bits and no two frames share an
// ID; otherwise a static message saying what is wrong (for config errors).
const char* validate(const ProtocolIds& ids) noexcept;

// ---------------------------------------------------------------------------
// Payload constants
// ---------------------------------------------------------------------------

inline constexpr std::uint8_t kSyncDlc = 0;
inline constexpr std::uint8_t kCountsDlc = 8;
inline constexpr std::uint8_t kIndexDlc = 3;
inline constexpr std::uint8_t kHeartbeatMinDlc = 2;

// HEARTBEAT byte 0.
enum class BoardState : std::uint8_t {
  kBoot = 0,       // counters not yet running
  kFreeRun = 1,    // sampling on its own 1 kHz timer
  kSyncSlave = 2,  // sampling on each received SYNC
  kFault = 3,      // stopped sampling; see the error bits
};

// HEARTBEAT byte 1: board error bits, set while the condition holds (sticky
// ones until the next heartbeat has been sent).
namespace board_error {
inline constexpr std::uint8_t kQuadrature = 1U << 0;       // illegal A/B transition on a channel
inline constexpr std::uint8_t kCounterOverflow = 1U << 1;  // a hardware counter saturated
inline constexpr std::uint8_t kIndex = 1U << 2;          // index pulse seen off its expected count
inline constexpr std::uint8_t kEncoderPower = 1U << 3;   // encoder supply out of range
inline constexpr std::uint8_t kTxOverrun = 1U << 4;      // board dropped frames it could not send
inline constexpr std::uint8_t kSyncLost = 1U << 5;       // SYNC expected but not received
inline constexpr std::uint8_t kConfig = 1U << 6;         // configuration / CRC error
inline constexpr std::uint8_t kWatchdogReset = 1U << 7;  // board restarted by its watchdog
}  // namespace board_error

// Optional HEARTBEAT bytes: byte 2 = channel bitmask of quadrature errors
// (bit c: channel c), byte 3 = protocol version (1). Absent bytes decode as 0.
inline constexpr std::uint8_t kProtocolVersion = 1;

// Error-frame classes, same values as linux/can/error.h (CAN_ERR_*), carried
// in the identifier of an error frame.
namespace err_class {
inline constexpr std::uint32_t kTxTimeout = 0x001;  // CAN_ERR_TX_TIMEOUT
inline constexpr std::uint32_t kLostArb = 0x002;    // CAN_ERR_LOSTARB   (data[0])
inline constexpr std::uint32_t kCrtl = 0x004;       // CAN_ERR_CRTL      (data[1])
inline constexpr std::uint32_t kProt = 0x008;       // CAN_ERR_PROT      (data[2], data[3])
inline constexpr std::uint32_t kTrx = 0x010;        // CAN_ERR_TRX       (data[4])
inline constexpr std::uint32_t kAck = 0x020;        // CAN_ERR_ACK
inline constexpr std::uint32_t kBusOff = 0x040;     // CAN_ERR_BUSOFF
inline constexpr std::uint32_t kBusError = 0x080;   // CAN_ERR_BUSERROR
inline constexpr std::uint32_t kRestarted = 0x100;  // CAN_ERR_RESTARTED
inline constexpr std::uint32_t kCnt = 0x200;        // CAN_ERR_CNT (data[6], data[7] valid)
inline constexpr std::uint32_t kMask = 0x1FFFFFFF;  // CAN_ERR_MASK
// What the SocketCAN backend asks for with CAN_RAW_ERR_FILTER.
inline constexpr std::uint32_t kSubscribed =
    kTxTimeout | kCrtl | kProt | kAck | kBusOff | kBusError | kRestarted;
}  // namespace err_class

// data[1] of a kCrtl error frame (CAN_ERR_CRTL_*).
namespace err_crtl {
inline constexpr std::uint8_t kRxOverflow = 0x01;
inline constexpr std::uint8_t kTxOverflow = 0x02;
inline constexpr std::uint8_t kRxWarning = 0x04;
inline constexpr std::uint8_t kTxWarning = 0x08;
inline constexpr std::uint8_t kRxPassive = 0x10;
inline constexpr std::uint8_t kTxPassive = 0x20;
inline constexpr std::uint8_t kActive = 0x40;
}  // namespace err_crtl

// data[2] of a kProt error frame (CAN_ERR_PROT_*), the ones the simulators send.
namespace err_prot {
inline constexpr std::uint8_t kBit = 0x01;  // CAN_ERR_PROT_BIT: single bit error
}  // namespace err_prot

inline constexpr std::uint8_t kErrorFrameDlc = 8;  // CAN_ERR_DLC

// ---------------------------------------------------------------------------
// Decoded payloads
// ---------------------------------------------------------------------------

enum class FrameKind : std::uint8_t {
  kRejected = 0,
  kSync,
  kCountsA,
  kCountsB,
  kIndex,
  kHeartbeat,
  kError,
};

enum class Reject : std::uint8_t {
  kNone = 0,
  kUnknownId,  // standard data frame whose ID is not one of the board's
  kWrongDlc,   // known ID, length not what protocol v1 says
  kRtr,        // remote request (v1 never uses them)
  kExtended,   // 29-bit identifier (v1 is CAN 2.0A)
  kFd,         // CAN FD frame (v1 is classic CAN)
};

std::string_view to_string(FrameKind kind) noexcept;
std::string_view to_string(Reject reason) noexcept;

struct CountsPayload {
  int first_channel = 0;                                         // 0 for A, 3 for B
  std::array<std::uint16_t, kChannelsPerCountsFrame> count16{};  // low 16 bits, as sent
  std::uint8_t index_latched = 0;  // bit i: channel first_channel + i (bits 3..7 ignored)
  std::uint8_t seq = 0;
};

struct IndexPayload {
  int channel = 0;
  std::uint16_t count16 = 0;  // low 16 bits of the count latched at the index edge
  std::uint8_t seq = 0;       // cycle in which the edge was latched
};

struct HeartbeatPayload {
  std::uint8_t state = 0;                      // BoardState value (unknown values passed through)
  std::uint8_t errors = 0;                     // board_error bits
  std::uint8_t channel_quadrature_errors = 0;  // optional byte 2, 0 when absent
  std::uint8_t protocol_version = 0;           // optional byte 3, 0 when absent
};

// An error frame as linux/can/error.h lays it out.
struct ErrorPayload {
  std::uint32_t classes = 0;           // err_class bits (identifier & CAN_ERR_MASK)
  std::uint8_t lost_arb_bit = 0;       // data[0]
  std::uint8_t controller = 0;         // data[1], err_crtl bits
  std::uint8_t protocol_type = 0;      // data[2], CAN_ERR_PROT_*
  std::uint8_t protocol_location = 0;  // data[3], CAN_ERR_PROT_LOC_*
  std::uint8_t transceiver = 0;        // data[4], CAN_ERR_TRX_*
  std::uint8_t tx_error_count = 0;     // data[6] (meaningful with kCnt)
  std::uint8_t rx_error_count = 0;     // data[7] (meaningful with kCnt)
};

// Tagged result: `kind` says which member is meaningful; `reject` is kNone
// unless kind == kRejected.
struct Decoded {
  FrameKind kind = FrameKind::kRejected;
  Reject reject = Reject::kNone;
  CountsPayload counts{};
  IndexPayload index{};
  HeartbeatPayload heartbeat{};
  ErrorPayload error{};
};

// Decodes one received frame. Checks in this order: error flag (decoded as
// kError whatever the ID), FD, RTR, extended, ID, DLC.
Decoded decode(const CanFrame& frame, const ProtocolIds& ids = {}) noexcept;

// ---------------------------------------------------------------------------
// Encoders (board simulator, sim backend, SYNC master, tests)
// ---------------------------------------------------------------------------

CanFrame encode_sync(const ProtocolIds& ids = {}) noexcept;
// which = 0 → COUNTS_A (channels 0..2), 1 → COUNTS_B (channels 3..5).
CanFrame encode_counts(int which, const std::array<std::uint16_t, kChannelsPerCountsFrame>& count16,
                       std::uint8_t index_latched, std::uint8_t seq,
                       const ProtocolIds& ids = {}) noexcept;
CanFrame encode_index(int channel, std::uint16_t count16, std::uint8_t seq,
                      const ProtocolIds& ids = {}) noexcept;
// dlc 2..8; bytes 2 and 3 are written when dlc allows, the rest are zero.
CanFrame encode_heartbeat(const HeartbeatPayload& hb, std::uint8_t dlc = 4,
                          const ProtocolIds& ids = {}) noexcept;
// An error frame as the kernel delivers it (flags kError, DLC 8).
CanFrame encode_error(const ErrorPayload& err) noexcept;

// ---------------------------------------------------------------------------
// Counter arithmetic
// ---------------------------------------------------------------------------

// 16-bit counts and 8-bit board sequences: exodaq/common/wrapping.hpp.
using exodaq::count_delta16;
using exodaq::seq_delta;
using exodaq::unwrap16;

}  // namespace exodaq::drivers::can
