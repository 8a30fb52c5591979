#pragma once
// CAN frames as every protocol and the SocketCAN transport see them: the
// frame value type, the controller's error frames (linux/can/error.h's
// layout), and the identifier filters a protocol asks the kernel for.
// Plain values, no I/O, no Linux headers: the SocketCAN port adapts
// `struct can_frame` at its edge.
#include <array>
#include <cstdint>

#include "exodaq/drivers/encoder_sample.hpp"

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
// A frame this socket sent, received back as it went on the bus
// (CanPortConfig::receive_own: CAN_RAW_RECV_OWN_MSGS, MSG_CONFIRM).
inline constexpr std::uint8_t kOwn = 1U << 4;
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
// Error frames
// ---------------------------------------------------------------------------

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

// The bus state an error frame leaves (bus-off, restarted, controller
// warning/passive/active); `current` when the frame says nothing about it.
BusState bus_state_after(BusState current, const ErrorPayload& error) noexcept;

// The error frame's payload; false for any other frame.
bool decode_error(const CanFrame& frame, ErrorPayload& out) noexcept;
// An error frame as the kernel delivers it (flags kError, DLC 8).
CanFrame encode_error(const ErrorPayload& err) noexcept;

// ---------------------------------------------------------------------------
// Identifier filters (CAN_RAW_FILTER)
// ---------------------------------------------------------------------------

inline constexpr std::uint32_t kStandardIdMask = 0x7FF;

// A standard (11-bit) data frame passes when (id & mask) == (filter.id & mask).
struct CanIdFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = kStandardIdMask;
  constexpr bool passes(std::uint32_t frame_id) const noexcept {
    return (frame_id & mask) == (id & mask);
  }
};

// A protocol's filters, fixed capacity (a value: reopening the port in the
// loop allocates nothing).
struct CanIdFilterSet {
  static constexpr int kCapacity = 72;
  std::array<CanIdFilter, kCapacity> filters{};
  int count = 0;

  // false when full.
  constexpr bool add(CanIdFilter f) noexcept {
    for (int i = 0; i < count; ++i) {
      const CanIdFilter& g = filters[static_cast<std::size_t>(i)];
      if (g.mask == f.mask && g.passes(f.id)) return true;  // already there
    }
    if (count == kCapacity) return false;
    filters[static_cast<std::size_t>(count++)] = f;
    return true;
  }
  constexpr bool passes(std::uint32_t frame_id) const noexcept {
    for (int i = 0; i < count; ++i) {
      if (filters[static_cast<std::size_t>(i)].passes(frame_id)) return true;
    }
    return false;
  }
};

}  // namespace exodaq::drivers::can
