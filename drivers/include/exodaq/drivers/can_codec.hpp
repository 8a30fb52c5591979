#pragma once
// CAN protocol v1 of the encoder interface board (docs/can-protocol.md):
// frame value type, encoders for every frame and one decoder that either
// returns a tagged payload or a precise rejection reason.
//
// Pure functions on plain values: no I/O, no allocation, no Linux headers.
// Frames, error frames and filters of any CAN protocol: can_frame.hpp.
#include <array>
#include <cstdint>
#include <string_view>

#include "exodaq/common/wrapping.hpp"
#include "exodaq/drivers/can_frame.hpp"

namespace exodaq::drivers::can {

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

// The kernel filters of a v1 board: the aligned 32-ID blocks (mask 0x7E0)
// that hold its COUNTS, INDEX and HEARTBEAT IDs (and SYNC's when
// `receive_sync`), so frames addressed to the board but malformed (wrong
// DLC, an unused ID in its block, RTR, 29-bit) still reach the decoder and
// are counted, while other nodes' traffic stays in the kernel.
CanIdFilterSet port_filters(const ProtocolIds& ids, bool receive_sync) noexcept;

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

// ---------------------------------------------------------------------------
// Counter arithmetic
// ---------------------------------------------------------------------------

// 16-bit counts and 8-bit board sequences: exodaq/common/wrapping.hpp.
using exodaq::seq_delta;

}  // namespace exodaq::drivers::can
