#include "exodaq/drivers/can_frame.hpp"

namespace exodaq::drivers::can {

BusState bus_state_after(BusState current, const ErrorPayload& err) noexcept {
  namespace ec = err_class;
  namespace crtl = err_crtl;
  if ((err.classes & ec::kBusOff) != 0) return BusState::kOff;
  if ((err.classes & ec::kRestarted) != 0) return BusState::kActive;
  if ((err.classes & ec::kCrtl) != 0) {
    if ((err.controller & (crtl::kRxPassive | crtl::kTxPassive)) != 0) return BusState::kPassive;
    if ((err.controller & (crtl::kRxWarning | crtl::kTxWarning)) != 0) return BusState::kWarning;
    if ((err.controller & crtl::kActive) != 0) return BusState::kActive;
  }
  return current;
}

bool decode_error(const CanFrame& f, ErrorPayload& out) noexcept {
  if ((f.flags & frame_flag::kError) == 0) return false;
  out = ErrorPayload{};
  out.classes = f.id & err_class::kMask;
  out.lost_arb_bit = f.data[0];
  out.controller = f.data[1];
  out.protocol_type = f.data[2];
  out.protocol_location = f.data[3];
  out.transceiver = f.data[4];
  out.tx_error_count = f.data[6];
  out.rx_error_count = f.data[7];
  return true;
}

CanFrame encode_error(const ErrorPayload& err) noexcept {
  CanFrame f;
  f.id = err.classes & err_class::kMask;
  f.flags = frame_flag::kError;
  f.dlc = kErrorFrameDlc;
  f.data[0] = err.lost_arb_bit;
  f.data[1] = err.controller;
  f.data[2] = err.protocol_type;
  f.data[3] = err.protocol_location;
  f.data[4] = err.transceiver;
  f.data[6] = err.tx_error_count;
  f.data[7] = err.rx_error_count;
  return f;
}

}  // namespace exodaq::drivers::can
